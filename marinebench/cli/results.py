"""The commands that read written results: ``compare``, ``report`` and ``figures``."""

from __future__ import annotations

import json
import sys
from enum import Enum
from pathlib import Path
from typing import Annotated

import typer

from marinebench.cli.common import Unpaired, err, fail, one_line_errors, out
from marinebench.errors import MarinebenchError


def _write_text(path: Path, text: str, option: str) -> None:
    """Write one output file atomically; a path that cannot be written is one line naming the option."""
    from marinebench.results.writer import atomic_write_text

    try:
        atomic_write_text(path, text)
    except FileExistsError:  # mkdir of a parent that is a file
        fail(f"{option}: {path}: a parent is a file, not a folder")
    except OSError as exc:
        fail(f"{option}: {path}: cannot write ({exc.strerror or exc})")


class Format(str, Enum):
    md = "md"
    json = "json"
    csv = "csv"


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
    """compare's output in ``fmt``: markdown (the worse, missing, changed and better cells; ``all_cells``: every one), json
    (headline, notes and every cell) or csv (every cell)."""
    from marinebench.results.compare import headline, to_markdown

    if fmt is Format.md:
        return to_markdown(table, all_cells=all_cells, paired=paired)
    if fmt is Format.json:
        return json.dumps({"summary": headline(table), "paired": paired,
                           "machines": table.attrs.get("machine_note", ""), "renamed": table.attrs.get("renamed", ""),
                           "cells": json.loads(table.to_json(orient="records"))}, indent=2) + "\n"
    return table.to_csv(index=False)


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
