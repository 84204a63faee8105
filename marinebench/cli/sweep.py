"""``marinebench sweep``: a config's sensitivity sweep (or parameters given in place), its points simulated
in batches that survive an interruption (here, in local worker processes or on Dask) and written."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from marinebench.cli.common import (
    DEFAULT_SWEEP,
    ProfileName,
    Quiet,
    Sets,
    SweepConfig,
    check_points,
    check_sweep_config,
    claims_verdict,
    diverged_warning,
    err,
    fail,
    interrupted,
    load_config,
    one_line_errors,
    out,
    output_stem,
    progress_bar,
    up_to_date,
)
from marinebench.errors import ConfigError, MarinebenchError, UserCodeError


def sweep(
    params: Annotated[list[str] | None, typer.Argument(metavar="PARAM", help="parameters to sweep one at a time: names of the "
                                                       "config's sweep.params (default: all of them), or KEY=LO..HI[:log] given "
                                                       "in place (delta_p1=0.5..3, world.gnss_sigma=0.05..3:log)",
                                                       show_default=False)] = None,
    config: SweepConfig = DEFAULT_SWEEP,
    n: Annotated[int | None, typer.Option("--n", metavar="N", help="points per parameter (default: the config's)")] = None,
    gnss: Annotated[str | None, typer.Option("--gnss", "--groups", metavar="GROUPS", help="comma-separated world groups of "
                                             "sweep.groups (default: all; --gnss after Torben's two GNSS models)")] = None,
    variants: Annotated[str | None, typer.Option(metavar="NAMES", help="comma-separated variants swept side by side, one curve "
                                                  "each, or 'all' (default: sweep.variant); each parameter's key must be a "
                                                  "setting of every one, e.g. a world.<key>")] = None,
    horizon: Annotated[float | None, typer.Option(metavar="SECONDS", help="simulated time per run [s]")] = None,
    out_dir: Annotated[Path | None, typer.Option("--out", metavar="DIR", help="write to DIR/<config stem>_sweep.../ (default: results/)")] = None,
    seed: Annotated[int | None, typer.Option(metavar="N", min=0, help="root seed")] = None,
    seeds: Annotated[int | None, typer.Option(metavar="N", min=1, help="Monte-Carlo runs per point (default: the config's); >1 writes "
                                               "<stem>_sweep_<N>seeds/ with intervals")] = None,
    set_: Sets = None,
    profile: ProfileName = None,
    chunk_size: Annotated[int, typer.Option(metavar="N", help="runs per batch; finished batches survive an interruption")] = 300,
    dask: Annotated[str | None, typer.Option(metavar="local|ADDRESS", help="run the batches on Dask: 'local' (a local cluster) or a "
                                             "scheduler address (tcp://host:8786); needs the 'dask' extra")] = None,
    workers: Annotated[int | None, typer.Option(metavar="N", min=1, help="workers of --dask local (default: one per core)")] = None,
    jobs: Annotated[int, typer.Option("--jobs", "-j", metavar="N", min=0, help="batches side by side in N worker processes on "
                                      "this machine (0: one per core; at most one per batch; 1: all in this process); the "
                                      "numbers do not depend on it")] = 0,
    quiet: Quiet = False,
    require_claims: Annotated[bool, typer.Option("--require-claims", help="exit 1 when a claim of sweep.claims (claims.md) fails, "
                                                 "after everything is written")] = False,
    grid: Annotated[bool, typer.Option("--grid", help="every combination of two parameters (--n per axis, default 11) instead of "
                                       "one at a time: a matrix per group in table.md, heat maps, and each claim of sweep.claims mapped along "
                                       "the slices of the other parameter (claims.md)")] = False,
    resume: Annotated[bool, typer.Option("--resume", help="do nothing when the folder was written from the same inputs (manifest's "
                                         "inputs_key); an interrupted sweep resumes from its batches anyway")] = False,
) -> None:
    """Sensitivity sweeps, batched: one parameter at a time, or two over a grid (--grid).

    Writes metrics.csv (param, param_value, gnss), table.md and a figure; with --grid, every combination of two
    parameters (param2, param2_value).

    Runs are simulated in batches of --chunk-size, side by side in one worker process per core (--jobs);
    an interrupted sweep resumes from the finished batches. With --dask the batches run on Dask workers
    instead. Where a run is simulated does not change its numbers."""
    import time as _time

    from marinebench.experiments.chunks import check_partial, chunks_of, discard_partial
    from marinebench.experiments.sweep import GRID_N, inline_params, sweep_suffix
    from marinebench.results.claims import summary_line
    from marinebench.results.outputs import write_sweep
    from marinebench.results.writer import replaceable

    _check_sweep_options(chunk_size, jobs, dask, n, horizon, grid, require_claims)
    check_sweep_config(config)
    groups = gnss.split(",") if gnss else None
    overrides = [*([f"profile={profile}"] if profile else []), *(set_ or []),
                 *([f"seed={seed}"] if seed is not None else [])]  # named in the folder
    with one_line_errors():
        params, inline = inline_params(params or [])
    overrides = [arg for arg, _ in inline.values()] + overrides  # a parameter given in place names the folder, as --set does
    sets, unchecked = _claims_in_range(config, set_ or [], inline, profile)
    base, exp, params = _sweep_experiment(config, params, sets, seed, seeds, variants, groups, n, horizon, grid,
                                          overrides, inline, profile)
    for note in [] if quiet else unchecked:
        err.print(f"note: {config}: {note}", markup=False)
    target = (out_dir if out_dir is not None else Path("results")) / (
        output_stem(config) + sweep_suffix(base, params, groups, n, horizon, overrides, grid))
    with one_line_errors():
        replaceable(target)
        check_partial(target)
    known = up_to_date(exp, target, quiet) if resume else None
    if known is not None:
        claims_verdict(require_claims, known)
        return
    t0 = _time.perf_counter()
    chunks = len(chunks_of(exp, chunk_size))
    metrics, summed, ran, wall, executor = _simulate_sweep(exp, config, target, chunk_size, chunks, dask, workers, jobs,
                                                           quiet)
    try:
        claims, mapped = write_sweep(
            target, exp, base, config, metrics, params, grid, started=t0, overrides=set_ or [],
            **({"profile": profile} if profile else {}),
            n=n or (GRID_N if grid else base.sweep.n), groups=gnss or "all", variants=base.sweep.swept,
            chunk_size=chunk_size, chunks=chunks, chunks_run=ran, executor=executor, wall_time_s=round(wall, 3),
            batch_time_s=round(summed, 3),
        )
    except OSError as exc:  # e.g. the disk filled up: the finished batches stay in the .partial folder
        fail(f"{target}: cannot write results ({exc.strerror or exc})")
    discard_partial(target)
    if warning := diverged_warning(target.name, metrics):
        err.print(warning + " (table.md: the diverged column)", markup=False)
    if not quiet:
        checked = (f", {summary_line(claims)}" if claims else
                   f", {len(mapped)} claim(s) mapped over the grid (claims.md)" if mapped else "")
        out.print(f"sweep: {len(exp.variants) * exp.seeds} runs x {exp.scenario.horizon:g} s in {_time.perf_counter() - t0:.1f} s "
                  f"({wall:.1f} s simulating in {executor}; {summed:.1f} s summed over the {ran} batch(es) run"
                  f"{f', {chunks - ran} kept from the interrupted sweep' if ran < chunks else ''}){checked} "
                  f"-> {target}", markup=False)
    claims_verdict(require_claims, sum(c.fails for c in claims))


def _claims_in_range(config: Path, sets: list[str], inline: dict[str, tuple[str, str]],
                     profile: str | None = None) -> tuple[list[str], list[str]]:
    """sweep: ``sets``, plus one leaving out the config's sweep claims about a parameter given in place at values
    outside its new range (:func:`~marinebench.experiments.sweep.claims_beyond`), and a note on each left out. A
    config that cannot be read is left to the loading that follows to report."""
    from marinebench.experiments.sweep import claims_beyond
    from marinebench.loading import resolve_document

    if not inline:
        return sets, []
    try:
        doc, _ = resolve_document(config, sets, profile)
    except MarinebenchError:
        return sets, []
    claims = doc.get("sweep", {}).get("claims") if isinstance(doc.get("sweep"), dict) else None
    kept, notes = claims_beyond(claims, inline)
    return ([*sets, f"sweep.claims={json.dumps(kept)}"] if notes else sets), notes


def _sweep_experiment(config: Path, params: list[str], sets: list[str], seed: int | None, seeds: int | None,
                      variants: str | None, groups: list[str] | None, n: int | None, horizon: float | None, grid: bool,
                      overrides: list[str], inline: dict[str, tuple[str, str]], profile: str | None = None):
    """sweep: the loaded experiment (its variants those of ``--variants``, or every one on the sweep's world for
    'all'), the experiment whose variants are the sweep's points, its designs solved (preflight), and the parameters
    swept (``params``, or every one of the config's ``sweep.params`` when none is named)."""
    from marinebench.experiments.sweep import in_place_error, sweep_experiment
    from marinebench.preflight import preflight

    with one_line_errors():
        base, _ = load_config(config, sets, seed, seeds, profile, sweep_params=False,  # parameters: checked below
                              variants=None if variants == "all" else variants, inline=inline)
        if variants == "all" and base.sweep is not None:  # every variant that runs on the sweep's scenario
            names = [v.name for v in (base.part(base.sweep_scenario()) if base.scenarios else base).variants]
            base = base.model_copy(update={"sweep": base.sweep.model_copy(update={"variants": names})})
        params = params or list(base.sweep.params if base.sweep is not None else [])
        try:
            exp = sweep_experiment(base, params, groups, n, horizon, config, overrides, grid)
            preflight(exp, config)
        except ConfigError as exc:  # about parameters given in place: name them
            raise in_place_error(exc, inline) from None
    return base, exp, params


def _simulate_sweep(exp, config: Path, target: Path, chunk_size: int, chunks: int, dask: str | None, workers: int | None,
                    jobs: int, quiet: bool) -> tuple:
    """sweep: simulate the points in ``chunks`` batches of ``chunk_size`` (in this process, local worker processes or
    on Dask) under a progress bar; returns (metrics, batch seconds summed, batches run, wall seconds, executor). An
    interruption exits, keeping the finished batches for the same command to resume from; a class of the user's
    failing in this process is one line naming ``config``, as in ``run``."""
    import time as _time
    from contextlib import nullcontext

    from marinebench.experiments.chunks import finished_chunks, partial_dir, run_chunked
    from marinebench.experiments.cluster import available_cores, dask_pool, local_pool
    from marinebench.results.writer import output_folder

    jobs = min(jobs or available_cores(), chunks)
    # the pool first: local workers are forked before the progress bar starts its thread
    where = dask_pool(dask, workers) if dask else local_pool(jobs) if jobs > 1 else nullcontext()
    try:
        with (one_line_errors(), output_folder(target.parent), where as pool,
              progress_bar(f"sweep {len(exp.variants) * exp.seeds} runs", quiet) as bar):
            task = bar.add_task("sweep", total=1)
            executor = pool.describe() if pool is not None else "this process"
            t_sim = _time.perf_counter()
            try:
                metrics, summed, ran = run_chunked(exp, target, chunk_size, progress=lambda k: bar.advance(task, k),
                                                   on_start=lambda k: bar.update(task, total=k), pool=pool)
            except UserCodeError as exc:
                raise UserCodeError(f"{config}: {exc}") from None
            wall = _time.perf_counter() - t_sim
            bar.update(task, completed=bar.tasks[0].total)
    except KeyboardInterrupt as exc:
        interrupted(f"{finished_chunks(target)} of {chunks} batch(es) finished and kept in {partial_dir(target)}; "
                     "the same command resumes from them", exc)
    return metrics, summed, ran, wall, executor


def _check_sweep_options(chunk_size: int, jobs: int, dask: str | None, n: int | None, horizon: float | None,
                         grid: bool, require_claims: bool) -> None:
    """sweep: options that contradict each other or are out of range, one line each, before anything loads."""
    if chunk_size < 1:
        fail("--chunk-size: must be at least 1")
    if jobs and dask:
        fail("--jobs: runs the batches in local processes; with --dask, --workers sets a local cluster's size")
    check_points(n, horizon)
    if grid and require_claims:
        fail("--require-claims: a grid sweep maps where each claim holds (claims.md) and gives no verdict; "
             "use it on a one-at-a-time sweep")
