"""``marinebench run``: experiments simulated and written, one after the other or side by side in worker
processes (``--jobs``), each folder whole or untouched."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from marinebench.cli.common import (
    ProfileName,
    Quiet,
    Sets,
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
from marinebench.errors import MarinebenchError, StiffnessError


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
    warning = diverged_warning(exp.name, result.metrics)
    checked = f", {summary_line(claims)}" if claims else ""
    line = f"{exp.name}: {len(result.run_seed)} runs in {result.wall_time:.1f} s{checked} -> {target}"
    return line, warning, sum(c.fails for c in claims)


def _run_in_worker(path: Path, exp, origins, target: Path, progress=None) -> tuple[str | None, str | None, int, str | None]:
    """``_run_and_write`` in a worker process: (line, warning, failing claims, error) as plain values
    (exceptions with custom constructors do not always survive pickling)."""
    try:
        return (*_run_and_write(path, exp, origins, target, progress=progress), None)
    except MarinebenchError as exc:
        return None, None, 0, str(exc)
    except Exception as exc:  # noqa: BLE001 -- a crash: one line, after the other experiments are written
        return None, None, 0, f"{path}: failed in a --jobs worker process ({type(exc).__name__}: {exc}; --jobs 1 shows the traceback)"


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
        loaded = [(c, *load_config(c, set_ or [], seed, seeds, profile, traces=traces)) for c in configs]  # validate everything first
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
        interrupted("the experiments already written are complete, the others untouched; the same command with "
                     "--resume runs only those not written", exc)
    claims_verdict(require_claims, failing)


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


def _skip_current(loaded: list, base: Path, quiet: bool) -> tuple[list, int]:
    """``run --resume``: the experiments not :func:`up_to_date` (to run), and the failing claims of the others."""
    todo, failing = [], 0
    for item in loaded:
        path, exp, _ = item
        known = up_to_date(exp, _target(base, path), quiet)
        if known is None:
            todo.append(item)
        else:
            failing += known
    return todo, failing


def _run_serial(loaded: list, base: Path, quiet: bool) -> int:
    """The experiments one after the other with a progress bar each; returns the number of failing claims."""
    failing = 0
    for path, exp, origins in loaded:
        with one_line_errors(), progress_bar(f"{exp.name:<22}", quiet) as bar:
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
    with local_pool(jobs) as pool, progress_bar(f"{len(order)} experiments, {jobs} processes", quiet) as bar:
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
