"""The examples of the README and docs/commands.md, run as documented, give the figures those pages quote.

`test_docs_quote_results.py` checks the quotes of committed results; these examples write nothing under
`results/`, so each is run here at its documented size: the first experiment (2 variants x 10 seeds of 60 s), its
compare and its 8-point sweep; the custom observer's two compared variants and the custom controller's example
(5 seeds each). About 1.5 minutes on one core. A change that moves one of them (as the Bejarano LMI objective
did once, silently turning a quoted "71 % below" into 19 % above) fails here and names the sentence.
"""

from __future__ import annotations

import json
import shutil

import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from marinebench.cli import app

from .conftest import ROOT, md_row
from .test_docs_quote_results import Quote, assert_quote_holds

runner = CliRunner()
FIRST = ROOT / "examples" / "first_experiment" / "asv_observers.yaml"


@pytest.fixture(scope="module")
def first(tmp_path_factory) -> dict:
    """README, *Your first experiment*: run (10 seeds), compare --variants, sweep (--n 8), as documented."""
    out = tmp_path_factory.mktemp("runs")
    run = runner.invoke(app, ["run", str(FIRST), "--out", str(out), "--seeds", "10", "--quiet"])
    assert run.exit_code == 0, run.output
    pair = runner.invoke(app, ["compare", str(out / "asv_observers"), "--variants", "liu_eps0.1", "proposed_d1.5",
                               "--format", "json"])
    sweep = runner.invoke(app, ["sweep", "--config", str(FIRST), "delta_p1", "--n", "8", "--out", str(out), "--quiet",
                                "--jobs", "1"])
    assert sweep.exit_code == 0, sweep.output
    both = runner.invoke(app, ["sweep", "--config", str(FIRST), "noise", "--n", "6", "--variants", "all", "--out", str(out),
                               "--quiet", "--jobs", "1"])
    assert both.exit_code == 0, both.output
    cells = {c["signal"]: c for c in json.loads(pair.output)["cells"]}
    return {"out": out, "compare_exit": pair.exit_code, "cells": cells,
            "sweep": pd.read_csv(out / "asv_observers_sweep_delta_p1_n8_3seeds" / "metrics.csv"),
            "both": out / "asv_observers_sweep_noise_liu_eps0.1+proposed_d1.5_n6_3seeds"}


def test_the_first_experiment_writes_what_the_readme_lists(first):
    folder = first["out"] / "asv_observers"
    for name in ("table.md", "metrics.csv", "manifest.json", "config.resolved.yaml", "figures/surge.png"):
        assert (folder / name).exists(), name
    assert set(pd.read_csv(folder / "metrics.csv")["seed"]) == set(range(10))


def test_the_first_experiments_compare_is_as_quoted(first):
    cells = first["cells"]
    pct = {s: 100 * cells[s]["rel_change"] for s in cells}
    assert_quote_holds(Quote("README.md", "finds the proposed estimator's σ_u and σ_v errors {} % and\n{} % below",
                       lambda: [-pct["sigma_u"], -pct["sigma_v"]]))
    assert_quote_holds(Quote("README.md", "its yaw-rate and σ_r errors {} % and\n{} % above",
                       lambda: [pct["r"], pct["sigma_r"]]))
    verdicts = {s: c["verdict"] for s, c in cells.items()}
    assert verdicts == {"sigma_u": "better", "sigma_v": "better", "u": "same", "v": "same",
                        "r": "worse", "sigma_r": "worse"}, verdicts
    assert first["compare_exit"] == 1  # "and so exits 1 (something worse)"


def test_the_first_experiments_sweep_is_lowest_where_quoted(first):
    m = first["sweep"]
    assert set(m["param"]) == {"delta_p1"} and m["param_value"].nunique() == 8
    assert m["param_value"].min() == 0.5 and m["param_value"].max() == 5.0
    curve = m[m.metric == "std"].groupby(["signal", "param_value"])["value"].mean()
    lowest = [float(curve[s].idxmin()) for s in ("u", "sigma_u")]
    assert_quote_holds(Quote("README.md", "where both e_u and e_σu are\nlowest at δp = {}: at", lambda: lowest[:1]))
    assert lowest[0] == lowest[1], lowest


def test_the_first_experiments_side_by_side_sweep_is_as_quoted(first):
    """The two variants along the noise level: each ratio at no noise (recomputed from metrics.csv) and where it
    crosses 1 (as table.md's *Between variants* gives it)."""
    m = pd.read_csv(first["both"] / "metrics.csv")
    assert set(m["sweep_variant"]) == {"liu_eps0.1", "proposed_d1.5"} and m["param_value"].nunique() == 6
    means = m[m.metric == "std"].groupby(["signal", "param_value", "sweep_variant"])["value"].mean()
    ratio = {s: (means[s].xs("proposed_d1.5", level="sweep_variant") / means[s].xs("liu_eps0.1", level="sweep_variant"))
             for s in ("u", "sigma_u")}
    table = (first["both"] / "table.md").read_text()
    equal = {s: float(md_row(table, "noise", s, "proposed_d1.5 / liu_eps0.1")[7]) for s in ("u", "sigma_u")}
    assert_quote_holds(Quote("README.md", "without noise the proposed estimator's e_u is {}× Liu's and its e_σu {}×,\nand "
                             "its ratio to Liu's crosses 1 at {} of the noise for e_σu and at {} for e_u",
                             lambda: [ratio["u"].iloc[0], ratio["sigma_u"].iloc[0], equal["sigma_u"], equal["u"]]))
    assert ratio["sigma_u"].iloc[-1] < 1 < ratio["sigma_u"].iloc[0]  # better with the noise, worse without


def test_the_custom_observer_example_is_as_quoted(tmp_path):
    """README and docs/commands.md: the earth-frame ESO (omega = 5) beside Liu's ESO (eps = 0.2), 5 seeds. Only the
    two compared variants run: a variant's numbers do not depend on the others (same seeds, same world)."""
    folder = ROOT / "examples" / "custom_observer"
    shutil.copy(folder / "earth_eso.py", tmp_path)
    doc = yaml.safe_load((folder / "earth_eso.yaml").read_text())
    doc["scenario"] = str(ROOT / "scenarios" / "cs2_noisy.yaml")
    doc["variants"] = [v for v in doc["variants"] if v["name"] in ("earth_eso_w5", "liu_eps0.2")]
    config = tmp_path / "earth_eso.yaml"
    config.write_text(yaml.safe_dump(doc, sort_keys=False))
    res = runner.invoke(app, ["run", str(config), "--out", str(tmp_path), "--quiet"])
    assert res.exit_code == 0, res.output
    m = pd.read_csv(tmp_path / "earth_eso" / "metrics.csv")
    assert m["seed"].nunique() == 5
    mean = m[m.metric == "std"].groupby(["variant", "signal"])["value"].mean()
    figures = [mean[("earth_eso_w5", "u")], mean[("liu_eps0.2", "u")],
               mean[("earth_eso_w5", "sigma_u")], mean[("liu_eps0.2", "sigma_u")]]
    for doc_file in ("README.md", "docs/commands.md"):
        assert_quote_holds(Quote(doc_file, "(ω = 5 ↔ ε = 0.2: e_u {} vs {}, e_σu\n{} vs {}, 5 seeds)", lambda: figures))


def test_the_custom_controller_example_is_as_quoted(tmp_path):
    """docs/commands.md: the example PID's depth RMSE on S1 beside S+RISE's and RISE's (5 seeds, as committed)."""
    config = ROOT / "examples" / "custom_controller" / "pid_s1.yaml"
    res = runner.invoke(app, ["run", str(config), "--out", str(tmp_path), "--quiet"])
    assert res.exit_code == 0, res.output
    m = pd.read_csv(tmp_path / "pid_s1" / "metrics.csv")
    assert m["seed"].nunique() == 5
    rmse = m[(m.metric == "rmse") & (m.signal == "depth")].groupby("variant")["value"].mean()
    assert_quote_holds(Quote("docs/commands.md", "its untuned default tracks depth to {} m RMSE (S+RISE {}, RISE {};",
                       lambda: [rmse["pid"], 100 * rmse["srise"], 100 * rmse["rise"]]))
