"""compare: planted regressions caught, noise within tolerance not, missing cells, exit codes, CIs."""

import io
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from scipy.stats import t as student_t
from typer.testing import CliRunner

from marinebench.cli import app
from marinebench.results.compare import (
    COLUMNS,
    Tolerance,
    compare_frames,
    compare_variants,
    paired_bootstrap_ci,
    paired_t_ci,
    relative_change_ci,
    welch_ci,
)

from .conftest import ROOT, tidy_metrics

runner = CliRunner()


def write_result(root: Path, experiment: str, values: dict, seeds: int = 8, horizon: float = 10.0,
                 status: dict | None = None, root_seed: int = 1) -> Path:
    """A synthetic result directory: values[(variant, signal)] -> per-seed array of metric ``std``
    (values[(variant, signal, metric)] for another metric)."""
    d = root / experiment
    d.mkdir(parents=True)
    rows = []
    for (variant, signal, *metric), vals in values.items():
        for s in range(seeds):
            st = (status or {}).get((variant, signal, s), "ok")
            rows.append((experiment, "scen", variant, s, signal, metric[0] if metric else "std",
                         np.nan if st != "ok" else vals[s], st))
    pd.DataFrame(rows, columns=["experiment", "scenario", "variant", "seed", "signal", "metric", "value", "status"]) \
        .to_csv(d / "metrics.csv", index=False)
    (d / "config.resolved.yaml").write_text(yaml.safe_dump({"scenario": {"horizon": horizon}, "seed": root_seed,
                                                           "metrics": []}))
    return d


@pytest.fixture
def base_values():
    rng = np.random.default_rng(0)
    return {(v, s): 0.1 + 0.02 * rng.random(8) for v in ("a", "b") for s in ("u", "v")}


def test_planted_regression_is_caught_and_listed_first(tmp_path, base_values):
    write_result(tmp_path / "base", "exp", base_values)
    cand = dict(base_values)
    cand[("b", "v")] = base_values[("b", "v")] * 1.3  # planted: 30 % worse on every seed
    rng = np.random.default_rng(1)
    cand[("a", "u")] = base_values[("a", "u")] * (1 + 0.005 * rng.standard_normal(8))  # noise within tolerance
    write_result(tmp_path / "cand", "exp", cand)
    res = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand")])
    assert res.exit_code == 1
    lines = res.output.splitlines()
    assert lines[0] == "### marinebench compare: 1 worse, 0 better, 3 same"
    first = lines[4]
    assert "WORSE" in first and "| b | v |" in first
    # the interval is in the change column's unit (% of the baseline): +30 % on every seed, so on every resample
    lo, hi = (float(x) for x in re.search(r"\| \+30\.0% \| \[\+([\d.]+)%, \+([\d.]+)%\] \|", first).groups())
    assert lo == hi == 30.0


def test_seeds_run_on_one_side_only_are_left_out_and_said(tmp_path, base_values):
    """A candidate run with more seeds than the baseline: each cell is paired on the 5 seeds both ran, the
    JSON counts the 3 others as unpaired, and the summary says so (a gate must not hide what it compared)."""
    write_result(tmp_path / "base", "exp", base_values, seeds=5)
    write_result(tmp_path / "cand", "exp", base_values, seeds=8)
    res = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand"), "--format", "json"])
    cells = json.loads(res.output)["cells"]
    assert res.exit_code == 0 and {(c["n"], c["unpaired"], c["verdict"]) for c in cells} == {(5, 3, "same")}
    res = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand")])
    assert res.output.splitlines()[-1] == ("4 cell(s) have seeds that only one side ran (up to 3 per cell): they are "
                                           "left out, each cell is compared on the seeds both ran (`seeds`).")
    same = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "base")])
    assert "only one side ran" not in same.output


def test_identical_results_are_all_same(tmp_path, base_values):
    write_result(tmp_path / "base", "exp", base_values)
    write_result(tmp_path / "cand", "exp", base_values)
    res = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand"), "--format", "json"])
    assert res.exit_code == 0
    doc = json.loads(res.output)
    assert doc["summary"] == "0 worse, 0 better, 4 same"
    assert {c["verdict"] for c in doc["cells"]} == {"same"}


def test_improvement_and_missing_and_new_cells(tmp_path, base_values):
    write_result(tmp_path / "base", "exp", base_values)
    cand = {k: v for k, v in base_values.items() if k != ("a", "v")}
    cand[("a", "u")] = base_values[("a", "u")] * 0.5
    cand[("c", "u")] = base_values[("a", "u")]
    write_result(tmp_path / "cand", "exp", cand)
    out = tmp_path / "cmp.csv"
    res = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand"), "--format", "csv",
                              "--output", str(out)])
    assert res.exit_code == 0, res.output  # nothing worse
    table = pd.read_csv(out)
    verdicts = dict(zip(zip(table["variant"], table["signal"]), table["verdict"]))
    assert verdicts[("a", "u")] == "better" and verdicts[("a", "v")] == "missing" and verdicts[("c", "u")] == "new"
    assert list(table["verdict"])[:2] == ["missing", "new"]
    assert list(table.columns) == ["experiment", "scenario", "variant", "signal", "metric", *COLUMNS]
    missing = table[table["verdict"] == "missing"].iloc[0]  # its baseline mean, nothing for the candidate
    assert missing["baseline"] == pytest.approx(base_values[("a", "v")].mean()) and np.isnan(missing["candidate"])
    md = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand")]).output
    row = next(line for line in md.splitlines() if "MISSING" in line.upper() and "| a | v |" in line)
    assert f"| {base_values[('a', 'v')].mean():.4g} | – |" in row, row
    strict = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand"), "--strict"])
    assert strict.exit_code == 1 and "1 missing" in strict.output  # a dropped cell fails a strict gate
    only_new = runner.invoke(app, ["compare", str(tmp_path / "cand"), str(tmp_path / "cand"), "--strict"])
    assert only_new.exit_code == 0


def test_a_diagnostic_that_moved_is_changed_not_worse(tmp_path, base_values):
    """The resetting observer's reset count has no better side: more resets after a change (or a variant that resets
    beside one that never does) is listed as changed, and the gate passes; the same move of an error fails it."""
    jumps = np.array([3.0, 4, 3, 5, 4, 3, 4, 4])
    write_result(tmp_path / "base", "exp", base_values | {("a", "z", "n_jumps"): jumps})
    write_result(tmp_path / "cand", "exp", base_values | {("a", "z", "n_jumps"): jumps + 2})
    res = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand")])
    assert res.exit_code == 0, res.output
    assert res.output.startswith("### marinebench compare: 0 worse, 0 better, 1 changed, 4 same")
    assert "| changed | exp | scen | a | z | n_jumps | 3.75 | 5.75 | +53.3% |" in res.output
    write_result(tmp_path / "worse", "exp", base_values | {("a", "z", "n_jumps"): jumps,
                                                           ("a", "u"): base_values[("a", "u")] + 2})
    res = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "worse")])
    assert res.exit_code == 1 and "0 worse" not in res.output, res.output


def test_cells_are_listed_worse_missing_new_better_same(tmp_path, base_values):
    """The table's order is the verdicts' severity, whatever the size of the changes (the better cell's -50 % is
    larger than the worse cell's +30 %) or the cells' names (the new cell a/w sorts before the missing b/v)."""
    write_result(tmp_path / "base", "exp", base_values)
    cand = {k: v for k, v in base_values.items() if k != ("b", "v")}
    cand[("a", "u")] = base_values[("a", "u")] * 0.5
    cand[("b", "u")] = base_values[("b", "u")] * 1.3
    cand[("a", "w")] = base_values[("a", "u")]
    write_result(tmp_path / "cand", "exp", cand)
    table = compare_frames(pd.read_csv(tmp_path / "base" / "exp" / "metrics.csv"),
                           pd.read_csv(tmp_path / "cand" / "exp" / "metrics.csv"))
    assert list(zip(table["verdict"], table["variant"], table["signal"])) == [
        ("worse", "b", "u"), ("missing", "b", "v"), ("new", "a", "w"), ("better", "a", "u"), ("same", "a", "v")]


def test_markdown_lists_changed_cells_and_counts_the_rest(tmp_path, base_values):
    write_result(tmp_path / "base", "exp", base_values)
    cand = dict(base_values)
    cand[("a", "u")] = base_values[("a", "u")] * 0.5
    cand[("c", "u")] = base_values[("a", "u")]
    write_result(tmp_path / "cand", "exp", cand)
    args = ["compare", str(tmp_path / "base"), str(tmp_path / "cand")]
    rows = [ln for ln in runner.invoke(app, args).output.splitlines() if ln.startswith("| ") and "---" not in ln][1:]
    assert [r.split(" | ")[0] for r in rows] == ["| **better**"]
    assert "3 same and 1 new cell(s) not listed" in runner.invoke(app, args).output
    every = runner.invoke(app, [*args, "--all"]).output
    assert len([ln for ln in every.splitlines() if ln.startswith("| ")][1:]) == 5  # 4 paired cells and the new one
    assert "not listed" not in every


def test_an_experiment_on_one_side_only_is_one_row(tmp_path, base_values):
    """A candidate that ran a subset of the baseline's configs: each absent experiment is one row."""
    write_result(tmp_path / "base", "exp", base_values)
    write_result(tmp_path / "base", "gone", base_values)
    write_result(tmp_path / "cand", "exp", base_values)
    args = ["compare", str(tmp_path / "base"), str(tmp_path / "cand")]
    res = runner.invoke(app, args)
    assert res.exit_code == 0
    lines = res.output.splitlines()
    assert lines[0] == "### marinebench compare: 0 worse, 0 better, 4 same, 4 missing (1 whole experiment(s) only in the baseline)"
    rows = [ln for ln in lines if ln.startswith("| ") and "---" not in ln][1:]
    assert rows == [("| **missing** | gone | – | – | whole experiment, only in the baseline: 4 cell(s), 0 claim(s) "
                     "| – | – | – | – | – | – |")]
    assert lines[-1] == "4 same cell(s) not listed (`--all` lists every cell)."
    assert runner.invoke(app, [*args, "--strict"]).exit_code == 1  # an experiment the candidate lacks fails strictly
    every = [ln for ln in runner.invoke(app, [*args, "--all"]).output.splitlines() if ln.startswith("| ")][1:]
    assert len(every) == 8 and sum("| gone |" in r for r in every) == 4
    # a variant dropped from an experiment that is still there stays a cell-level row
    write_result(tmp_path / "cand2", "exp", {k: v for k, v in base_values.items() if k[0] == "a"})
    partial = runner.invoke(app, ["compare", str(tmp_path / "base" / "exp"), str(tmp_path / "cand2")])
    assert "whole experiment" not in partial.output and partial.output.count("**missing** | exp | scen | b |") == 2


def test_result_sets_with_nothing_in_common_are_refused(tmp_path, base_values):
    """A gate that pairs no cell (a wrong directory) must not pass silently."""
    write_result(tmp_path / "base", "exp", base_values)
    write_result(tmp_path / "cand", "other", base_values)
    res = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand")])
    assert res.exit_code == 2 and "no cell in common" in res.output
    assert len(res.output.strip().splitlines()) == 1


def test_a_claim_that_no_longer_holds_is_worse(tmp_path, base_values):
    """Claims come from the manifests: held -> fails is worse, fails -> holds better, a dropped one missing."""
    def claims(d, verdicts):
        (d / "manifest.json").write_text(json.dumps({"claims": [
            {"text": t, "source": "", "holds": h} for t, h in verdicts.items()]}))
    claims(write_result(tmp_path / "base", "exp", base_values), {"a < b": True, "b < a": False, "gone": True})
    claims(write_result(tmp_path / "cand", "exp", base_values), {"a < b": False, "b < a": True})
    res = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand")])
    assert res.exit_code == 1 and res.output.startswith("### marinebench compare: 1 worse, 1 better, 4 same, 1 missing")
    assert "| **WORSE** | exp | – | – | a < b | claim | holds | fails |" in res.output
    assert "| **better** | exp | – | – | b < a | claim | fails | holds |" in res.output
    only_cells = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand"), "--metric", "std"])
    assert only_cells.exit_code == 0 and "claim" not in only_cells.output


def test_a_claims_narrow_verdict_is_marked_on_its_side(tmp_path, base_values):
    """A verdict the manifest marks narrowly (its 95 % interval across the bound) says so in its column of the
    markdown and in the ``narrow`` field; the flip still counts (worse), as a gate must."""
    for side, claim in (("base", {"holds": True}), ("cand", {"holds": False, "narrowly": True})):
        d = write_result(tmp_path / side, "exp", base_values)
        (d / "manifest.json").write_text(json.dumps({"claims": [{"text": "a < b", "source": "", **claim}]}))
    res = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand")])
    assert res.exit_code == 1 and "| **WORSE** | exp | – | – | a < b | claim | holds | fails (narrowly) |" in res.output
    cells = json.loads(runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand"), "--format", "json"]).output)["cells"]
    assert [c["narrow"] for c in cells if c["metric"] == "claim"] == ["candidate"]
    assert {c["narrow"] for c in cells if c["metric"] != "claim"} == {""}


def test_newly_diverged_run_is_worse(tmp_path, base_values):
    """The cell is worse though its means (over the seeds both finished) are equal, and the row says why."""
    write_result(tmp_path / "base", "exp", base_values)
    write_result(tmp_path / "cand", "exp", base_values, status={("a", "u", 3): "diverged"})
    res = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand")])
    assert res.exit_code == 1 and "1 worse" in res.output
    assert "| a | u | std |" in res.output.splitlines()[4] and res.output.splitlines()[4].endswith("| 7, 1 diverged |")
    doc = json.loads(runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand"),
                                         "--format", "json"]).output)
    assert {(c["signal"], c["variant"]): c["diverged"] for c in doc["cells"] if c["metric"] == "std"} == \
        {("u", "a"): 1, ("u", "b"): 0, ("v", "a"): 0, ("v", "b"): 0}


def test_a_file_without_status_takes_it_from_its_values(tmp_path, base_values):
    """Older files have no ``status``: a blank (NaN) value there is a diverged run, not a NaN averaged in."""
    write_result(tmp_path / "base", "exp", base_values)
    cand = write_result(tmp_path / "cand", "exp", base_values, status={("a", "u", 3): "diverged"})
    df = pd.read_csv(cand / "metrics.csv").drop(columns="status")
    df.to_csv(cand / "metrics.csv", index=False)
    res = runner.invoke(app, ["compare", str(tmp_path / "base"), str(cand), "--format", "json"])
    worse = [c for c in json.loads(res.output)["cells"] if c["verdict"] == "worse"]
    assert res.exit_code == 1 and [(c["variant"], c["signal"], c["n"], c["diverged"]) for c in worse] == \
        [("a", "u", 7, 1)]


def test_unusable_inputs_exit_2(tmp_path, base_values):
    write_result(tmp_path / "base", "exp", base_values)
    write_result(tmp_path / "other", "exp", base_values, horizon=20.0)
    for name in ("exp2", "exp3"):  # two more experiments with other worlds: named after the first
        write_result(tmp_path / "base", name, base_values)
        write_result(tmp_path / "other", name, base_values, horizon=20.0)
    (tmp_path / "empty").mkdir()
    cases = [
        ([str(tmp_path / "base"), str(tmp_path / "nope")], "no such directory"),
        ([str(tmp_path / "base"), str(tmp_path / "empty")], "no metrics.csv found"),
        ([str(tmp_path / "base"), str(tmp_path / "other")],
         "mismatched configs for experiment 'exp' (" + str(tmp_path / "base" / "exp")),
        ([str(tmp_path / "base"), str(tmp_path / "other")], "scenario.horizon; and for 2 more: exp2, exp3"),
        ([str(tmp_path / "base"), "--variants", "a", "zz"], "no variant 'zz'"),
        ([str(tmp_path / "base"), "--variants", "a", "a"], "error: --variants: A and B are both 'a'; name two different"),
        ([str(tmp_path / "base")], "missing CANDIDATE"),
    ]
    for args, message in cases:
        res = runner.invoke(app, ["compare", *args])
        assert res.exit_code == 2 and message in res.output, (args, res.output)
        assert len(res.output.strip().splitlines()) == 1


def test_a_metric_no_cell_has_is_refused(tmp_path, base_values):
    """A mistyped --metric would leave nothing to compare, and a gate that compares nothing passes."""
    write_result(tmp_path / "base", "exp", base_values)
    for args, have in (([str(tmp_path / "base"), str(tmp_path / "base")], "claim, std"),
                       ([str(tmp_path / "base" / "exp"), "--variants", "a", "b"], "std")):
        res = runner.invoke(app, ["compare", *args, "--metric", "std", "--metric", "sdt"])
        assert res.exit_code == 2 and res.output.strip() == f"error: --metric: no cell has metric 'sdt' (have: {have})"
    res = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "base"), "--metric", "claim"])
    assert res.exit_code == 2 and "no cell in common" in res.output, res.output  # no manifests, so no claims either
    res = runner.invoke(app, ["compare", str(tmp_path / "base" / "exp"), "--variants", "a", "b", "--metric", "claim"])
    assert res.exit_code == 2 and res.output.strip() == "error: --metric: no cell has metric 'claim' (have: std)"  # an
    # experiment's claims are not a variant's (before: "no variant 'a' (have: )")


def test_tree_with_duplicate_experiment_is_unusable(tmp_path, base_values):
    write_result(tmp_path / "tree" / "x", "exp", base_values)
    write_result(tmp_path / "tree" / "y", "exp", base_values)
    res = runner.invoke(app, ["compare", str(tmp_path / "tree"), str(tmp_path / "tree")])
    assert res.exit_code == 2 and "appears twice" in res.output


def test_variant_comparison_inside_one_run(tmp_path, base_values):
    vals = dict(base_values)
    vals[("b", "u")] = base_values[("a", "u")] * 1.5
    vals[("b", "v")] = base_values[("a", "v")]
    write_result(tmp_path, "exp", vals)
    res = runner.invoke(app, ["compare", str(tmp_path / "exp"), "--variants", "a", "b"])
    assert res.exit_code == 1
    assert "| b vs a | u | std |" in res.output and "1 worse, 0 better, 1 same" in res.output
    table = compare_variants(tmp_path / "exp", "a", "b")  # the columns of a comparison of two runs
    assert list(table.columns) == ["experiment", "scenario", "variant", "signal", "metric", *COLUMNS]
    assert list(table["variant"]) == ["b vs a"] * 2
    u = table[table["signal"] == "u"].iloc[0]  # the paired t interval of the per-seed differences, in % of a's mean
    diff = base_values[("a", "u")] * 0.5
    half = student_t.ppf(0.975, diff.size - 1) * diff.std(ddof=1) / np.sqrt(diff.size)
    assert (u.ci_low, u.ci_high) == pytest.approx((diff.mean() - half, diff.mean() + half))
    assert u.rel_ci_low == pytest.approx(u.ci_low / base_values[("a", "u")].mean())
    assert "paired Student t interval" in res.output


def test_variants_over_a_tree_of_runs_and_sweeps(tmp_path, base_values):
    """--variants over a tree (results/) that holds runs, a sweep of several variants side by side and a
    one-variant sweep: the runs' cells and the sweep's points are compared (before: the sweep's column hid every
    run, '0 worse, 0 better, 0 same', exit 0); a refusal names the variants, not the points; two variants never
    run beside each other are refused, as two directories with no cell in common are."""
    tree = tmp_path / "tree"
    write_result(tree, "exp", base_values)
    for name, variants in (("sw", ("a", "b")), ("one", ("k_000_default", "k_001_default"))):
        d = write_result(tree, name, {(v, "u"): base_values[("a", "u")] for v in variants})
        m = pd.read_csv(d / "metrics.csv")
        m = m.assign(param="k", param_value=[float(v.endswith("1_default")) for v in m["variant"]], gnss="default")
        if name == "sw":  # each variant at two points
            m = pd.concat([m.assign(param_value=0.0), m.assign(param_value=1.0)])
            points = [f"{v}_k_{x:03.0f}" for v, x in zip(m["variant"], m["param_value"])]
            m = m.assign(sweep_variant=m["variant"], variant=points)
        m.to_csv(d / "metrics.csv", index=False)
    write_result(tree, "solo", {("c", "u"): base_values[("a", "u")]})
    write_result(tree, "lone", {("d", "u"): base_values[("a", "u")]})
    grid = write_result(tree, "grid", {("k_000_eps_000_default", "u"): base_values[("a", "u")]})  # gives the tree
    m = pd.read_csv(grid / "metrics.csv")  # param2 columns, blank in the other sweeps' rows
    m.assign(param="k", param_value=0.0, param2="eps", param2_value=0.0, gnss="default").to_csv(grid / "metrics.csv",
                                                                                              index=False)
    res = runner.invoke(app, ["compare", str(tree), "--variants", "a", "b", "--format", "csv"])
    assert res.exit_code in (0, 1), res.output
    cells = pd.read_csv(io.StringIO(res.output))
    assert sorted(zip(cells["experiment"], cells["variant"], cells["signal"])) == [
        ("exp", "b vs a", "u"), ("exp", "b vs a", "v"), ("sw", "k=0: b vs a", "u"), ("sw", "k=1: b vs a", "u")]
    res = runner.invoke(app, ["compare", str(tree), "--variants", "c", "d"])
    assert res.exit_code == 2 and res.output.strip() == (
        f"error: {tree}: variants 'c' and 'd' have no cell in common (experiment, scenario, signal, metric; a sweep's "
        "point): neither was run beside the other")
    res = runner.invoke(app, ["compare", str(tree), "--variants", "a", "zz"])
    assert res.exit_code == 2 and res.output.strip().endswith("no variant 'zz' (have: a, b, c, d)"), res.output


def test_interval_chooses_the_ci_of_a_paired_comparison(tmp_path, base_values):
    """--interval t between two runs (e.g. one-variant sweeps of two variants) gives the paired t interval and says so
    under the table; --interval bootstrap with --variants the gate's; a wrong value or one with --unpaired is one
    line, exit 2."""
    cand = dict(base_values)
    cand[("a", "u")] = base_values[("a", "u")] * 1.5
    for side, values in (("base", base_values), ("cand", cand)):  # with a claim each: its rows join the cells' table
        d = write_result(tmp_path / side, "exp", values)
        (d / "manifest.json").write_text(json.dumps({"claims": [{"text": "a < b", "source": "", "holds": True}]}))
    t = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand"), "--interval", "t", "--format", "json"])
    (u,) = [c for c in json.loads(t.output)["cells"] if c["variant"] == "a" and c["signal"] == "u"]
    lo, hi = paired_t_ci(base_values[("a", "u")] * 0.5)
    assert t.exit_code == 1 and (u["ci_low"], u["ci_high"]) == pytest.approx((lo, hi))
    md = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand"), "--interval", "t"]).output
    assert "paired Student t interval" in md
    boot = runner.invoke(app, ["compare", str(tmp_path / "base"), "--variants", "a", "b", "--interval", "bootstrap"])
    assert "paired Student t interval" not in boot.output
    for bad, says in ((["--interval", "z"], "--interval: 'bootstrap' or 't'"), (["--interval", "t", "--unpaired"], "Welch")):
        res = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand"), *bad])
        assert res.exit_code == 2 and says in res.output and len(res.output.strip().splitlines()) == 1


@pytest.mark.parametrize("seeds", [2, 3, 5])
def test_the_paired_t_interval_holds_its_level_on_differences_that_are_noise(seeds):
    """Per-seed differences drawn around zero: the 95 % interval excludes zero in 5 % of 2000 draws (within 4
    standard errors of the share), at any number of seeds; the percentile bootstrap does far more often."""
    rng = np.random.default_rng(seeds)
    draws = [rng.normal(0.0, 1.0, seeds) for _ in range(2000)]
    t_excludes = np.mean([not (lo <= 0.0 <= hi) for lo, hi in map(paired_t_ci, draws)])
    assert 0.03 <= t_excludes <= 0.07
    boot_excludes = np.mean([not (lo <= 0.0 <= hi) for lo, hi in (paired_bootstrap_ci(d, n_boot=200, seed=i)
                                                                   for i, d in enumerate(draws[:500]))])
    assert boot_excludes > 0.12
    assert np.isnan(paired_t_ci(np.array([1.0]))).all()


def test_names_that_look_like_numbers_or_blanks_stay_names(tmp_path, base_values):
    """A config, scenario or variant may be named "123", "1" or "NA" (config.NAME): read back from metrics.csv they
    stay names, not numbers (before: a traceback in report and compare --variants) or blanks (a refusal)."""
    vals = {("1" if v == "a" else "NA", s): x for (v, s), x in base_values.items()}
    vals[("NA", "u")] = vals[("1", "u")] * 1.5
    for side in ("base", "cand"):
        write_result(tmp_path / side, "123", vals)
    res = runner.invoke(app, ["compare", str(tmp_path / "base" / "123"), "--variants", "1", "NA"])
    assert res.exit_code == 1 and "| **WORSE** | 123 | scen | NA vs 1 | u | std |" in res.output, res.output
    res = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand")])
    assert res.exit_code == 0 and "0 worse, 0 better, 4 same" in res.output, res.output
    res = runner.invoke(app, ["report", str(tmp_path / "cand"), "--out", str(tmp_path / "r.html")])
    assert res.exit_code == 0, res.output
    assert 'href="#123"' in (tmp_path / "r.html").read_text()


def test_bootstrap_ci_coverage_on_synthetic_data():
    rng = np.random.default_rng(3)
    hits = 0
    for _ in range(400):
        d = rng.normal(0.5, 1.0, 20)
        lo, hi = paired_bootstrap_ci(d, n_boot=1000, seed=int(rng.integers(1 << 30)))
        hits += lo <= 0.5 <= hi
    assert 0.9 <= hits / 400 <= 0.98  # percentile bootstrap is slightly liberal at n = 20


def test_bootstrap_ci_has_the_width_of_its_level():
    """With many seeds the percentile bootstrap of a mean is the normal interval: half-width 1.96 s / sqrt(n) at
    95 % (1.64 at 90 %), whatever the draw."""
    for s in range(5):
        d = np.random.default_rng(s).normal(0.3, 1.0, 400)
        se = d.std(ddof=1) / np.sqrt(d.size)
        for level, z in ((0.95, 1.959964), (0.9, 1.644854)):
            lo, hi = paired_bootstrap_ci(d, level=level, seed=s)
            assert (hi - lo) / 2 == pytest.approx(z * se, rel=0.06), (s, level)
            assert (hi + lo) / 2 == pytest.approx(d.mean(), abs=0.15 * se)


def test_an_interval_that_reaches_zero_is_no_change():
    """One seed of five changed and the others identical: a third of the resamples leave that seed out, so the
    interval of the difference starts at exactly 0, and a change whose interval contains zero is "same"."""
    base = pd.DataFrame({"experiment": "e", "scenario": "s", "variant": "a", "seed": range(5), "signal": "u",
                         "metric": "std", "value": 1.0, "status": "ok"})
    cand = base.assign(value=[1.0, 1.0, 1.0, 1.0, 1.5])
    row = compare_frames(base, cand).iloc[0]
    assert row["ci_low"] == 0.0 and row["ci_high"] > 0.02 * 1.0
    assert row["verdict"] == "same"
    better = compare_frames(base, base.assign(value=[1.0, 1.0, 1.0, 1.0, 0.5])).iloc[0]  # and ending at 0
    assert better["ci_high"] == 0.0 and better["ci_low"] < -0.02 and better["verdict"] == "same"


def test_the_ci_of_a_relative_change_is_one_of_ratios(tmp_path):
    """Errors cut to a tenth on every seed, one seed's ten times the others': the change is −90 % on every
    resample. Dividing the CI of the mean difference by the baseline's mean printed [−225 %, …], below −100 %
    for an error that cannot go negative."""
    base = np.array([1.0, 1.0, 10.0])
    lo, _ = paired_bootstrap_ci(0.1 * base - base)
    assert lo / base.mean() < -1.0  # what was printed before
    assert relative_change_ci(base, 0.1 * base) == pytest.approx((-0.9, -0.9))
    write_result(tmp_path / "a", "exp", {("a", "u"): base}, seeds=3)
    write_result(tmp_path / "b", "exp", {("a", "u"): 0.1 * base}, seeds=3)
    res = runner.invoke(app, ["compare", str(tmp_path / "a"), str(tmp_path / "b")])
    assert "| -90.0% | [-90.0%, -90.0%] | 3 |" in res.output, res.output


def test_relative_ci_agrees_with_the_difference_on_zero():
    rng = np.random.default_rng(5)
    for _ in range(200):
        b = rng.uniform(0.5, 2.0, 6)
        c = b * rng.normal(1.0, 0.1, 6)
        lo, hi = paired_bootstrap_ci(c - b, n_boot=400, seed=1)
        rlo, rhi = relative_change_ci(b, c, n_boot=400, seed=1)
        assert np.sign(lo) == np.sign(rlo) or min(abs(lo), abs(rlo)) < 1e-2
        assert np.sign(hi) == np.sign(rhi) or min(abs(hi), abs(rhi)) < 1e-2


def test_tolerance_decides_with_one_seed():
    base = pd.DataFrame({"experiment": "e", "scenario": "s", "variant": "a", "seed": [0], "signal": "u",
                         "metric": "std", "value": [1.0], "status": "ok"})
    small = base.assign(value=[1.01])
    big = base.assign(value=[1.5])
    assert compare_frames(base, small, Tolerance(rtol=0.02))["verdict"][0] == "same"
    assert compare_frames(base, big, Tolerance(rtol=0.02))["verdict"][0] == "worse"
    # rtol is relative to the baseline: 0.5 is above 0.4 x 1.0, though within 0.4 x the candidate's 1.5
    assert compare_frames(base, big, Tolerance(rtol=0.4))["verdict"][0] == "worse"
    assert compare_frames(base, big, Tolerance(rtol=0.5))["verdict"][0] == "same"


def test_real_run_compared_with_itself_rerun(tiny_config, tmp_path):
    """A fresh run with the same config and seeds is 'same' everywhere; a worse tuning is caught."""
    for name, sets in (("a", []), ("b", []), ("c", ["--set", "variants[proposed_d1.2].observer.delta_p1=6"])):
        assert runner.invoke(app, ["run", str(tiny_config), "--out", str(tmp_path / name), "--quiet", *sets]).exit_code == 0
    res = runner.invoke(app, ["compare", str(tmp_path / "a"), str(tmp_path / "b")])
    assert res.exit_code == 0 and "0 worse, 0 better, 12 same" in res.output
    res = runner.invoke(app, ["compare", str(tmp_path / "a"), str(tmp_path / "c")])
    assert res.exit_code == 1 and "proposed_d1.2" in res.output.splitlines()[4]
    shutil.rmtree(tmp_path / "c")


def test_results_from_another_cpu_are_named_under_the_table(tmp_path):
    """Manifests from different hardware: the summary says so (a last-digit difference is then no mystery);
    from the same hardware, or without a machine record (older results), it says nothing."""

    for name in ("here", "same", "there"):
        shutil.copytree(ROOT / "reference" / "quick" / "torben_fig1", tmp_path / name / "torben_fig1")
    manifest = tmp_path / "there" / "torben_fig1" / "manifest.json"
    doc = json.loads(manifest.read_text())
    doc["machine"] = {"cpu": "Other CPU", "numpy_simd": ["X86_V3", "X86_V4"]}
    manifest.write_text(json.dumps(doc))
    res = runner.invoke(app, ["compare", str(tmp_path / "here"), str(tmp_path / "there")])
    assert res.exit_code == 0 and "Computed on different machines" in res.output
    assert "candidate: Other CPU, numpy X86_V3+X86_V4)" in res.output
    res = runner.invoke(app, ["compare", str(tmp_path / "here"), str(tmp_path / "there"), "--format", "json"])
    assert "Other CPU" in json.loads(res.output)["machines"]
    assert "different machines" not in runner.invoke(app, ["compare", str(tmp_path / "here"), str(tmp_path / "same")]).output
    del doc["machine"]
    manifest.write_text(json.dumps(doc))
    assert "different machines" not in runner.invoke(app, ["compare", str(tmp_path / "here"), str(tmp_path / "there")]).output


def test_a_reference_older_than_an_option_still_pairs(tmp_path):
    """A reference written before an option existed (absent there, at its default now) pairs with a new run;
    a different value of the same option does not."""

    ref = ROOT / "reference" / "quick" / "torben_fig1"
    for name in ("old", "new", "changed"):
        shutil.copytree(ref, tmp_path / name / "torben_fig1")
    old = tmp_path / "old" / "torben_fig1" / "config.resolved.yaml"
    doc = yaml.safe_load(old.read_text())
    del doc["scenario"]["sensors"]["continuous_feed"]  # an option added after this reference was written
    old.write_text(yaml.safe_dump(doc, sort_keys=False))
    res = runner.invoke(app, ["compare", str(tmp_path / "old"), str(tmp_path / "new")])
    assert res.exit_code == 0 and "0 worse, 0 better" in res.output, res.output
    changed = tmp_path / "changed" / "torben_fig1" / "config.resolved.yaml"
    doc["scenario"]["sensors"]["continuous_feed"] = "hold"
    changed.write_text(yaml.safe_dump(doc, sort_keys=False))
    res = runner.invoke(app, ["compare", str(tmp_path / "old"), str(tmp_path / "changed")])
    assert res.exit_code == 2 and "scenario.sensors.continuous_feed" in res.output, res.output


DAMAGED = {
    "manifest_not_json": ("manifest.json", b"{bad", "manifest.json: invalid JSON: line 1, column 2"),
    "manifest_not_object": ("manifest.json", b"[1]", "manifest.json: expected a JSON object at the top level"),
    "manifest_bad_claims": ("manifest.json", b'{"claims": [{"text": "x"}]}',
                            "manifest.json: claims: expected a list of objects with 'text' and 'holds'"),
    "resolved_not_yaml": ("config.resolved.yaml", b"x: [\n", "config.resolved.yaml: invalid YAML: line 2"),
    "metrics_empty": ("metrics.csv", b"", "metrics.csv: not a readable CSV"),
    "metrics_no_rows": ("metrics.csv", b"experiment,scenario,variant,seed,signal,metric,value\n", "metrics.csv: no rows"),
    "metrics_foreign": ("metrics.csv", b"experiment,x\nexp,1\n", "metrics.csv: missing column(s) ['scenario', 'variant'"),
    "metrics_not_utf8": ("metrics.csv", b"\xff\xfe", "metrics.csv: not a readable CSV ('utf-8' codec"),
    "value_not_numeric": ("metrics.csv", b"experiment,scenario,variant,seed,signal,metric,value\nexp,s,a,0,u,std,x\n",
                          "metrics.csv: column 'value' is not numeric"),
    # a file cut short mid-row, and one with rows appended twice: before, tracebacks from the sort and the pairing
    "metrics_truncated": ("metrics.csv", b"experiment,scenario,variant,seed,signal,metric,value\nexp,s,a,0,u,std,0.1\nexp,s\n",
                          "metrics.csv: line 3: a row without its experiment, scenario, variant, seed, signal, metric"),
    "metrics_blank_metric": ("metrics.csv", (b"experiment,scenario,variant,seed,signal,metric,value\n"
                                             b"exp,s,a,0,u,std,0.1\nexp,s,a,0,v,,0.1\n"), "metrics.csv: line 3: a row without its"),
    "metrics_duplicated": ("metrics.csv", (b"experiment,scenario,variant,seed,signal,metric,value\n"
                                           b"exp,s,a,0,u,std,0.1\nexp,s,a,0,u,std,0.2\n"),
                           ("metrics.csv: 2 rows share their experiment, scenario, variant, seed, signal and metric "
                            "(first: experiment=exp, scenario=s, variant=a, seed=0, signal=u, metric=std)")),
    # averaged in, a NaN made the cell's means NaN and the cell `same` (rc 0); an infinity made a warning
    "metrics_nan_ok": ("metrics.csv", (b"experiment,scenario,variant,seed,signal,metric,value,status\n"
                                       b"exp,s,a,0,u,std,0.1,ok\nexp,s,a,1,u,std,nan,ok\n"),
                       "metrics.csv: line 3: value nan with status ok (a finished run's value is a finite number"),
    "metrics_inf_ok": ("metrics.csv", (b"experiment,scenario,variant,seed,signal,metric,value,status\n"
                                       b"exp,s,a,0,u,std,-inf,ok\n"), "metrics.csv: line 2: value -inf with status ok"),
}


@pytest.mark.parametrize("case", sorted(DAMAGED))
@pytest.mark.parametrize("command", ["compare", "report"])
def test_a_damaged_result_file_is_one_line_naming_it(case, command, tmp_path, base_values):
    """compare and report read files other tools (or a crash, or a hand edit) may have damaged: one line, exit 2."""
    write_result(tmp_path / "base", "exp", base_values)
    cand = write_result(tmp_path / "cand", "exp", base_values)
    name, content, expected = DAMAGED[case]
    (cand / name).write_bytes(content)
    args = ["compare", str(tmp_path / "base"), str(tmp_path / "cand")] if command == "compare" else \
        ["report", str(tmp_path / "cand"), "--out", str(tmp_path / "r.html"), "--compare", str(tmp_path / "base")]
    res = runner.invoke(app, args)
    lines = res.output.strip().splitlines()
    assert res.exit_code == 2 and len(lines) == 1 and "Traceback" not in res.output, res.output
    assert lines[0].startswith(f"error: {cand / name}") and expected in lines[0], lines[0]
    assert not (tmp_path / "r.html").exists()


def test_a_manifest_whose_claims_have_just_text_and_holds_is_read(tmp_path):
    from marinebench.results.stored import read_manifest

    (tmp_path / "manifest.json").write_text('{"claims": [{"text": "a < b", "holds": true}]}')
    assert read_manifest(tmp_path) == {"claims": [{"text": "a < b", "holds": True}]}
    assert read_manifest(tmp_path / "nowhere") == {}


def test_report_names_a_table_that_is_not_utf8(tmp_path, base_values):
    d = write_result(tmp_path / "res", "exp", base_values)
    (d / "table.md").write_bytes(b"| a |\n\xff")
    res = runner.invoke(app, ["report", str(tmp_path / "res"), "--out", str(tmp_path / "r.html")])
    assert res.exit_code == 2 and res.output.strip() == f"error: {d / 'table.md'}: not UTF-8 text (byte 6)"
    assert not (tmp_path / "r.html").exists()


def test_other_root_seeds_are_refused_paired_and_compared_unpaired(tmp_path):
    """A candidate run on another root seed has other noise on every run: pairing its seed i with the baseline's
    seed i would be meaningless, so the paired gate refuses it and says what compares it. Unpaired, every run
    of each side counts (here 8 against 5), a planted +30 % is still caught, and noise alone is not."""
    rng = np.random.default_rng(11)
    base = {(v, s): 0.1 + 0.01 * rng.standard_normal(8) for v in ("a", "b") for s in ("u", "v")}
    cand = {(v, s): 0.1 + 0.01 * rng.standard_normal(5) for v in ("a", "b") for s in ("u", "v")}
    cand[("b", "v")] = 0.13 + 0.01 * rng.standard_normal(5)
    write_result(tmp_path / "base", "exp", base, root_seed=2024)
    write_result(tmp_path / "cand", "exp", cand, seeds=5, root_seed=7)
    paired = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand")])
    assert paired.exit_code == 2 and len(paired.output.strip().splitlines()) == 1
    assert ": seed (other root seeds are not pairs: --unpaired compares them as independent samples)" in paired.output
    res = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand"), "--unpaired", "--all"])
    assert res.exit_code == 1, res.output
    lines = res.output.splitlines()
    assert lines[0] == "### marinebench compare: 1 worse, 0 better, 3 same"
    assert "| **WORSE** | exp | scen | b | v | std |" in lines[4] and lines[4].endswith("| 8/5 |")
    assert "Unpaired: each side's runs are an independent sample" in res.output
    # the other worlds' keys are still refused: only the root seed may differ
    write_result(tmp_path / "other", "exp", cand, seeds=5, horizon=20.0, root_seed=7)
    res = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "other"), "--unpaired"])
    assert res.exit_code == 2 and "scenario.horizon" in res.output and ": seed" not in res.output, res.output


def test_a_sweep_at_another_root_seed_is_compared_under_its_tagged_name(tmp_path, base_values):
    """``sweep ... --seed 7 --seeds 5`` names its experiment exp_sweep_seed=7_5seeds so that it does not replace
    the committed exp_sweep_5seeds; results of one config are still one experiment: compared as such (and said
    so), paired refused for the seed; another config's results are not paired at all."""
    dirs = {"base": ("exp_sweep_5seeds", "exp.yaml", 2024), "cand": ("exp_sweep_seed=7_5seeds", "exp.yaml", 7),
            "unrelated": ("other_sweep_5seeds", "other.yaml", 7)}
    for side, (name, config, seed) in dirs.items():
        d = write_result(tmp_path / side, name, base_values, root_seed=seed)
        (d / "manifest.json").write_text(json.dumps({"config_files": {"experiment": f"configs/{config}"}}))
    base, cand = tmp_path / "base" / "exp_sweep_5seeds", tmp_path / "cand" / "exp_sweep_seed=7_5seeds"
    res = runner.invoke(app, ["compare", str(base), str(cand), "--unpaired"])
    assert res.exit_code == 0 and res.output.startswith("### marinebench compare: 0 worse, 0 better, 4 same")
    assert "Compared as one experiment: 'exp_sweep_seed=7_5seeds' (candidate) as 'exp_sweep_5seeds'" in res.output
    paired = runner.invoke(app, ["compare", str(base), str(cand)])
    assert paired.exit_code == 2 and ": seed (other root seeds are not pairs" in paired.output
    res = runner.invoke(app, ["compare", str(base), str(tmp_path / "unrelated"), "--unpaired"])
    assert res.exit_code == 2 and "no cell in common" in res.output


def test_unpaired_single_runs_call_no_change(tmp_path, base_values):
    """One run per side on other seeds (a 1-seed sweep rerun at --seed 7): no interval exists and the noise alone
    moves a cell by more than the tolerance, so unpaired nothing is called worse or better, and a line says why.
    Paired (the same seed), one run is deterministic and the tolerance decides."""
    cand = {cell: v * 1.3 for cell, v in base_values.items()}
    write_result(tmp_path / "base", "exp", base_values, seeds=1, root_seed=2024)
    write_result(tmp_path / "cand", "exp", cand, seeds=1, root_seed=7)
    res = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "cand"), "--unpaired"])
    assert res.exit_code == 0 and res.output.startswith("### marinebench compare: 0 worse, 0 better, 4 same")
    assert "4 cell(s) have a single run on a side" in res.output
    write_result(tmp_path / "same_seed", "exp", cand, seeds=1, root_seed=2024)
    res = runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / "same_seed")])
    assert res.exit_code == 1 and res.output.startswith("### marinebench compare: 4 worse")


def test_unpaired_counts_a_larger_share_of_diverged_runs_as_worse(tmp_path, base_values):
    write_result(tmp_path / "base", "exp", base_values, status={("a", "u", 0): "diverged"})
    write_result(tmp_path / "same", "exp", base_values, status={("a", "u", 5): "diverged"}, root_seed=2)
    write_result(tmp_path / "more", "exp", base_values, status={("a", "u", s): "diverged" for s in (1, 2)}, root_seed=3)
    out = [runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / c), "--unpaired", "--format", "json"])
           for c in ("same", "more")]
    assert [r.exit_code for r in out] == [0, 1]
    doc = json.loads(out[1].output)
    assert doc["paired"] is False
    worse = [c for c in doc["cells"] if c["verdict"] == "worse"]
    assert [(c["variant"], c["signal"], c["n"], c["n_candidate"]) for c in worse] == [("a", "u", 7, 6)]


def test_unpaired_ci_is_welchs_t_interval():
    """Unequal sizes and spreads: the same interval as scipy's Welch test (Welch-Satterthwaite degrees of freedom);
    equal spreads too (a shifted copy)."""
    from scipy import stats

    rng = np.random.default_rng(8)
    for n_b, n_c, s_b, s_c in ((3, 9, 0.1, 0.5), (5, 4, 0.4, 0.05), (12, 20, 0.3, 0.5)):
        b, c = rng.normal(1.0, s_b, n_b), rng.normal(1.2, s_c, n_c)
        ci = stats.ttest_ind(c, b, equal_var=False).confidence_interval(0.95)
        assert welch_ci(b, c) == pytest.approx((ci.low, ci.high), rel=1e-9)
    b = np.array([1.0, 1.5, 3.0])
    ci = stats.ttest_ind(b + 0.25, b, equal_var=False).confidence_interval(0.95)
    assert welch_ci(b, b + 0.25) == pytest.approx((ci.low, ci.high), rel=1e-9) and ci.low < 0 < ci.high


def test_relative_change_of_a_negative_baseline_has_the_sign_of_the_change():
    """A mean-error metric can be negative: twice as negative is a change of −100 % of |baseline|, below zero like
    the difference, not +100 %."""
    base = np.array([-1.0, -1.1, -0.9, -1.05])
    lo, hi = paired_bootstrap_ci(2 * base - base)
    rlo, rhi = relative_change_ci(base, 2 * base)
    assert lo <= hi < 0 and (rlo, rhi) == pytest.approx((-1.0, -1.0))


def test_unpaired_ci_keeps_its_level_with_few_seeds():
    """Independent samples of different sizes hold the true difference about 95 % of the time, and with the
    2–3 seeds of a quick run no change at all is rarely called one (a percentile bootstrap of the two means
    would exclude zero in one case in three at 2 against 2)."""
    rng = np.random.default_rng(4)
    hits = sum(lo <= 0.2 <= hi for lo, hi in (welch_ci(rng.normal(1.0, 0.3, 12), rng.normal(1.2, 0.5, 20))
                                               for _ in range(1000)))
    assert 0.93 <= hits / 1000 <= 0.97
    for n in (2, 3):
        false = sum(not (lo <= 0.0 <= hi) for lo, hi in (welch_ci(rng.normal(1, 0.1, n), rng.normal(1, 0.1, n))
                                                          for _ in range(2000)))
        assert false / 2000 <= 0.07, (n, false)
    # a paired design cancels the noise both sides share; unpaired, the interval on the same values is wider
    b = rng.normal(1.0, 0.3, 10)
    c = b + 0.05 + 0.01 * rng.standard_normal(10)
    p_lo, p_hi = paired_bootstrap_ci(c - b)
    u_lo, u_hi = welch_ci(b, c)
    assert p_lo > 0 and u_lo < 0 < u_hi and (u_hi - u_lo) > 5 * (p_hi - p_lo)


def frame(values: dict, status: dict | None = None) -> pd.DataFrame:
    return tidy_metrics(values, status=status)


def test_welch_interval_of_runs_without_spread_is_the_difference():
    """Every run the same on each side: the change is known exactly, so the interval is that point (and not
    zero, a change)."""
    assert welch_ci(np.array([1.0, 1.0, 1.0]), np.array([1.5, 1.5])) == (0.5, 0.5)


def test_relative_interval_is_undefined_where_a_resampled_baseline_mean_is_zero():
    lo, hi = relative_change_ci(np.array([0.0, 0.0, 1.0]), np.array([1.0, 1.0, 2.0]))
    assert np.isnan(lo) and np.isnan(hi)


def test_a_seed_that_diverged_on_both_sides_is_not_a_new_divergence():
    vals = {("a", "u"): 0.1 + 0.01 * np.arange(6)}
    status = {("a", "u", 2): "diverged"}
    out = compare_frames(frame(vals, status), frame(vals, status))
    assert out.verdict.tolist() == ["same"] and out.n.tolist() == [5]


def test_unpaired_relative_interval_of_a_negative_baseline_has_the_sign_of_the_change():
    base = np.array([-1.0, -1.1, -0.9, -1.05])
    out = compare_frames(frame({("a", "u"): base}), frame({("a", "u"): 2 * base}), paired=False).iloc[0]
    assert out.rel_change == pytest.approx(-1.0)
    assert out.rel_ci_low <= out.rel_change <= out.rel_ci_high < 0


def test_cells_of_one_verdict_are_listed_by_the_size_of_their_change():
    base = {(v, "u"): 0.1 + 0.001 * np.arange(6) for v in ("a", "b", "c")}
    cand = {("a", "u"): base[("a", "u")] * 1.2, ("b", "u"): base[("b", "u")] * 1.6, ("c", "u"): base[("c", "u")] * 1.4}
    out = compare_frames(frame(base), frame(cand))
    assert out.variant.tolist() == ["b", "c", "a"] and set(out.verdict) == {"worse"}


def test_a_metric_where_higher_is_better_turns_the_verdict(monkeypatch):
    from marinebench.results import compare

    base = {("a", "u"): 0.1 + 0.001 * np.arange(6)}
    up = {("a", "u"): base[("a", "u")] * 1.5}
    assert compare_frames(frame(base), frame(up)).verdict.tolist() == ["worse"]
    monkeypatch.setattr(compare, "HIGHER_IS_BETTER", {"std"})
    assert compare_frames(frame(base), frame(up)).verdict.tolist() == ["better"]


def test_two_seeds_have_an_interval_and_the_relative_columns_are_of_the_baseline():
    """Two paired seeds already bootstrap an interval: +25 % on both is worse, +25 % on one and -5 % on the other
    is no change (the interval reaches below zero), though either's mean change is beyond the tolerance. Unpaired,
    the relative interval is Welch's interval in units of the baseline's mean."""
    base = pd.DataFrame({"experiment": "e", "scenario": "s", "variant": "a", "seed": [0, 1], "signal": "u",
                         "metric": "std", "value": [2.0, 2.0], "status": "ok"})
    worse = compare_frames(base, base.assign(value=[2.5, 2.5])).iloc[0]
    assert worse["verdict"] == "worse" and worse["rel_change"] == 0.25 and worse["ci_low"] == worse["ci_high"] == 0.5
    assert worse["rel_ci_low"] == pytest.approx(0.25) and worse["rel_ci_high"] == pytest.approx(0.25)
    mixed = compare_frames(base, base.assign(value=[2.5, 1.9])).iloc[0]
    assert mixed["verdict"] == "same" and mixed["ci_low"] < 0 < mixed["ci_high"]
    spread = base.assign(value=[1.0, 3.0])
    row = compare_frames(spread, spread.assign(value=[2.0, 5.0]), paired=False).iloc[0]
    lo, hi = welch_ci(np.array([1.0, 3.0]), np.array([2.0, 5.0]))
    assert (row["ci_low"], row["ci_high"]) == (lo, hi) and (row["rel_ci_low"], row["rel_ci_high"]) == (lo / 2, hi / 2)
    assert row["rel_change"] == 1.5 / 2


def test_the_default_tolerance_is_two_percent_of_the_baseline(tmp_path, base_values):
    """``Tolerance()`` and compare's --rtol default: a change the seeds agree on is 'same' up to 2 % of the
    baseline's mean and a verdict beyond it (every seed x1.019 / x1.021 / x0.979)."""
    base = tidy_metrics({("a", "u"): [0.10, 0.11, 0.12, 0.13]})
    verdicts = [compare_frames(base, base.assign(value=base["value"] * f))["verdict"].iloc[0] for f in (1.019, 1.021, 0.979)]
    assert verdicts == ["same", "worse", "better"]
    write_result(tmp_path / "base", "exp", base_values)
    for factor, code in ((1.019, 0), (1.021, 1)):
        write_result(tmp_path / str(factor), "exp", {k: v * factor for k, v in base_values.items()})
        assert runner.invoke(app, ["compare", str(tmp_path / "base"), str(tmp_path / str(factor))]).exit_code == code


def test_the_tree_is_read_past_temporary_and_vanishing_folders(tmp_path, base_values, monkeypatch):
    """A ``run`` writing into the tree compared: its dot-folder (the write under way) is not looked into, and a folder
    that vanishes while the tree is listed (renamed into place) is passed over; before, ``rglob`` raised
    FileNotFoundError (a traceback) when it did."""
    import os

    from marinebench.results import compare

    write_result(tmp_path / "tree", "exp", base_values)
    write_result(tmp_path / "tree" / ".exp2.tmp-host-1-2", "exp", base_values)  # the same name: would be 'twice'
    (tmp_path / "tree" / "gone").mkdir()
    real = os.scandir

    def vanishing(path="."):
        if Path(path).name == "gone":
            raise FileNotFoundError(2, "No such file or directory", str(path))
        return real(path)

    monkeypatch.setattr(os, "scandir", vanishing)
    assert compare.find_results(tmp_path / "tree") == {"exp": tmp_path / "tree" / "exp"}


@pytest.mark.parametrize("command, option", [("compare", "--output"), ("report", "--out")])
def test_an_output_file_replaces_only_one_its_command_wrote(tmp_path, base_values, command, option):
    """``report --out`` and ``compare --output`` write a file whole in place of what is there: only an earlier output
    of the same command (recognised by how it starts), an empty file, or nothing is replaced. Before, ``report
    --out base/exp/metrics.csv`` replaced the result's metrics with HTML, rc 0."""
    base = write_result(tmp_path / "base", "exp", base_values)
    write_result(tmp_path / "cand", "exp", base_values)
    args = ["compare", str(tmp_path / "base"), str(tmp_path / "cand")] if command == "compare" else \
        ["report", str(tmp_path / "cand"), "--compare", str(tmp_path / "base")]
    metrics = (base / "metrics.csv").read_bytes()
    (tmp_path / "notes.md").write_text("my notes\n")
    (tmp_path / "link").symlink_to(tmp_path / "notes.md")
    for target, why in [(base / "metrics.csv", "a file this command did not write"),
                        (tmp_path / "notes.md", "a file this command did not write"),
                        (tmp_path / "link", "a symbolic link"), (base, "not a file")]:
        res = runner.invoke(app, [*args, option, str(target)])
        assert res.exit_code == 2 and res.output.strip() == (
            f"error: {option}: {target}: {why}: not replaced" + (" (move it, or choose another " if "did not" in why
                                                                  else " (choose another ") + f"{option})"), res.output
    assert (base / "metrics.csv").read_bytes() == metrics and (tmp_path / "notes.md").read_text() == "my notes\n"
    (tmp_path / "empty").touch()  # e.g. made by mktemp
    formats = [["--format", f] for f in ("md", "json", "csv")] if command == "compare" else [[]]
    for fmt in formats:
        for target in (tmp_path / f"out{''.join(fmt)}", tmp_path / f"out{''.join(fmt)}", tmp_path / "empty"):
            res = runner.invoke(app, [*args, *fmt, option, str(target)])  # the second time replaces the first
            assert res.exit_code == 0 and target.stat().st_size > 0, res.output
    if command == "compare":  # --variants writes the same columns (its variant column reads 'b vs a')
        for _ in range(2):
            res = runner.invoke(app, ["compare", str(base), "--variants", "a", "b", "--format", "csv", "--output",
                                      str(tmp_path / "variants.csv")])
            assert res.exit_code != 2, res.output  # 0 or 1: the verdict, not a refusal


def test_an_output_file_that_cannot_be_read_is_not_replaced(tmp_path, monkeypatch):
    """Whether a file there was written by the command is read from its start; one that cannot be read is refused
    (as root, a mode of 000 does not stop a read, so the failure is made here)."""
    from marinebench.errors import ConfigError
    from marinebench.results import writer

    (tmp_path / "out.md").write_text("### marinebench compare: 0 worse\n")

    def unreadable(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(writer, "open", unreadable, raising=False)
    with pytest.raises(ConfigError, match=r"^--output: .*out\.md: cannot read what is there \(Permission denied\): "
                                          r"not replaced$"):
        writer.replaceable_file(tmp_path / "out.md", ("### marinebench compare:",), "--output")


def test_a_sweep_at_another_horizon_is_another_world(tmp_path):
    """A sweep's config.resolved.yaml holds the world its runs had: with --horizon, that horizon, not the config's
    (in a config of several worlds, the swept one's), so compare refuses to pair two sweeps of one config run for
    different times, and the folder's figures can still be drawn again from it."""
    from marinebench.experiments.sweep import as_swept
    from marinebench.loading import load_checked

    args = ["sweep", "k", "--config", str(ROOT / "configs" / "torben_fig3.yaml"), "--n", "2", "--gnss", "dgnss",
            "--jobs", "1", "--quiet"]
    for horizon in ("2", "3"):
        res = runner.invoke(app, [*args, "--horizon", horizon, "--out", str(tmp_path / horizon)])
        assert res.exit_code == 0, res.output
    short, longer = (tmp_path / h / f"torben_fig3_sweep_k_dgnss_n2_{h}s" for h in ("2", "3"))
    assert yaml.safe_load((short / "config.resolved.yaml").read_text())["scenario"]["horizon"] == 2.0
    res = runner.invoke(app, ["compare", str(short), str(longer)])
    assert res.exit_code == 2 and "scenario.horizon" in res.output, res.output
    assert runner.invoke(app, ["figures", str(short)]).exit_code == 0
    several, _ = load_checked(ROOT / "configs" / "bejarano_fig4_5.yaml")
    swept = as_swept(several, list(several.sweep.params), 7.0)
    assert {name: world.horizon for name, world in swept.scenarios.items()} == {
        name: 7.0 if name == several.sweep_scenario() else world.horizon for name, world in several.scenarios.items()}


def test_sweeps_of_other_points_pair_by_value_not_by_number(tmp_path):
    """A sweep's variants number its points (``delta_p1_001_default``): with ``--n 2`` the second is 3, with
    ``--n 3`` it is 1.75. compare pairs what was run: the two common values are the same, 1.75 is new, and nothing
    is worse or better (paired by number, 3 against 1.75 was a change of every error)."""
    args = ["sweep", "delta_p1=0.5..3", "--config", str(ROOT / "configs" / "bejarano_fig6.yaml"), "--horizon", "6",
            "--seeds", "2", "--jobs", "1", "--quiet"]
    for n in ("2", "3"):
        res = runner.invoke(app, [*args, "--n", n, "--out", str(tmp_path / n)])
        assert res.exit_code == 0, res.output
    two, three = (next((tmp_path / n).iterdir()) for n in ("2", "3"))
    res = runner.invoke(app, ["compare", str(two), str(three), "--format", "csv"])
    assert res.exit_code == 0, res.output
    cells = pd.read_csv(io.StringIO(res.output))
    cells = cells[cells.metric != "claim"]
    assert sorted(cells.groupby("verdict")["variant"].unique().map(sorted).items()) == [
        ("new", ["delta_p1=1.75"]), ("same", ["delta_p1=0.5", "delta_p1=3"])]


def test_points_that_seven_digits_cannot_tell_apart_keep_their_variant():
    """metrics.csv writes a point's value to 7 digits: two points it cannot tell apart are not one cell."""
    from marinebench.results.compare import by_point

    runs = pd.DataFrame({"experiment": "e", "seed": [0, 0, 0, 1, 0],
                         "variant": ["x_000_default", "x_001_default", "x_002_default", "x_002_default", "run"],
                         "param": ["x", "x", "x", "x", None], "param_value": [1000.0, 1000.00000001, 1001.0, 1001.0, None],
                         "gnss": ["default"] * 4 + [None]})
    assert by_point(runs)["variant"].tolist() == ["x=1000 (x_000_default)", "x=1000 (x_001_default)", "x=1001", "x=1001",
                                                  "run"]


def test_a_clash_of_points_in_one_experiment_leaves_the_others_labels_alone():
    """Two points that one sweep cannot tell apart keep their variant there only: another experiment of the tree
    with the same value keeps the plain label, so it still pairs with a folder holding that experiment alone."""
    from marinebench.results.compare import by_point

    runs = pd.DataFrame({"experiment": ["a", "a", "b"], "seed": 0,
                         "variant": ["x_000_default", "x_001_default", "x_000_default"],
                         "param": "x", "param_value": [1000.0, 1000.00000001, 1000.0], "gnss": "default"})
    assert by_point(runs)["variant"].tolist() == ["x=1000 (x_000_default)", "x=1000 (x_001_default)", "x=1000"]
    assert by_point(runs[runs["experiment"] == "b"])["variant"].tolist() == ["x=1000"]
