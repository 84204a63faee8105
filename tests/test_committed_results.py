"""The committed results (and the CI gate's quick reference) are self-consistent: each folder's ``table.md`` and ``claims.md`` are what the current code
makes of its own ``metrics.csv`` and ``config.resolved.yaml``, so that anyone can derive them from the files (and
a change to the tables or claims that was not rerun shows here)."""

import json
from pathlib import Path

import pandas as pd
import pytest

from marinebench.experiments.curves import sweep_claims, sweep_table
from marinebench.experiments.grid import grid_claims, grid_claims_markdown, grid_table
from marinebench.experiments.runner import summarise
from marinebench.experiments.settings import tuning
from marinebench.loading import load_experiment
from marinebench.results.claims import evaluate
from marinebench.results.claims import markdown as claims_markdown
from marinebench.results.tables import markdown_table

from .conftest import ROOT

FOLDERS = sorted(p for top in ("results", "reference/quick") for p in (ROOT / top).iterdir() if (p / "manifest.json").exists())


def _read(folder: Path):
    manifest = json.loads((folder / "manifest.json").read_text())
    exp, _ = load_experiment(folder / "config.resolved.yaml")
    metrics = pd.read_csv(folder / "metrics.csv", keep_default_na=False, na_values=[""])
    claims = (folder / "claims.md").read_text() if (folder / "claims.md").exists() else None
    return manifest, exp, metrics, claims


def _experiment_files(exp, metrics) -> tuple[str, str | None]:
    checked = evaluate(exp, metrics)
    return markdown_table(exp, summarise(metrics)), claims_markdown(exp, checked) if checked else None


def _sweep_files(manifest: dict, base, metrics) -> tuple[str, str | None]:
    spec = base.sweep
    table = grid_table if manifest["grid"] else sweep_table
    text = "\n".join(table(metrics, metric, spec, model=base.model_label()) for metric in spec.shown)
    exp = base.model_copy(update={"name": manifest["experiment"]})  # the sweep's experiment, as far as claims.md shows it
    if manifest["grid"]:
        mapped = grid_claims(metrics, spec)
        own = {p: tuning(base, p) for p in manifest["params"]}
        return text, grid_claims_markdown(exp, mapped, own) if mapped else None
    checked = sweep_claims(metrics, spec)
    title = f"sweep of {Path(manifest['config_files']['experiment']).name}"
    return text, claims_markdown(exp, checked, where="group", title=title) if checked else None


def test_there_are_experiments_and_sweeps():
    kinds = {"params" in json.loads((f / "manifest.json").read_text()) for f in FOLDERS}
    assert len(FOLDERS) >= 30 and kinds == {True, False}


@pytest.mark.parametrize("folder", FOLDERS, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_table_and_claims_are_made_from_the_folders_own_metrics(folder):
    manifest, exp, metrics, claims = _read(folder)
    table, made_claims = _sweep_files(manifest, exp, metrics) if "params" in manifest else _experiment_files(exp, metrics)
    assert table == (folder / "table.md").read_text(), f"{folder.name}/table.md is not what its metrics.csv makes"
    assert made_claims == claims, f"{folder.name}/claims.md is not what its metrics.csv makes"
