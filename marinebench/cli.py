"""marinebench command line: thin layer over config loading, the runner and the writers.

Exit codes: 0 success, 1 failure of a check (``compare``; ``--require-claims``), 2 unusable input
(config errors, infeasible designs, a step too large for the observer gains).
"""

from __future__ import annotations

import inspect
import json
import re
import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from enum import Enum
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

from marinebench.errors import ConfigError, MarinebenchError, StiffnessError, UserCodeError

app = typer.Typer(add_completion=False, no_args_is_help=True, help="Simulation benchmarks for marine-vehicle observers.")
# options that run and sweep share
Quiet = Annotated[bool, typer.Option("--quiet", "-q", help="no progress bar")]
DEFAULT_SWEEP = Path("configs/torben_fig3.yaml")  # relative to the working directory, as results/ is
SweepConfig = Annotated[Path, typer.Option(metavar="FILE", help="experiment with a sweep section (the default is relative to "
                                           "the working directory)")]
Sets = Annotated[list[str] | None, typer.Option("--set", metavar="KEY=VALUE", help="override a config field: "
                                                "dotted.key=value ('scenarios.*.horizon=20': * is every key or item)")]
ProfileName = Annotated[str | None, typer.Option("--profile", metavar="NAME", help="apply the config's named profile (e.g. quick)")]
Unpaired = Annotated[bool, typer.Option("--unpaired", help="compare the two sides as independent samples (e.g. runs on "
                                        "another --seed): every run counts, Welch's t interval (wider)")]
err = Console(stderr=True, highlight=False, soft_wrap=True)
out = Console(highlight=False, soft_wrap=True)


def _print_version(value: bool) -> None:
    if value:
        from marinebench import __version__
        from marinebench.results.writer import git_revision

        revision = git_revision()
        out.print(f"marinebench {__version__}" + (f" (git {revision})" if revision != "unknown" else ""), markup=False)
        raise typer.Exit()


@app.callback()
def _options(version: Annotated[bool, typer.Option("--version", callback=_print_version, is_eager=True,
                                                   help="print the version (and git revision) and exit")] = False) -> None:
    """Simulation benchmarks for marine-vehicle observers."""


def fail(message: str, code: int = 2) -> None:
    err.print(f"error: {message}", markup=False)
    raise typer.Exit(code)


class Terminated(KeyboardInterrupt):
    """SIGTERM (a cancelled CI job, ``timeout``, ``kill``), raised by :func:`main`'s handler so that the command
    unwinds as on Ctrl-C: folders stay whole, the worker processes stop, the same line says what was kept."""


def _terminated(signum, frame) -> None:
    raise Terminated


def _interrupted(what: str, exc: KeyboardInterrupt) -> None:
    """Ctrl-C or SIGTERM: say in one line what was kept and how to go on; exit 130 or 143 as the shell would
    (typer exits 130 silently)."""
    err.print(f"interrupted: {what}", markup=False)
    raise typer.Exit(128 + (signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT))


@contextmanager
def one_line_errors() -> Iterator[None]:
    """A :class:`MarinebenchError` raised inside becomes its one line on stderr and exit code 2."""
    try:
        yield
    except MarinebenchError as exc:
        fail(str(exc))


def _write_text(path: Path, text: str, option: str) -> None:
    """Write one output file atomically; a path that cannot be written is one line naming the option."""
    from marinebench.results.writer import atomic_write_text

    try:
        atomic_write_text(path, text)
    except FileExistsError:  # mkdir of a parent that is a file
        fail(f"{option}: {path}: a parent is a file, not a folder")
    except OSError as exc:
        fail(f"{option}: {path}: cannot write ({exc.strerror or exc})")


def _sweep_config(config: Path) -> None:
    """sweep/bench: the default --config is relative to the working directory; say so when it is not there."""
    if config == DEFAULT_SWEEP and not config.exists():
        fail(f"{config}: file not found in {Path.cwd()}: the default --config is relative to the working directory; "
             "run from the repository's root or pass --config FILE")


def _load(config: Path, sets: list[str], seed: int | None, seeds: int | None, profile: str | None = None,
          sweep_params: bool = True, variants: str | None = None, traces: bool = False,
          inline: dict[str, tuple[str, str]] | None = None):
    """Load, validate and design (LMIs) one experiment; raises ConfigError naming file and key (``sweep_params``:
    see :func:`~marinebench.loading.load_checked`; ``variants``: ``sweep --variants``, comma-separated; ``traces``:
    ``run --traces``; ``inline``: the sweep parameters given in place, ``{key: (argument, value)}``,
    :func:`~marinebench.experiments.sweep.inline_params`). An error in what an option set names the option."""
    from marinebench.loading import load_checked

    if variants is not None:
        names = [name.strip() for name in variants.split(",")]
        if not all(names):
            raise ConfigError("--variants", "", f"comma-separated variant names, e.g. rise,srise, or 'all' (got '{variants}')")
        variants = json.dumps(names)  # quoted: a variant may be named "1e3"
    options = {"seed": ("--seed", seed), "seeds": ("--seeds", seeds), "sweep.variants": ("--variants", variants),
               "engine.write_traces": ("--traces", "true" if traces else None), **(inline or {})}
    sets = list(sets) + [f"{key}={value}" for key, (_, value) in options.items() if value is not None]
    try:
        return load_checked(config, sets, profile, sweep_params)
    except ConfigError as exc:  # the options are applied last, as --sets: name the option that was typed
        key = next((k for k in options if exc.key == k or exc.key.startswith(f"{k}.")), None)
        if exc.file == "--set" and key is not None and options[key][1] is not None:
            raise ConfigError(options[key][0], "", exc.message) from None
        raise


def _run_and_write(path: Path, exp, origins, target: Path, progress=None, on_start=None) -> tuple[str, str | None, int]:
    """Simulate one experiment and write its results atomically; returns the summary line, a warning (or
    None) and the number of its claims that fail. Errors are re-raised as one line naming the file."""
    from marinebench.experiments.runner import run as run_experiment
    from marinebench.results.claims import evaluate, summary_line
    from marinebench.results.outputs import as_written, write_run

    try:
        result = run_experiment(exp, progress=progress, on_start=on_start)
    except StiffnessError as exc:
        raise MarinebenchError(f"{path}: scenario.dt: {exc}") from None
    except MarinebenchError as exc:
        raise MarinebenchError(f"{path}: {exc}") from None
    claims = evaluate(exp, as_written(result.metrics))  # the metrics as metrics.csv holds them, as write_run checks them
    try:
        write_run(result, target, origins, claims)
    except OSError as exc:  # e.g. the disk filled up: the previous results stay, nothing half-written
        raise MarinebenchError(f"{target}: cannot write results ({exc.strerror or exc})") from None
    warning = _diverged_warning(exp.name, result.metrics)
    checked = f", {summary_line(claims)}" if claims else ""
    line = f"{exp.name}: {len(result.run_seed)} runs in {result.wall_time:.1f} s{checked} -> {target}"
    return line, warning, sum(c.fails for c in claims)


def _diverged_warning(name: str, metrics) -> str | None:
    """The warning that some runs diverged (their metric values are excluded from means, tables and claims)."""
    n_div = int((metrics["status"] != "ok").sum())
    return f"warning: {name}: {n_div} metric values from diverged runs excluded" if n_div else None


def _run_in_worker(path: Path, exp, origins, target: Path, progress=None) -> tuple[str | None, str | None, int, str | None]:
    """``_run_and_write`` in a worker process: (line, warning, failing claims, error) as plain values
    (exceptions with custom constructors do not always survive pickling)."""
    try:
        return (*_run_and_write(path, exp, origins, target, progress=progress), None)
    except MarinebenchError as exc:
        return None, None, 0, str(exc)
    except Exception as exc:  # noqa: BLE001 -- a crash: one line, after the other experiments are written
        return None, None, 0, f"{path}: failed in a --jobs worker process ({type(exc).__name__}: {exc}; --jobs 1 shows the traceback)"


@app.command()
def run(
    configs: Annotated[list[Path], typer.Argument(metavar="CONFIG", help="experiment YAML files")],
    out_dir: Annotated[Path | None, typer.Option("--out", metavar="DIR", help="write to DIR/<config stem>/ (default results/)")] = None,
    seed: Annotated[int | None, typer.Option(metavar="N", min=0, help="root seed (overrides the config)")] = None,
    seeds: Annotated[int | None, typer.Option(metavar="N", min=1, help="Monte-Carlo runs per variant")] = None,
    set_: Sets = None,
    profile: ProfileName = None,
    jobs: Annotated[int, typer.Option("--jobs", "-j", metavar="N", min=0, help="experiments run at once in separate processes "
                                      "(0, the default: one per core; 1: one after the other); the numbers do not depend on it")] = 0,
    quiet: Quiet = False,
    require_claims: Annotated[bool, typer.Option("--require-claims", help="exit 1 when a claim of a config (claims.md) fails, after "
                                                 "everything is written")] = False,
    resume: Annotated[bool, typer.Option("--resume", help="skip an experiment whose results were written from the same inputs "
                                         "(manifest's inputs_key: resolved config, seeds, marinebench source, package "
                                         "versions, custom classes' files), e.g. after an interruption")] = False,
    traces: Annotated[bool, typer.Option("--traces", help="also write traces.csv.gz, the data of the figures: truth and estimate "
                                         "of seed 0 of each variant every engine.trace_dt, one row per scenario, variant, "
                                         "seed, t and signal (engine.write_traces)")] = False,
) -> None:
    """Run experiments; each writes config.resolved.yaml, manifest.json, metrics.csv, table.md, claims.md, figures/."""
    from marinebench.experiments.cluster import available_cores
    from marinebench.results.writer import output_folder, replaceable

    base = out_dir if out_dir is not None else Path("results")
    with one_line_errors():
        configs = _distinct_targets(configs, base)
        loaded = [(c, *_load(c, set_ or [], seed, seeds, profile, traces=traces)) for c in configs]  # validate everything first
        for c in configs:  # and that no one's files are where the results go, before anything runs
            replaceable(_target(base, c))
    failing = 0
    try:
        with one_line_errors(), output_folder(base):
            if resume:
                loaded, failing = _skip_current(loaded, base, quiet)
            jobs = min(jobs or available_cores(), max(1, len(loaded)))
            failing += _run_parallel(loaded, base, jobs, quiet) if jobs > 1 else _run_serial(loaded, base, quiet)
    except KeyboardInterrupt as exc:
        _interrupted("the experiments already written are complete, the others untouched; the same command with "
                     "--resume runs only those not written", exc)
    _claims_verdict(require_claims, failing)


def _claims_verdict(required: bool, failing: int) -> None:
    """``--require-claims``: exit 1, after everything is written, when any claim fails."""
    if required and failing:
        err.print(f"{failing} claim(s) fail (see claims.md)", markup=False)
        raise typer.Exit(1)


def _distinct_targets(configs: list[Path], base: Path) -> list[Path]:
    """The configs, each file once (a shell glob may name one twice), refusing two files that would write the same
    folder ``base/<stem>/``: the second would silently replace the first's results."""
    firsts: dict[str, Path] = {}
    for c in configs:
        first = firsts.setdefault(output_stem(c), c)
        if first is not c and first.resolve() != c.resolve():
            raise MarinebenchError(f"{c}: writes {_target(base, c)}, as {first} does; run them with different --out")
    return list(firsts.values())


def _target(base: Path, config: Path) -> Path:
    """The folder an experiment file's results go to: ``base/<config stem>/`` (:func:`output_stem`)."""
    return base / output_stem(config)


def output_stem(config: Path) -> str:
    """What a config's result folder is named after: the file's stem, or for a result folder's
    ``config.resolved.yaml`` the experiment's ``name`` in it, so that rerunning a result writes where the config it
    was resolved from did (``results/torben_fig1/``), not to ``config.resolved/``."""
    if config.name == "config.resolved.yaml":
        from marinebench.config import NAME
        from marinebench.loading import read_yaml

        try:
            name = read_yaml(config).get("name")
        except ConfigError:  # loading the file reports it, naming the key
            name = None
        if isinstance(name, str) and re.fullmatch(NAME, name):
            return name
    return config.stem


def _up_to_date(exp, target: Path, quiet: bool) -> int | None:
    """``--resume``: None when ``target`` was not written from the same inputs as ``exp`` (its manifest's
    ``inputs_key``), or its manifest cannot be read (then it is written again); otherwise says so and returns the
    number of failing claims the manifest records."""
    from marinebench.provenance import inputs_key
    from marinebench.results.stored import StoredResultError, read_manifest

    try:
        stored = read_manifest(target)
    except (OSError, StoredResultError):
        return None
    if stored.get("inputs_key") != inputs_key(exp):
        return None
    claims = stored.get("claims", [])
    if not quiet:
        verdict = f", {sum(c['holds'] for c in claims)} of {len(claims)} claims hold" if claims else ""
        out.print(f"{exp.name}: up to date (same inputs){verdict} -> {target}", markup=False)
    return sum(not c["holds"] and "not_checked" not in c for c in claims)


def _skip_current(loaded: list, base: Path, quiet: bool) -> tuple[list, int]:
    """``run --resume``: the experiments not :func:`_up_to_date` (to run), and the failing claims of the others."""
    todo, failing = [], 0
    for item in loaded:
        path, exp, _ = item
        known = _up_to_date(exp, _target(base, path), quiet)
        if known is None:
            todo.append(item)
        else:
            failing += known
    return todo, failing


def _run_serial(loaded: list, base: Path, quiet: bool) -> int:
    """The experiments one after the other with a progress bar each; returns the number of failing claims."""
    failing = 0
    for path, exp, origins in loaded:
        with one_line_errors(), Progress(
            TextColumn(f"{exp.name:<22}"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"),
            TimeElapsedColumn(), TimeRemainingColumn(), console=err, disable=quiet, transient=False,
        ) as bar:
            task = bar.add_task(exp.name, total=1)
            line, warning, n_failing = _run_and_write(
                path, exp, origins, _target(base, path),
                progress=lambda n, task=task: bar.advance(task, n),
                on_start=lambda n, task=task: bar.update(task, total=n),
            )
            bar.update(task, completed=bar.tasks[0].total)
        failing += n_failing
        if warning:
            err.print(warning, markup=False)
        if not quiet:
            out.print(line, markup=False)
    return failing


def _run_parallel(loaded: list, base: Path, jobs: int, quiet: bool) -> int:
    """``run --jobs N``: the experiments side by side in N local worker processes (forked, as the sweep's
    batches: ``experiments/cluster.py``), the longest first, with one progress bar over all their steps. Every
    experiment that can finish is written; the first error is reported afterwards (exit 2)."""
    from marinebench.experiments.cluster import ChunkFailed, local_pool
    from marinebench.experiments.runner import run_steps, steps

    errors, failing = [], 0
    order = sorted(loaded, key=lambda item: run_steps(item[1]), reverse=True)  # the longest first
    tasks = {i: (path, exp, origins, _target(base, path)) for i, (path, exp, origins) in enumerate(order)}
    # the pool first: its workers are forked before the progress bar starts its thread
    with local_pool(jobs) as pool, Progress(
        TextColumn(f"{len(order)} experiments, {jobs} processes"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"),
        TimeElapsedColumn(), TimeRemainingColumn(), console=err, disable=quiet, transient=False,
    ) as bar:
        task = bar.add_task("run", total=sum(steps(exp) for _, exp, _ in order))
        try:
            for _, (line, warning, n_failing, error) in pool.results(
                _run_in_worker, tasks, progress=lambda k: bar.advance(task, k)
            ):
                failing += n_failing
                if error:
                    errors.append(error)
                if warning:
                    err.print(warning, markup=False)
                if line and not quiet:
                    out.print(line, markup=False)
        except ChunkFailed as exc:  # errors come back as values, so this is a worker that died (killed, out of memory)
            errors.insert(0, f"{tasks[exc.chunk][0]}: its --jobs worker process died ({type(exc.cause).__name__}: "
                             f"{exc.cause}); the experiments reported above are written")
        bar.update(task, completed=bar.tasks[0].total)
    if errors:
        fail(errors[0])
    return failing


@app.command()
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

    from marinebench.experiments.chunks import check_partial, discard_partial
    from marinebench.experiments.sweep import GRID_N, inline_params, sweep_suffix
    from marinebench.results.claims import summary_line
    from marinebench.results.outputs import write_sweep
    from marinebench.results.writer import replaceable

    _check_sweep_options(chunk_size, jobs, dask, n, horizon, grid, require_claims)
    _sweep_config(config)
    groups = gnss.split(",") if gnss else None
    overrides = [*(set_ or []), *([f"seed={seed}"] if seed is not None else [])]  # named in the folder
    with one_line_errors():
        params, inline = inline_params(params or [])
    overrides = [arg for arg, _ in inline.values()] + overrides  # a parameter given in place names the folder, as --set does
    sets, unchecked = _claims_in_range(config, set_ or [], inline)
    base, exp, params = _sweep_experiment(config, params, sets, seed, seeds, variants, groups, n, horizon, grid,
                                          overrides, inline)
    for note in [] if quiet else unchecked:
        err.print(f"note: {config}: {note}", markup=False)
    target = (out_dir if out_dir is not None else Path("results")) / (
        output_stem(config) + sweep_suffix(base, params, groups, n, horizon, overrides, grid))
    with one_line_errors():
        replaceable(target)
        check_partial(target)
    known = _up_to_date(exp, target, quiet) if resume else None
    if known is not None:
        _claims_verdict(require_claims, known)
        return
    t0 = _time.perf_counter()
    metrics, summed, ran, wall, executor = _simulate_sweep(exp, config, target, chunk_size, dask, workers, jobs, quiet)
    try:
        claims, mapped = write_sweep(
            target, exp, base, config, metrics, params, grid, started=t0, overrides=set_ or [],
            n=n or (GRID_N if grid else base.sweep.n), groups=gnss or "all", variants=base.sweep.swept,
            chunk_size=chunk_size, chunks_run=ran, executor=executor, wall_time_s=round(wall, 3),
            batch_time_s=round(summed, 3),
        )
    except OSError as exc:  # e.g. the disk filled up: the finished batches stay in the .partial folder
        fail(f"{target}: cannot write results ({exc.strerror or exc})")
    discard_partial(target)
    if warning := _diverged_warning(target.name, metrics):
        err.print(warning + " (table.md: the diverged column)", markup=False)
    if not quiet:
        checked = (f", {summary_line(claims)}" if claims else
                   f", {len(mapped)} claim(s) mapped over the grid (claims.md)" if mapped else "")
        out.print(f"sweep: {len(exp.variants) * exp.seeds} runs x {exp.scenario.horizon:g} s in {_time.perf_counter() - t0:.1f} s "
                  f"({wall:.1f} s simulating in {executor}; {summed:.1f} s summed over the {ran} batch(es) run){checked} "
                  f"-> {target}", markup=False)
    _claims_verdict(require_claims, sum(c.fails for c in claims))


def _claims_in_range(config: Path, sets: list[str], inline: dict[str, tuple[str, str]]) -> tuple[list[str], list[str]]:
    """sweep: ``sets``, plus one leaving out the config's sweep claims about a parameter given in place at values
    outside its new range (:func:`~marinebench.experiments.sweep.claims_beyond`), and a note on each left out. A
    config that cannot be read is left to the loading that follows to report."""
    from marinebench.experiments.sweep import claims_beyond
    from marinebench.loading import resolve_document

    if not inline:
        return sets, []
    try:
        doc, _ = resolve_document(config, sets)
    except MarinebenchError:
        return sets, []
    claims = doc.get("sweep", {}).get("claims") if isinstance(doc.get("sweep"), dict) else None
    kept, notes = claims_beyond(claims, inline)
    return ([*sets, f"sweep.claims={json.dumps(kept)}"] if notes else sets), notes


def _sweep_experiment(config: Path, params: list[str], sets: list[str], seed: int | None, seeds: int | None,
                      variants: str | None, groups: list[str] | None, n: int | None, horizon: float | None, grid: bool,
                      overrides: list[str], inline: dict[str, tuple[str, str]]):
    """sweep: the loaded experiment (its variants those of ``--variants``, or every one on the sweep's world for
    'all'), the experiment whose variants are the sweep's points, its designs solved (preflight), and the parameters
    swept (``params``, or every one of the config's ``sweep.params`` when none is named)."""
    from marinebench.experiments.sweep import in_place_error, sweep_experiment
    from marinebench.preflight import preflight

    with one_line_errors():
        base, _ = _load(config, sets, seed, seeds, sweep_params=False,  # the parameters are checked below
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


def _simulate_sweep(exp, config: Path, target: Path, chunk_size: int, dask: str | None, workers: int | None, jobs: int,
                    quiet: bool) -> tuple:
    """sweep: simulate the points in batches of ``chunk_size`` (in this process, local worker processes or on
    Dask) under a progress bar; returns (metrics, batch seconds summed, batches run, wall seconds, executor). An
    interruption exits, keeping the finished batches for the same command to resume from; a class of the user's
    failing in this process is one line naming ``config``, as in ``run``."""
    import time as _time
    from contextlib import nullcontext

    from marinebench.experiments.chunks import chunks_of, finished_chunks, partial_dir, run_chunked
    from marinebench.experiments.cluster import available_cores, dask_pool, local_pool
    from marinebench.results.writer import output_folder

    jobs = min(jobs or available_cores(), len(chunks_of(exp, chunk_size)))
    # the pool first: local workers are forked before the progress bar starts its thread
    where = dask_pool(dask, workers) if dask else local_pool(jobs) if jobs > 1 else nullcontext()
    try:
        with one_line_errors(), output_folder(target.parent), where as pool, Progress(
            TextColumn(f"sweep {len(exp.variants) * exp.seeds} runs"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"),
            TimeElapsedColumn(), TimeRemainingColumn(), console=err, disable=quiet,
        ) as bar:
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
        _interrupted(f"{finished_chunks(target)} of {len(chunks_of(exp, chunk_size))} batch(es) finished and kept in {partial_dir(target)}; "
                     "the same command resumes from them", exc)
    return metrics, summed, ran, wall, executor


def _check_sweep_options(chunk_size: int, jobs: int, dask: str | None, n: int | None, horizon: float | None,
                         grid: bool, require_claims: bool) -> None:
    """sweep: options that contradict each other or are out of range, one line each, before anything loads."""
    if chunk_size < 1:
        fail("--chunk-size: must be at least 1")
    if jobs and dask:
        fail("--jobs: runs the batches in local processes; with --dask, --workers sets a local cluster's size")
    _check_points(n, horizon)
    if grid and require_claims:
        fail("--require-claims: a grid sweep maps where each claim holds (claims.md) and gives no verdict; "
             "use it on a one-at-a-time sweep")


def _check_points(n: int | None, horizon: float | None) -> None:
    """sweep, bench: ``--n`` points per parameter and ``--horizon`` seconds per run in range."""
    from marinebench.experiments.sweep import points_error

    if bad := points_error(n, horizon):
        fail(f"--{bad[0]}: must be {bad[1]}")


@app.command()
def bench(
    config: SweepConfig = DEFAULT_SWEEP,
    params: Annotated[str, typer.Option(metavar="PARAMS", help="comma-separated swept parameters")] = "k,delta,eps",
    n: Annotated[int | None, typer.Option("--n", metavar="N", help="points per parameter (default: the config's)")] = None,
    horizon: Annotated[float, typer.Option(metavar="SECONDS", min=0.1, help="simulated seconds per run in the benchmark")] = 50.0,
    runs: Annotated[int, typer.Option(metavar="N", min=1, help="runs timed with the per-run reference loop")] = 3,
) -> None:
    """Time the batched engine against the plain per-run reference on the same runs, in one process."""
    import resource
    import time as _time

    from marinebench.experiments.reference import against_reference
    from marinebench.experiments.runner import run as run_experiment
    from marinebench.experiments.sweep import sweep_experiment

    _check_points(n, horizon)
    _sweep_config(config)
    with one_line_errors():
        base, _ = _load(config, [], None, None, sweep_params=False)
        _benchable(base, config)
        names = params.split(",")
        have = list(base.sweep.params) if base.sweep is not None else []
        if unknown := [p for p in names if p not in have]:
            raise ConfigError("--params", "", f"{params}: {config} has no sweep parameter {unknown[0]!r} (its "
                              f"sweep.params: {', '.join(have) or 'none: the config has no sweep section'})")
        if len(set(names)) < len(names):
            raise ConfigError("--params", "", f"{params}: a parameter given more than once")
        exp = sweep_experiment(base, names, None, n, horizon, config)
    full_horizon = base.scenario.horizon
    B = len(exp.variants)
    t0 = _time.perf_counter()
    batched = run_experiment(exp, traces=False)
    t_batch = _time.perf_counter() - t0
    picks = np.linspace(0, B - 1, max(1, min(runs, B))).round().astype(int)
    t_ref, worst = against_reference(exp, batched.metrics, picks)
    scale = full_horizon / horizon
    per_run_batched = t_batch / B
    out.print(f"runs: {B} x {horizon:g} s (sweep {params}); reference on {len(picks)} of them", markup=False)
    out.print(f"batched engine:      {t_batch:8.2f} s  ({per_run_batched * 1e3:.2f} ms per run)", markup=False)
    out.print(f"per-run reference:   {t_ref * B:8.2f} s  ({t_ref * 1e3:.2f} ms per run, extrapolated to {B} runs)", markup=False)
    out.print(f"speed-up (same process): {t_ref / per_run_batched:.1f}x", markup=False)
    out.print(f"extrapolated full sweep ({B} x {full_horizon:g} s): batched {t_batch * scale:.1f} s, "
              f"reference {t_ref * B * scale:.0f} s", markup=False)
    out.print(f"largest relative J_tot difference batched vs reference: {worst:.2e}", markup=False)
    out.print(f"peak RSS: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB", markup=False)


def _benchable(base, config: Path) -> None:
    """bench: the plain per-run reference exists for the DP observers (NPO, resetting) in a dp_supply world, and is
    compared with the batch on its J_tot metric."""
    if base.scenario is None or base.scenario.kind != "dp_supply":
        raise ConfigError(config, "scenario.kind", "bench compares the batched engine with the plain per-run "
                          "reference of the DP observers, which exists for dp_supply scenarios (e.g. configs/torben_fig3.yaml)")
    swept = [v for v in base.variants if v.name in (base.sweep.swept if base.sweep is not None else [])]
    if other := [v.name for v in swept if v.observer.kind not in ("npo", "resetting_fto")]:
        raise ConfigError(config, "sweep.variant", f"{other[0]}: bench's per-run reference is of the DP observers (npo, "
                          "resetting_fto), not of this variant's (e.g. configs/torben_fig3.yaml)")
    if not any(m.kind == "j_tot" and m.label == "J_tot" for m in base.metrics):
        raise ConfigError(config, "metrics", "bench compares the batch with the reference on a j_tot metric named J_tot")


class Format(str, Enum):
    md = "md"
    json = "json"
    csv = "csv"


@app.command()
def compare(
    baseline: Annotated[Path, typer.Argument(metavar="BASELINE", help="result directory or tree (e.g. results/)")],
    candidate: Annotated[Path | None, typer.Argument(metavar="CANDIDATE", help="result directory or tree to check")] = None,
    variants: Annotated[
        tuple[str, str] | None, typer.Option(metavar="A B", help="compare two variants of BASELINE instead: A B (B vs A)")
    ] = None,
    metric: Annotated[list[str] | None, typer.Option(metavar="NAME", help="only these metrics (repeatable)")] = None,
    rtol: Annotated[float, typer.Option(metavar="X", help="relative tolerance for 'same'")] = 0.02,
    atol: Annotated[float, typer.Option(metavar="X", help="absolute tolerance for 'same'")] = 0.0,
    fmt: Annotated[Format, typer.Option("--format", help="output format")] = Format.md,
    output: Annotated[Path | None, typer.Option(metavar="FILE", help="write the comparison to FILE")] = None,
    strict: Annotated[bool, typer.Option("--strict", help="a baseline cell the candidate lacks (a dropped variant, signal or "
                                         "metric) also fails, as a worse cell does")] = False,
    all_cells: Annotated[bool, typer.Option("--all", help="list 'same' and 'new' cells too (markdown; json and "
                                            "csv always hold every cell)")] = False,
    unpaired: Unpaired = False,
    interval: Annotated[str | None, typer.Option(metavar="bootstrap|t", help="the CI of a paired comparison: 'bootstrap' "
                                                 "(default between runs: the gate's consistency check) or 't' (the paired "
                                                 "Student t interval, for differences that are noise; default with --variants)")] = None,
) -> None:
    """Compare results cell by cell over seeds (paired on seed, bootstrap CIs; or --unpaired); exit 1 if worse.

    Exit 0: nothing worse; 1: something worse (or, with --strict, missing); 2: unusable input."""
    from marinebench.results.compare import OUTPUT_HEADS, Tolerance, compare_error, comparison, headline
    from marinebench.results.writer import replaceable_file

    tol = Tolerance(rtol=rtol, atol=atol)
    if wrong := compare_error(candidate, variants, tol, interval, paired=not unpaired):
        fail(wrong)
    with one_line_errors():
        if output is not None:  # before reading anything: a file there that compare did not write stays
            replaceable_file(output, OUTPUT_HEADS, "--output")
        table = comparison(baseline, candidate, variants, metric, tol, paired=not unpaired, interval=interval)
    text = _comparison_text(table, fmt, all_cells, paired=not unpaired)
    if output is not None:
        _write_text(output, text, "--output")
        err.print(headline(table), markup=False)
    else:
        sys.stdout.write(text)
    failing = {"worse", "missing"} if strict else {"worse"}
    raise typer.Exit(1 if table["verdict"].isin(failing).any() else 0)


def _comparison_text(table, fmt: Format, all_cells: bool, paired: bool) -> str:
    """compare's output in ``fmt``: markdown (the worse, missing and better cells; ``all_cells``: every one), json
    (headline, notes and every cell) or csv (every cell)."""
    from marinebench.results.compare import headline, to_markdown

    if fmt is Format.md:
        return to_markdown(table, all_cells=all_cells, paired=paired)
    if fmt is Format.json:
        return json.dumps({"summary": headline(table), "paired": paired,
                           "machines": table.attrs.get("machine_note", ""), "renamed": table.attrs.get("renamed", ""),
                           "cells": json.loads(table.to_json(orient="records"))}, indent=2) + "\n"
    return table.to_csv(index=False)


@app.command()
def report(
    results: Annotated[Path, typer.Argument(metavar="RESULTS", help="result directory or tree")],
    out_file: Annotated[Path, typer.Option("--out", metavar="FILE", help="HTML file to write")] = Path("report.html"),
    compare_with: Annotated[Path | None, typer.Option("--compare", metavar="BASELINE", help="baseline results to compare against")] = None,
    unpaired: Unpaired = False,
) -> None:
    """Write one self-contained static HTML report (figures embedded, no JavaScript)."""
    from marinebench.results.report import HEAD, render_report
    from marinebench.results.writer import replaceable_file

    if unpaired and compare_with is None:
        fail("--unpaired: compares the results with a baseline, so it needs --compare BASELINE")
    with one_line_errors():
        replaceable_file(out_file, (HEAD,), "--out")  # before reading anything: a file there it did not write stays
        html = render_report(results, compare_with, paired=not unpaired)
    _write_text(out_file, html, "--out")
    out.print(f"report -> {out_file}", markup=False)


@app.command()
def figures(
    results: Annotated[list[Path], typer.Argument(metavar="RESULTS", help="result folders written by run --traces, or by sweep")],
) -> None:
    """Draw a result's figures again, without simulating: a run's from its traces.csv.gz (run --traces) and the figures:
    of its config.resolved.yaml, which may be edited first (other signals, variants or files); a sweep's from its
    metrics.csv and the sweep: of its config.resolved.yaml (the metrics, signals and axis labels shown)."""
    from marinebench.results.outputs import redraw_figures

    for folder in results:
        with one_line_errors():
            if not folder.is_dir():
                raise MarinebenchError(f"{folder}: no such directory")
            drawn = redraw_figures(folder)
        out.print(f"{folder}: {len(drawn)} figure(s) -> {folder / 'figures'}", markup=False)


@app.command()
def validate(
    files: Annotated[list[Path], typer.Argument(metavar="FILE", help="experiment or scenario YAML files")],
    set_: Sets = None,
    profile: ProfileName = None,
) -> None:
    """Check configs (and solve their observer designs) without running them.

    With --set and --profile, each file is checked as run would load it."""
    from marinebench.loading import is_scenario_file, load_scenario

    for f in files:
        with one_line_errors():
            if is_scenario_file(f):
                if set_ or profile:
                    raise ConfigError("--set" if set_ else "--profile", "", f"{f}: a scenario file; --set and --profile "
                                      "apply to experiment files (which can set scenario.<key>)")
                load_scenario(f)
            else:
                exp, _ = _load(f, set_ or [], None, None, profile)
                for i, claim in enumerate(exp.claims):
                    if (problem := exp.claim_problem(claim)) is not None:
                        err.print(f"warning: {f}: claims.{i} cannot be checked: {problem}", markup=False)
        out.print(f"{f}: ok", markup=False)


@app.command()
def design(
    files: Annotated[list[Path], typer.Argument(metavar="CONFIG", help="experiment YAML files")],
    set_: Sets = None,
    profile: ProfileName = None,
    as_json: Annotated[bool, typer.Option("--json", help="JSON instead of YAML")] = False,
) -> None:
    """Solve and print each variant's observer design (gains, poles) without simulating.

    LMI gains and poles (Bejarano, the CDO's K*), Kalman gains L1/L2 (Torben), ESO gains, as the manifest records
    them. With --set, e.g. scenario.cdo.lmi_decay=0.2, a design is recomputed for other settings."""
    import yaml

    from marinebench.experiments.runner import design_summary

    designs = {}
    for f in files:
        with one_line_errors():
            exp, _ = _load(f, set_ or [], None, None, profile)
            parts = {name: design_summary(exp.part(name)) for name in exp.scenarios} if exp.scenarios else None
            designs[exp.name] = parts or design_summary(exp)
    plain = json.loads(json.dumps(designs, default=float))  # numpy scalars -> floats
    if as_json:
        sys.stdout.write(json.dumps(plain, indent=2) + "\n")
    else:
        sys.stdout.write(yaml.safe_dump(_rounded(plain), sort_keys=False, default_flow_style=None, width=120,
                                        allow_unicode=True))


def _rounded(obj, digits: int = 6):
    """Floats in a nested document to ``digits`` significant digits (for reading; --json keeps them all)."""
    if isinstance(obj, float):
        return float(f"{obj:.{digits}g}")
    if isinstance(obj, dict):
        return {k: _rounded(v, digits) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_rounded(v, digits) for v in obj]
    return obj


class FileKind(str, Enum):
    experiment = "experiment"
    scenario = "scenario"


@app.command()
def schema(kind: Annotated[FileKind, typer.Option(help="which files")] = FileKind.experiment) -> None:
    """Print the JSON Schema of experiment (or scenario) YAML files, for editor completion and checking.

    The schema is of the files as written: with from:, and scenario paths."""
    from marinebench.schema import file_schema

    sys.stdout.write(json.dumps(file_schema(kind.value), indent=2) + "\n")


@app.command(name="list")
def list_kinds(
    groups: Annotated[list[str] | None, typer.Argument(metavar="GROUP|KIND", help="only these groups, e.g. observers "
                                                        "metrics (default: all); a kind, e.g. bejarano, lists its "
                                                        "settings", show_default=False)] = None,
) -> None:
    """List registered kinds: scenarios, vessels, observers, controllers, signals, noise, events, metrics.

    Each observer shows the scenario kinds it runs on. `marinebench list observers` lists one group;
    `marinebench list bejarano` lists one kind's settings (the keys of its YAML mapping, and what a sweep's KEY may
    name), with type, default and meaning."""
    from marinebench.keypaths import did_you_mean, near_misses
    from marinebench.registry import kind_models, kinds

    registered, models = kinds(), kind_models()
    named = {kind for entries in models.values() for kind in entries}
    for group in groups or []:
        if group not in registered and group not in named:
            fail(f"GROUP: no group or kind '{group}'{did_you_mean(near_misses(group, [*registered, *sorted(named)]))}; "
                 f"groups: {', '.join(registered)}")
    for group, entries in registered.items():
        if groups and group not in groups:
            continue
        out.print(f"[bold]{group}[/bold]")
        for name, doc in entries.items():
            out.print(f"  {name:<22} {doc}", markup=False)
    for kind in [g for g in groups or [] if g in named and g not in registered]:
        _print_settings(kind, registered, models)


def _print_settings(kind: str, registered: dict, models: dict) -> None:
    """``list KIND``: each group's model of that kind, its settings one per line."""
    from rich.markup import escape

    from marinebench.registry import fields_of

    for group, entries in models.items():
        if kind not in entries:
            continue
        out.print(f"[bold]{kind}[/bold] ({group}): {escape(registered[group][kind])}")
        only = getattr(entries[kind], "ONLY_FOR", {})  # a model read by several kinds: this kind's settings
        rows = [row for row in fields_of(entries[kind]) if kind in only.get(row[0], (kind,))]
        width = max((len(name) for name, *_ in rows), default=0)
        for name, type_, default, text in rows:
            out.print(f"  {name:<{width}}  {type_} = {default}" + (f"  {text}" if text else ""), markup=False)


# Each command's help is its docstring with every paragraph on one line: typer's rich help keeps a docstring's
# line breaks, which the terminal then wraps a second time. (The first paragraph is the summary in `--help`.)
for _command in app.registered_commands:
    _command.help = "\n\n".join(" ".join(p.split()) for p in inspect.cleandoc(_command.callback.__doc__).split("\n\n"))

# click's exception classes, through typer (recent typer vendors its own copy of click, older ones use click's)
_USAGE_ERROR, _CLICK_EXCEPTION = (next(c for c in typer.BadParameter.__mro__ if c.__name__ == name)
                                  for name in ("UsageError", "ClickException"))


def _command_named(args: list[str]) -> str:
    """``marinebench COMMAND`` for the command ``args`` name first (a usage error raised while its options are
    parsed may carry no context), else ``marinebench``."""
    names = typer.main.get_command(app).commands
    return f"marinebench {args[0]}" if args and args[0] in names else "marinebench"


def main(args: list[str] | None = None) -> None:
    """Console entry point: ``app``, except that a bad option or argument (a usage error, which typer draws as
    a boxed panel with the usage) is one line naming it, like every other input error, exit code 2; and SIGTERM
    is handled as Ctrl-C (:class:`Terminated`)."""
    signal.signal(signal.SIGTERM, _terminated)
    argv = sys.argv[1:] if args is None else args
    try:
        code = app(args=args, prog_name="marinebench", standalone_mode=False)
        if not argv:  # the help, a usage error (click >= 8.2 raises one; click 8.1 returned 0)
            code = 2
    except _USAGE_ERROR as exc:
        message = " ".join(exc.format_message().split()).replace(": Value error, ", ": ")  # typer checks via pydantic
        command = exc.ctx.command_path if exc.ctx else _command_named(argv)
        if message:  # (none when no arguments printed the help)
            err.print(f"error: {message} (see '{command} --help')", markup=False)
        sys.exit(2)
    except _CLICK_EXCEPTION as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except typer.Abort:
        err.print("aborted", markup=False)
        sys.exit(1)
    sys.exit(code if isinstance(code, int) else 0)


if __name__ == "__main__":  # pragma: no cover
    main()
