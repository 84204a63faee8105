"""marinebench command line: thin layer over config loading, the runner and the writers.

Exit codes: 0 success, 1 failure of a check (reserved for ``compare``), 2 unusable input (config
errors, infeasible designs, a step too large for the observer gains).
"""

from __future__ import annotations

import json
import sys
from enum import Enum
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

from marinebench.errors import MarinebenchError, StiffnessError

app = typer.Typer(add_completion=False, no_args_is_help=True, help="Simulation benchmarks for marine-vehicle observers.")
err = Console(stderr=True, highlight=False, soft_wrap=True)
out = Console(highlight=False, soft_wrap=True)


def fail(message: str, code: int = 2) -> None:
    err.print(f"error: {message}", markup=False)
    raise typer.Exit(code)


def _load(config: Path, sets: list[str], seed: int | None, seeds: int | None, profile: str | None = None):
    """Load, validate and design (LMIs) one experiment; raises ConfigError naming file and key."""
    from marinebench.config import load_experiment, preflight

    sets = list(sets)
    if seed is not None:
        sets.append(f"seed={seed}")
    if seeds is not None:
        sets.append(f"seeds={seeds}")
    exp, origins = load_experiment(config, sets, profile)
    preflight(exp, config)
    return exp, origins


@app.command()
def run(
    configs: Annotated[list[Path], typer.Argument(help="experiment YAML files")],
    out_dir: Annotated[Path | None, typer.Option("--out", help="write to DIR/<config stem>/ (default results/)")] = None,
    seed: Annotated[int | None, typer.Option(help="root seed (overrides the config)")] = None,
    seeds: Annotated[int | None, typer.Option(help="Monte-Carlo runs per variant")] = None,
    set_: Annotated[list[str] | None, typer.Option("--set", help="override a config field: dotted.key=value")] = None,
    profile: Annotated[str | None, typer.Option(help="apply the config's named profile (e.g. quick)")] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="no progress bar")] = False,
) -> None:
    """Run experiments and write config.resolved.yaml, manifest.json, metrics.csv, table.md, figures/."""
    from marinebench.experiments.runner import run as run_experiment
    from marinebench.results.outputs import write_run

    try:
        loaded = [(c, *_load(c, set_ or [], seed, seeds, profile)) for c in configs]  # validate everything first
    except MarinebenchError as exc:
        fail(str(exc))
    base = out_dir if out_dir is not None else Path("results")
    for path, exp, origins in loaded:
        target = base / path.stem
        try:
            with Progress(
                TextColumn(f"{exp.name:<22}"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"),
                TimeElapsedColumn(), TimeRemainingColumn(), console=err, disable=quiet, transient=False,
            ) as bar:
                task = bar.add_task(exp.name, total=1)
                result = run_experiment(
                    exp,
                    progress=lambda n, task=task: bar.advance(task, n),
                    on_start=lambda n, task=task: bar.update(task, total=n),
                )
                bar.update(task, completed=bar.tasks[0].total)
        except StiffnessError as exc:
            fail(f"{path}: scenario.dt: {exc}")
        except MarinebenchError as exc:
            fail(f"{path}: {exc}")
        write_run(result, target, origins)
        n_div = int((result.metrics["status"] != "ok").sum())
        if n_div:
            err.print(f"warning: {exp.name}: {n_div} metric values from diverged runs excluded", markup=False)
        if not quiet:
            out.print(f"{exp.name}: {len(result.run_seed)} runs in {result.wall_time:.1f} s -> {target}", markup=False)


class Format(str, Enum):
    md = "md"
    json = "json"
    csv = "csv"


@app.command()
def compare(
    baseline: Annotated[Path, typer.Argument(help="result directory or tree (e.g. results/)")],
    candidate: Annotated[Path | None, typer.Argument(help="result directory or tree to check")] = None,
    variants: Annotated[
        tuple[str, str] | None, typer.Option(help="compare two variants of BASELINE instead: A B (B vs A)")
    ] = None,
    metric: Annotated[list[str] | None, typer.Option(help="only these metrics (repeatable)")] = None,
    rtol: Annotated[float, typer.Option(help="relative tolerance for 'same'")] = 0.02,
    atol: Annotated[float, typer.Option(help="absolute tolerance for 'same'")] = 0.0,
    fmt: Annotated[Format, typer.Option("--format", help="output format")] = Format.md,
    output: Annotated[Path | None, typer.Option(help="write the comparison to FILE")] = None,
) -> None:
    """Paired comparison with bootstrap CIs. Exit 0: nothing worse; 1: something worse; 2: unusable input."""
    from marinebench.results.compare import Tolerance, compare_dirs, compare_variants, headline, to_markdown
    from marinebench.results.writer import atomic_write_text

    if rtol < 0 or atol < 0:
        fail("--rtol/--atol: tolerances must be non-negative")
    tol = Tolerance(rtol=rtol, atol=atol)
    try:
        if variants is not None:
            if candidate is not None:
                fail("give either CANDIDATE or --variants A B, not both")
            table = compare_variants(baseline, variants[0], variants[1], metric, tol)
        else:
            if candidate is None:
                fail("missing CANDIDATE (or use --variants A B)")
            table = compare_dirs(baseline, candidate, metric, tol)
    except MarinebenchError as exc:
        fail(str(exc))
    if fmt is Format.md:
        text = to_markdown(table)
    elif fmt is Format.json:
        text = json.dumps({"summary": headline(table), "cells": json.loads(table.to_json(orient="records"))}, indent=2) + "\n"
    else:
        text = table.to_csv(index=False)
    if output is not None:
        atomic_write_text(output, text)
        err.print(headline(table), markup=False)
    else:
        sys.stdout.write(text)
    raise typer.Exit(1 if (table["verdict"] == "worse").any() else 0)


@app.command()
def report(
    results: Annotated[Path, typer.Argument(help="result directory or tree")],
    out_file: Annotated[Path, typer.Option("--out", help="HTML file to write")] = Path("report.html"),
    compare_with: Annotated[Path | None, typer.Option("--compare", help="baseline results to compare against")] = None,
) -> None:
    """Write one self-contained static HTML report (figures embedded, no JavaScript)."""
    from marinebench.results.report import render_report
    from marinebench.results.writer import atomic_write_text

    try:
        html = render_report(results, compare_with)
    except MarinebenchError as exc:
        fail(str(exc))
    atomic_write_text(out_file, html)
    out.print(f"report -> {out_file}", markup=False)


@app.command()
def validate(files: Annotated[list[Path], typer.Argument(help="experiment or scenario YAML files")]) -> None:
    """Check configs (and solve their observer designs) without running them."""
    from marinebench.config import is_scenario_file, load_scenario

    for f in files:
        try:
            if is_scenario_file(f):
                load_scenario(f)
            else:
                _load(f, [], None, None)
        except MarinebenchError as exc:
            fail(str(exc))
        out.print(f"{f}: ok", markup=False)


@app.command()
def schema(kind: Annotated[str, typer.Option(help="experiment or scenario")] = "experiment") -> None:
    """Print the JSON Schema of experiment (or scenario) YAML files."""
    from marinebench.config import Experiment
    from marinebench.scenario import Scenario

    models = {"experiment": Experiment, "scenario": Scenario}
    if kind not in models:
        fail(f"--kind: expected one of {sorted(models)}, got '{kind}'")
    sys.stdout.write(json.dumps(models[kind].model_json_schema(), indent=2) + "\n")


@app.command(name="list")
def list_kinds() -> None:
    """List registered kinds: vessels, observers, signals, noise models, metrics."""
    from marinebench.registry import kinds

    for group, entries in kinds().items():
        out.print(f"[bold]{group}[/bold]")
        for name, doc in entries.items():
            out.print(f"  {name:<22} {doc}", markup=False)


def main() -> None:  # pragma: no cover - console entry point
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
