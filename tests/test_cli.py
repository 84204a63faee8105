"""CLI through typer's CliRunner: run, validate, schema, list, and every bad-config case."""

import json
import re
from pathlib import Path

import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from marinebench.cli import app, main

from .conftest import ROOT

runner = CliRunner()


def test_run_writes_every_output(tiny_config, tmp_path):
    out = tmp_path / "out"
    res = runner.invoke(app, ["run", str(tiny_config), "--out", str(out), "--quiet"])
    assert res.exit_code == 0, res.output
    d = out / "tiny"
    assert sorted(p.name for p in d.iterdir()) == ["config.resolved.yaml", "figures", "manifest.json", "metrics.csv", "table.md"]
    m = pd.read_csv(d / "metrics.csv")
    assert {"experiment", "scenario", "variant", "seed", "signal", "metric", "value"} <= set(m.columns)
    assert len(m) == 2 * 2 * 6  # variants x seeds x signals
    man = json.loads((d / "manifest.json").read_text())
    assert man["seed"] == 2024 and man["versions"]["numpy"] and man["git_revision"] and man["assumptions"]
    assert man["machine"]["cores"] >= 1 and man["machine"]["cpu"] and isinstance(man["machine"]["numpy_simd"], list)
    from marinebench.provenance import package_digest

    assert man["source_digest"] == package_digest() and len(man["source_digest"]) == 64  # the code, installed or not
    assert (d / "figures" / "u.png").stat().st_size > 1000 and (d / "figures" / "sv.png").exists()
    table = (d / "table.md").read_text()
    assert "e_u paper" in table and "0.09" in table and "not computed" in table
    assert "Mean over 2 seeds with the 95% Student-t interval in brackets" in table
    resolved = yaml.safe_load((d / "config.resolved.yaml").read_text())
    assert resolved["scenario"]["dt"] == 0.01 and resolved["variants"][1]["observer"]["rho"] is None


def test_seed_seeds_and_set_options(tiny_config, tmp_path):
    res = runner.invoke(app, ["run", str(tiny_config), "--out", str(tmp_path), "--quiet", "--seed", "9",
                              "--seeds", "3", "--set", "variants[liu_eps0.2].observer.eps=0.3"])
    assert res.exit_code == 0, res.output
    resolved = yaml.safe_load((tmp_path / "tiny" / "config.resolved.yaml").read_text())
    assert resolved["seed"] == 9 and resolved["seeds"] == 3
    assert resolved["variants"][0]["observer"]["eps"] == 0.3
    assert pd.read_csv(tmp_path / "tiny" / "metrics.csv")["seed"].nunique() == 3


def test_one_seed_has_no_interval_and_its_table_and_claims_say_so(tmp_path):
    res = runner.invoke(app, ["run", str(ROOT / "configs" / "bejarano_fig6.yaml"), "--out", str(tmp_path), "--quiet",
                              "--seeds", "1", "--profile", "quick"])
    assert res.exit_code == 0, res.output
    table = (tmp_path / "bejarano_fig6" / "table.md").read_text()
    assert "One seed, so no interval" in table and "interval in brackets" not in table
    rows = [line for line in table.splitlines() if line.startswith("| proposed_dpsi")]
    assert len(rows) == 3 and not any("[" in row for row in rows)
    claims = (tmp_path / "bejarano_fig6" / "claims.md").read_text()
    assert "Checked on one seed, root seed 2024" in claims and "; one seed gives no interval." in claims
    assert "bootstrap standard error" not in claims


def test_rerun_replaces_results_atomically(tiny_config, tmp_path):
    out = tmp_path / "out"
    for _ in range(2):
        assert runner.invoke(app, ["run", str(tiny_config), "--out", str(out), "--quiet"]).exit_code == 0
    assert [p.name for p in out.iterdir()] == ["tiny"]  # no temp or backup directories left


def test_a_results_resolved_config_reruns_it_under_its_experiments_name(tiny_config, tmp_path):
    """Not into ``config.resolved/``: a result reruns where its config wrote, with the same numbers."""
    first, again = tmp_path / "first", tmp_path / "again"
    assert runner.invoke(app, ["run", str(tiny_config), "--out", str(first), "--quiet"]).exit_code == 0
    resolved = first / "tiny" / "config.resolved.yaml"
    res = runner.invoke(app, ["run", str(resolved), "--out", str(again), "--quiet"])
    assert res.exit_code == 0, res.output
    assert [p.name for p in again.iterdir()] == ["tiny"]
    assert (again / "tiny" / "metrics.csv").read_text() == (first / "tiny" / "metrics.csv").read_text()
    # two results' resolved configs are two folders, not "two configs that would write one folder"
    other = tmp_path / "other" / "config.resolved.yaml"
    other.parent.mkdir()
    other.write_text(resolved.read_text().replace("name: tiny", "name: tiny2"))
    res = runner.invoke(app, ["run", str(resolved), str(other), "--out", str(again), "--quiet", "--jobs", "1"])
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in again.iterdir()) == ["tiny", "tiny2"]


def test_resume_skips_experiments_whose_inputs_are_unchanged(tiny_config, tmp_path):
    out = tmp_path / "out"
    args = ["run", str(tiny_config), "--out", str(out)]
    assert runner.invoke(app, [*args, "--quiet"]).exit_code == 0
    written = (out / "tiny" / "manifest.json").stat().st_mtime_ns
    res = runner.invoke(app, [*args, "--resume"])
    assert res.exit_code == 0 and "tiny: up to date (same inputs) ->" in res.output, res.output
    assert (out / "tiny" / "manifest.json").stat().st_mtime_ns == written  # nothing rewritten
    res = runner.invoke(app, [*args, "--resume", "--seeds", "3"])  # other inputs: run again
    assert res.exit_code == 0 and "up to date" not in res.output
    assert pd.read_csv(out / "tiny" / "metrics.csv")["seed"].nunique() == 3
    manifest = out / "tiny" / "manifest.json"
    man = json.loads(manifest.read_text())
    manifest.write_text(json.dumps(man | {"inputs_key": "0" * 64}))  # as if written by other code
    res = runner.invoke(app, [*args, "--resume", "--seeds", "3", "--jobs", "2"])
    assert res.exit_code == 0 and "up to date" not in res.output
    assert json.loads(manifest.read_text())["inputs_key"] == man["inputs_key"]
    # a manifest damaged with its key intact (claims not a list of objects, or no object at all) is written again;
    # before, an AttributeError or TypeError traceback
    for damaged in (json.dumps(man | {"claims": [1]}), json.dumps([man]), "\xff"):
        manifest.write_text(damaged)
        res = runner.invoke(app, [*args, "--resume", "--seeds", "3", "--quiet"])
        rewritten = json.loads(manifest.read_text())
        assert res.exit_code == 0 and rewritten["inputs_key"] == man["inputs_key"], res.output
        assert rewritten["claims"] == man["claims"] and rewritten["runs"] == man["runs"]


def edit(path: Path, tmp_path: Path, name: str, fn) -> Path:
    doc = yaml.safe_load(path.read_text())
    fn(doc)
    new = tmp_path / f"{name}.yaml"
    new.write_text(yaml.safe_dump(doc, sort_keys=False))
    return new


BAD = {
    "unknown_key": (lambda d: d.update(bogus=1), "bogus: unknown key (allowed here: assumptions, claims, description,"),
    # a near miss of an observer's key; the discriminated union's tag ('bejarano') is not part of the key
    "misspelt_key": (lambda d: d["variants"][1]["observer"].update(delta_p=1.0),
                     "variants.1.observer.delta_p: unknown key (did you mean delta_p1 or delta_psi1?)"),
    # every further error is named by its key, the claim's kind ('less') is not
    "two_errors": (lambda d: d.update(claims=[{"kind": "less", "a": "x", "b": "y", "signalz": ["u"]}], bogus=1),
                   "claims.0.text: Field required (and 2 more: claims.0.signalz, bogus)"),
    # past three further errors the list is cut
    "five_errors": (lambda d: d.update(claims=[{"kind": "less", "a": "x", "b": "y", "signalz": ["u"]}], bogus=1,
                                       bogus2=2, bogus3=3),
                    "claims.0.text: Field required (and 4 more: claims.0.signalz, bogus, bogus2, …)"),
    "wrong_type": (lambda d: d["variants"][0]["observer"].update(eps="fast"), "variants.0.observer.eps"),
    "out_of_range": (lambda d: d["scenario"].update(dt=-0.01), "scenario.dt: Input should be greater than 0"),
    # a relative path is read from the config's folder, which the message shows
    "missing_scenario": (lambda d: d["scenario"].update({"from": "nowhere.yaml"}),
                         "scenario: scenario file not found: nowhere.yaml (relative to the file's folder: looked for /"),
    # a folder where a file belongs: before, the line named neither the config nor its key
    "scenario_is_a_folder": (lambda d: d["scenario"].update({"from": "."}), "scenario: . is a folder, not a file"),
    "infeasible_lmi": (lambda d: d["variants"][1]["observer"].update(delta_psi1=1.0, delta_p1=1.0, rho=1.2, r_max=5.0),
                       "variants.1.observer: positional LMI"),
    # the step is the scenario's, and the message names the variant whose poles need the smaller step
    "stiff": (lambda d: d["scenario"].update(dt=0.2), "scenario.dt: dt=0.2 s is too large"),
    "stiff_variant": (lambda d: d["variants"][1]["observer"].update(delta_p1=500.0),
                      "(the fastest: variant 'proposed_d1.2')"),
    # YAML's .inf passes a bound such as gt=0; before, it failed deep in the design with a traceback
    "not_finite": (lambda d: d["variants"][1]["observer"].update(delta_psi1=float("inf")),
                   "variants.1.observer.delta_psi1: Input should be a finite number"),
    "not_a_list": (lambda d: d.update(variants=3), "variants: Input should be a valid list"),
    # finite and in range, but beyond what the LMI design's numbers can hold: no traceback, no numpy warnings
    "design_overflow": (lambda d: d["variants"][1]["observer"].update(delta_psi1=1e300),
                        "variants.1.observer: no design for these values (OverflowError"),
    "too_many_steps": (lambda d: d["scenario"].update(horizon=1e12),
                       "scenario.horizon: 1e+12 s at dt=0.01 s is 1e+14 steps per run; at most 1e+08"),
    # a window that ends after a run of 4 s: before, it measured nothing and the claims divided by zero
    "window_after_horizon": (lambda d: d["metrics"][0].update(t_start=10.0, t_end=20.0),
                             "metrics.0: metric 'std' window [10, 20] s is empty in a run of 4 s"),
    # the same from t_start's default, which the message names
    "window_from_default_start": (lambda d: (d["metrics"][0].pop("t_start", None), d["metrics"][0].pop("t_end", None)),
                                  ("metrics.0: metric 'std' window [5, 4] s is empty in a run of 4 s (t_start defaults to "
                                   "5 s: set metrics.0.t_start)")),
    "observer_of_another_world": (lambda d: d["variants"][0].update(observer={"kind": "cdo"}),
                                  ("variants.0.observer.kind: 'cdo' does not apply to scenario kind open_loop_asv "
                                   "(its observers: bejarano, custom, liu_eso, npo, resetting_fto)")),
    # the DP observers run on the ASV world, but it records no bias truth to compare their bias estimate with
    "signal_without_truth": (lambda d: (d["variants"][0].update(observer={"kind": "npo"}),
                                        d["metrics"][0].update(signals=["u", "b_x"]), d["table"].update(signals=["u"])),
                             "metrics.0.signals: ['b_x']: an open_loop_asv world has no truth of these"),
    # a signal no variant estimates: its near misses, or what is estimated
    "unknown_signal": (lambda d: d["metrics"].append({"kind": "rmse", "t_start": 0.0, "signals": ["sigma_uu"]}),
                       "metrics.1.signals: unknown signals ['sigma_uu'] (did you mean sigma_u"),
    "unknown_signal_far_off": (lambda d: d["metrics"].append({"kind": "rmse", "t_start": 0.0, "signals": ["speed"]}),
                               ("metrics.1.signals: unknown signals ['speed'] (estimated here: r, sigma_r, sigma_u, "
                                "sigma_v, u, v; `marinebench list open_loop_asv` says what each is)")),
    # checks across keys name the key they are about and what is there instead
    "duplicate_variant_names": (lambda d: d["variants"][1].update(name="liu_eps0.2"),
                                "variants: duplicate names ['liu_eps0.2']"),
    "duplicate_metric_names": (lambda d: d["metrics"].append({"kind": "std"}),
                               "metrics: names must be unique, got ['std', 'std'] (give each repeated kind its own name)"),
    "closed_loop_metric": (lambda d: d["metrics"].append({"kind": "int", "signals": ["depth"]}),
                           "metrics: 'int' applies to rov_tracking scenarios only"),
    "table_metric": (lambda d: d["table"].update(metric="rmse"), "table.metric: 'rmse' is not among the metrics ['std']"),
    "table_metrics": (lambda d: d["table"].update(metrics=["std", "rmse"]),
                      "table.metrics.1: 'rmse' is not among the metrics ['std']"),
    "paper_variant": (lambda d: d["table"]["paper"]["values"].update(nobody={"u": 1.0}),
                      "table.paper.values: unknown variants ['nobody'] (have: liu_eps0.2, proposed_d1.2)"),
    # a misspelt key was ignored: a unit not applied, a paper value never shown
    "table_display_key": (lambda d: d["table"].update(display={"std/x": {"scale": 100, "unit": "cm"}}),
                          "table.display: ['std/x'] name no signal a metric records, as 'metric/signal' (e.g. std/r)"),
    "paper_value_key": (lambda d: d["table"]["paper"]["values"].update({"liu_eps0.2": {"x": 1.0}}),
                        "table.paper.values: liu_eps0.2: ['x'] are not keyed as the table reads them: a signal of std"),
    # before, the figure failed after the whole simulation, with a traceback (KeyError)
    "figure_signal": (lambda d: d["figures"][0].update(signals=["nope"]),
                      ("figures: u.png: no trace of ['nope'] on this world (a figure may show: r, sigma_r, sigma_u, "
                       "sigma_v, u, v; `marinebench list open_loop_asv` says what each is)")),
    # these ran before, writing an empty figure, a table of n/a or one figure over another
    "figure_time_range": (lambda d: d["figures"][0].update(t_range=[3, 1]),
                          "figures.0.t_range: [3.0, 1.0]: the start must be before the end"),
    "figure_no_signals": (lambda d: d["figures"][0].update(signals=[]), "figures.0.signals: List should have at least 1 item"),
    "figure_twice": (lambda d: d["figures"][1].update(file="u.png"), "figures: ['u.png'] named twice"),
    "figure_other_world": (lambda d: d["figures"][0].update(scenario="nope"),
                           "figures: u.png: scenario 'nope' is not this experiment's world ('cs2_noisy'"),
    "table_signal": (lambda d: d["table"].update(signals=["u", "x"]),
                     "table.signals: ['x'] are not recorded by the table's metrics (they record: r, sigma_r, sigma_u"),
    "table_relative_itself": (lambda d: d["table"].update(relative=["liu_eps0.2", "liu_eps0.2"]),
                              "table.relative: a variant against itself (liu_eps0.2)"),
    # before, an empty metrics list passed and the run crashed after simulating (IndexError in the table)
    "no_metrics": (lambda d: d.update(metrics=[]), "metrics: List should have at least 1 item"),
    "table_no_metrics": (lambda d: d["table"].update(metrics=[]), "table.metrics: List should have at least 1 item"),
    "metric_no_signals": (lambda d: d["metrics"][0].update(signals=[]), "metrics.0.signals: List should have at least 1 item"),
    # claims that would hold or fail trivially, or say nothing
    "claim_same_variant": (lambda d: d.update(claims=[{"kind": "less", "a": "liu_eps0.2", "b": "liu_eps0.2", "text": "t"}]),
                           "claims.0: names ['liu_eps0.2'] more than once: a claim compares different variants"),
    "claim_no_other": (lambda d: d.update(claims=[{"kind": "less", "a": "liu_eps0.2", "b": [], "text": "t"}]),
                       "claims.0.b: an empty list names no variant to compare with"),
    "claim_near_no_variants": (lambda d: d.update(claims=[{"kind": "near_paper", "variants": [], "text": "t"}]),
                               "claims.0.variants: List should have at least 1 item"),
    "claim_no_text": (lambda d: d.update(claims=[{"kind": "less", "a": "liu_eps0.2", "b": "proposed_d1.2", "text": ""}]),
                      "claims.0.text: String should have at least 1 character"),
    "sweep_claim_one_value": (lambda d: d.update(sweep={"params": {"eps": {"key": "eps", "range": [0.1, 1.0]}}, "claims": [
                                  {"kind": "probe", "param": "eps", "at": 0.5, "vs": 0.5, "text": "t"}]}),
                              "sweep.claims.0: at and vs are both 0.5: a probe claim compares two values"),
    "sweep_claim_one_curve": (lambda d: d.update(sweep={"params": {"eps": {"key": "eps", "range": [0.1, 1.0]}}, "claims": [
                                  {"kind": "groups", "param": "eps", "above": "a", "below": "a", "text": "t"}]}),
                              "sweep.claims.0: above and below are both 'a': a groups claim compares two curves"),
    "figure_variant": (lambda d: d["figures"][0].update(variants=["nope"]),
                       "figures: u.png names unknown variants ['nope'] (have: liu_eps0.2, proposed_d1.2)"),
    "sweep_variant": (lambda d: d.update(sweep={"variant": "nope", "metric": "std",
                                                "params": {"eps": {"key": "eps", "range": [0.1, 1.0]}}}),
                      "sweep.variant: 'nope' is not a variant (have: liu_eps0.2, proposed_d1.2)"),
    "sweep_too_many_points": (lambda d: d.update(sweep={"n": 5000, "params": {"eps": {"key": "eps", "range": [0.1, 1.0]}}}),
                              "sweep.n: Input should be less than or equal to 1000"),  # before: up to 100000, --n's 1000 aside
    "sweep_claim_metric": (lambda d: d.update(sweep={"params": {"eps": {"key": "eps", "range": [0.1, 1.0]}}, "claims": [
                               {"kind": "trend", "param": "eps", "range": [0.1, 1.0], "metric": "rmse", "text": "t"}]}),
                           "sweep.claims.0: metric 'rmse' is not among the sweep's metrics ['std']"),
    # checks across keys that had no test of their own (found by a line-coverage pass)
    "no_world": (lambda d: d.pop("scenario"), ": scenario: give exactly one of 'scenario' or 'scenarios'"),
    "two_kinds_of_world": (lambda d: d.update(scenarios={"a": d["scenario"]}),
                           ": scenario: give exactly one of 'scenario' or 'scenarios'"),
    "table_relative_unknown": (lambda d: d["table"].update(relative=["liu_eps0.2", "nope"]),
                               ": table.relative: unknown variants ['nope']"),
    "no_observer": (lambda d: d["variants"][0].pop("observer"), ": variants.0: give an 'observer' or a 'controller'"),
    "closed_loop_through_liu": (lambda d: d["variants"][0].update(controller={"kind": "rise"}),
                                ": variants.0: a closed-loop variant can be observed through 'cdo', 'eo' or 'custom', not 'liu_eso'"),
    "scenario_from_not_a_path": (lambda d: d["scenario"].update({"from": 3}), ": scenario.from: expected a file path"),
    "experiment_from_not_a_path": (lambda d: d.update({"from": 3}), ": from: expected a path to the experiment file"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_config_one_line_exit_2_nothing_written(case, tiny_config, tmp_path):
    fn, expected = BAD[case]
    bad = edit(tiny_config, tmp_path, case, fn)
    out = tmp_path / "out"
    res = runner.invoke(app, ["run", str(tiny_config), str(bad), "--out", str(out), "--quiet"])
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in res.output, res.output
    assert lines[0].startswith(f"error: {bad}") and expected in lines[0], lines[0]
    assert not out.exists()  # the valid first config was not run either


def test_a_bad_profile_entry_names_the_config_file(tiny_config, tmp_path):
    """A profile's settings are written in the config: their errors name it and the profile, not --set."""
    doc = yaml.safe_load(tiny_config.read_text())
    doc["profiles"] = {"short": ["scenario.horizon=-1"], "typo": ["variants[nope].observer.eps=1"]}
    tiny_config.write_text(yaml.safe_dump(doc))
    res = runner.invoke(app, ["run", str(tiny_config), "--profile", "short", "--out", str(tmp_path / "out")])
    assert res.exit_code == 2 and res.output.startswith(f"error: {tiny_config}: scenario.horizon: "), res.output
    res = runner.invoke(app, ["run", str(tiny_config), "--profile", "typo", "--out", str(tmp_path / "out")])
    assert not (tmp_path / "out").exists()
    assert res.exit_code == 2 and res.output.strip() == (f"error: {tiny_config}: profiles.typo.0: variants[nope].observer.eps: no item named 'nope' (have: liu_eps0.2, "
                                                        "proposed_d1.2)")


def test_invalid_yaml(tmp_path):
    bad = tmp_path / "broken.yaml"
    bad.write_text("variants: [\n  name: x\n")
    res = runner.invoke(app, ["validate", str(bad)])
    assert res.exit_code == 2 and "broken.yaml: invalid YAML: line 3" in res.output


@pytest.mark.parametrize("text, expected", [
    ("- liu_eps0.2\n- proposed_d1.2\n", "expected a mapping at the top level"),  # a list, not a mapping
    ("", "expected a mapping at the top level"),  # an empty file
    (None, "cannot read (Is a directory)"),  # e.g. a folder named like a config
])
def test_a_config_that_is_no_mapping_or_no_file_is_one_line(text, expected, tmp_path):
    path = tmp_path / "config.yaml"
    path.mkdir() if text is None else path.write_text(text)
    for command in (["validate", str(path)], ["run", str(path), "--out", str(tmp_path / "out"), "--quiet"]):
        res = runner.invoke(app, command)
        assert res.exit_code == 2 and res.output.strip() == f"error: {path}: {expected}", res.output
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("dotted, expected", [
    ("variants[nope].observer.eps=1", "variants[nope].observer.eps: no item named 'nope' (have: liu_eps0.2, proposed_d1.2)"),
    # a name written as a key (before: only "not a valid index"), also one with a dot in it, and another word
    ("variants.liu_eps0.2.observer.eps=1", ("variants.liu_eps0.2.observer.eps: 'liu_eps0' is not a valid index (0..1) "
     "(did you mean variants[liu_eps0.2].observer.eps? an item is selected by its name in brackets)")),
    ("variants.proposed_d1.2=1", ("variants.proposed_d1.2: 'proposed_d1' is not a valid index (0..1) (did you mean "
     "variants[proposed_d1.2]? an item is selected by its name in brackets)")),
    ("variants.liu.eps=1", ("variants.liu.eps: 'liu' is not a valid index (0..1) (its items by name: [liu_eps0.2], "
     "[proposed_d1.2])")),
    ("variants.2.eps=1", "variants.2.eps: '2' is not a valid index (0..1)"),
    ("seeds[x]=1", "seeds[x]: '[x]' selects from a list, found int"),
    ("variants.0[liu].eps=1", "variants.0[liu].eps: '[liu]' selects from a list, found dict"),
])
def test_a_set_selecting_a_list_item_that_is_not_there_is_one_line(dotted, expected, tiny_config):
    res = runner.invoke(app, ["validate", str(tiny_config), "--set", dotted])
    assert res.exit_code == 2 and res.output.strip() == f"error: --set: {expected}", res.output


def test_a_file_that_is_not_utf8_is_one_line(tmp_path):
    bad = tmp_path / "latin1.yaml"
    bad.write_bytes("seeds: 2 # réglage\n".encode("latin-1"))
    res = runner.invoke(app, ["validate", str(bad)])
    assert res.exit_code == 2 and res.output.strip() == f"error: {bad}: not UTF-8 text (byte 12): a YAML file is UTF-8"


@pytest.mark.parametrize("args, expected", [
    # typer's own checks: their wording changes with typer's version (a pattern), the one line does not
    (["run", "{cfg}", "--jobs", "-1"], re.compile(r"error: Invalid value for '--jobs' / '-j': .*\b0\b.* \(see 'marinebench "
                                                  r"run --help'\)$")),
    (["run", "{cfg}", "--bogus"], re.compile(r"error: No such option:? '?--bogus\b.* \(see 'marinebench run --help'\)$")),
    (["run"], "error: Missing argument 'CONFIG'. (see 'marinebench run --help')"),
    (["sweep", "k", "--n", "x"], re.compile(r"error: Invalid value for '--n': .*\binteger\b")),
    # --seed/--seeds are validated with the config's own bounds, and the error names the option typed
    (["run", "{cfg}", "--seeds", "100000"], "error: --seeds: Input should be less than or equal to 10000"),
    (["sweep", "k", "--seeds", "100000"], "error: --seeds: Input should be less than or equal to 10000"),
    (["run", "{cfg}", "--set", "seeds=100000"], "error: --set: seeds: Input should be less than or equal to 10000"),
    # out of range for a sweep: a typo that would hang building 1e8 points, or fail deep in the world's arrays
    (["sweep", "k", "--n", "100000000"], "error: --n: must be from 2 to 1000 points per parameter"),
    (["sweep", "k", "--horizon", "nan"], "error: --horizon: must be a positive, finite number of seconds"),
    (["sweep", "k", "--config", str(ROOT / "configs" / "torben_fig3.yaml"), "--horizon", "1e300"],
     "error: --horizon: 1e+300 s: 1e+300 s at dt=0.05 s is 2e+301 steps per run; at most 1e+08"),
    (["compare", "{cfg}", "{cfg}", "--rtol", "nan"], "error: --rtol/--atol: tolerances must be non-negative numbers"),
    (["compare", "{cfg}", "{cfg}", "--atol", "-1"], "error: --rtol/--atol: tolerances must be non-negative numbers"),
    # the edges of the sweep's ranges, and options that contradict each other
    (["sweep", "k", "--n", "1"], "error: --n: must be from 2 to 1000 points per parameter"),
    (["sweep", "k", "--horizon", "inf"], "error: --horizon: must be a positive, finite number of seconds"),
    (["sweep", "k", "--chunk-size", "0"], "error: --chunk-size: must be at least 1"),
    (["sweep", "k", "--jobs", "2", "--dask", "local"], "error: --jobs: runs the batches in local processes; with --dask"),
    (["sweep", "k", "--grid", "--require-claims"], "error: --require-claims: a grid sweep maps where each claim holds"),
    (["bogus"], "error: No such command 'bogus'. (see 'marinebench --help')"),
    # an option short of its values has no click context: the help named is still the command's (before: marinebench's)
    (["compare", "{cfg}", "--variants", "a"], "error: Option '--variants' requires 2 arguments. (see 'marinebench compare --help')"),
    (["schema", "--kind", "nope"], "error: Invalid value for '--kind': 'nope' is not one of 'experiment', 'scenario'"),
    (["compare", "a", "b", "--format", "nope"], "error: Invalid value for '--format': 'nope' is not one of 'md', 'json'"),
])
def test_a_bad_option_is_one_line_from_the_console_entry_point(args, expected, tiny_config, tmp_path, capsys):
    """click's usage errors (drawn by typer as a boxed panel) come out of ``marinebench`` as one line, exit 2."""
    with pytest.raises(SystemExit) as exit_:
        main([a.format(cfg=tiny_config) for a in args] + ["--out", str(tmp_path / "o")] * (args[0] in ("run", "sweep")))
    captured = capsys.readouterr()
    assert exit_.value.code == 2 and captured.out == ""
    lines = captured.err.strip().splitlines()
    shown = expected.match(lines[0]) if isinstance(expected, re.Pattern) else lines[0].startswith(expected)
    assert len(lines) == 1 and shown, captured.err
    assert not (tmp_path / "o").exists()


def test_the_console_entry_point_keeps_the_commands_exit_codes(tiny_config, tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["validate", str(tiny_config)])
    assert exit_.value.code == 0 and capsys.readouterr().out.strip() == f"{tiny_config}: ok"
    with pytest.raises(SystemExit) as exit_:
        main(["validate", str(tmp_path / "none.yaml")])
    assert exit_.value.code == 2 and capsys.readouterr().err.strip() == f"error: {tmp_path / 'none.yaml'}: file not found"
    with pytest.raises(SystemExit) as exit_:
        main(["--help"])
    assert exit_.value.code == 0 and "Usage: marinebench" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exit_:
        main([])  # no arguments: the help, and no empty error line
    captured = capsys.readouterr()
    assert exit_.value.code == 2 and "Usage: marinebench" in captured.out and captured.err == ""


@pytest.mark.parametrize("command", [c.callback.__name__ for c in app.registered_commands])
def test_help_shows_each_paragraph_of_the_docstring_on_one_line_and_its_first_as_the_summary(command):
    """typer's rich help keeps a docstring's line breaks (which the terminal wraps again); cli/__init__.py joins them."""
    import inspect

    info = next(c for c in app.registered_commands if c.callback.__name__ == command)
    name = info.name or command
    paragraphs = [" ".join(p.split()) for p in inspect.cleandoc(info.callback.__doc__).split("\n\n")]
    wide = {"COLUMNS": "400"}
    shown = [line.strip(" │") for line in runner.invoke(app, [name, "--help"], env=wide).output.splitlines()]
    assert all(p in shown for p in paragraphs), (paragraphs, shown[:12])
    assert "--no-" not in "\n".join(shown)  # on/off options are plain flags (--resume), without a --no-resume twin
    listing = runner.invoke(app, ["--help"], env=wide).output
    assert re.search(rf"│ {name} +{re.escape(paragraphs[0])} +│", listing), listing


def test_help_lists_every_command_once_in_the_order_of_a_session():
    """cli/__init__.py registers the commands in one place: from running to reading results to checking configs."""
    listing = runner.invoke(app, ["--help"], env={"COLUMNS": "400"}).output
    assert re.findall(r"^│ (\w+) ", listing, flags=re.MULTILINE) == [
        "run", "sweep", "bench", "compare", "report", "figures", "validate", "design", "schema", "list"]


def test_version():
    from marinebench import __version__
    from marinebench.results.writer import git_revision

    res = runner.invoke(app, ["--version"])
    assert res.exit_code == 0
    assert res.output.strip() in (f"marinebench {__version__}", f"marinebench {__version__} (git {git_revision()})")
    # the installed distribution's version (manifests' versions.marinebench) is read from __version__ at install
    from importlib.metadata import version

    assert version("marinebench") == __version__


def test_python_m_marinebench_is_the_command_and_its_manifests_say_marinebench(tmp_path, monkeypatch):
    """``python -m marinebench`` (a scripts folder not on PATH) runs the command, and a manifest written under it
    (argv[0] is then the module's file) records ``marinebench ...``, which pastes back into a shell; a Python
    program calling the API is named as itself."""
    import subprocess
    import sys

    import marinebench
    from marinebench import __version__
    from marinebench.results import writer

    done = subprocess.run([sys.executable, "-m", "marinebench", "--version"], capture_output=True, text=True, cwd=tmp_path,
                          check=False)
    assert done.returncode == 0 and done.stdout.startswith(f"marinebench {__version__}"), done
    done = subprocess.run([sys.executable, "-m", "marinebench", "list"], capture_output=True, text=True, cwd=tmp_path, check=False)
    assert done.returncode == 0 and "resetting_fto" in done.stdout, done
    package = Path(marinebench.__file__).parent
    for started in (package / "__main__.py", package / "cli" / "__main__.py"):
        monkeypatch.setattr(sys, "argv", [str(started), "run", "a b.yaml"])
        assert json.loads(writer.manifest())["command"] == "marinebench run 'a b.yaml'"
    monkeypatch.setattr(sys, "argv", [str(tmp_path / "study.py"), "--fast"])
    assert json.loads(writer.manifest())["command"] == "study.py --fast"


def test_an_unquoted_true_where_a_word_is_expected_gets_a_hint(tmp_path):
    """`depth_rate: true` (the option named 'true') is a YAML boolean: the error says why it was refused."""
    scenario = tmp_path / "s1.yaml"
    scenario.write_text((ROOT / "scenarios" / "rov_s1.yaml").read_text().replace("depth_rate: difference", "depth_rate: true"))
    res = runner.invoke(app, ["validate", str(scenario)])
    assert res.exit_code == 2 and res.output.strip() == (
        f"error: {scenario}: sensors.depth_rate: Input should be 'difference' or 'true' (YAML reads an unquoted true, "
        "false, yes, no, on or off as a boolean: quote the word)")
    scenario.write_text(scenario.read_text().replace("depth_rate: true", "depth_rate: 'true'"))
    assert runner.invoke(app, ["validate", str(scenario)]).exit_code == 0


@pytest.mark.parametrize("where, setting, key, wanted", [
    ("file", "seeds: true", "seeds", "an integer"),
    ("--set", "variants.0.observer.eps=yes", "variants.0.observer.eps", "a number"),
    ("--set", "variants.0.observer.k=[on, 3, 1]", "variants.0.observer.k.0", "a number"),
    ("--set", "variants.0.world.position_noise_scale=true", "variants.0.world.position_noise_scale", "a number"),
])
def test_a_boolean_where_a_number_belongs_is_a_wrong_type(tmp_path, where, setting, key, wanted):
    """pydantic's lax mode would run `seeds: true` as 1 seed and read `eps: yes` as 1.0 (YAML's unquoted yes, on and
    true are booleans): a one-line error naming the file (or --set) and the key, exit 2, and nothing written."""
    config = tmp_path / "x.yaml"
    config.write_text(f"from: {ROOT / 'configs' / 'bejarano_table3.yaml'}\n" + (setting if where == "file" else ""))
    sets = ["--set", setting] if where == "--set" else []
    res = runner.invoke(app, ["run", str(config), "--out", str(tmp_path / "out"), "--quiet", *sets])
    assert res.exit_code == 2 and res.output.strip() == (
        f"error: {'--set' if sets else config}: {key}: Input should be {wanted}, not a boolean (YAML reads an unquoted "
        "true, false, yes, no, on or off as a boolean)")
    assert not (tmp_path / "out").exists()


def test_a_number_where_a_boolean_belongs_is_a_wrong_type(tmp_path):
    """`notch: 1` in a scenario file, or a flag given as 1 in a controller's settings, would be read as true."""
    scenario = tmp_path / "dp.yaml"
    scenario.write_text(f"from: {ROOT / 'scenarios' / 'dp_impulse.yaml'}\nsensors: {{notch: 1}}\n")
    res = runner.invoke(app, ["validate", str(scenario)])
    assert res.exit_code == 2 and res.output.strip() == (
        f"error: {scenario}: sensors.notch: Input should be true or false, not a number")
    res = runner.invoke(app, ["validate", str(ROOT / "configs" / "tijjani_table3.yaml"),
                              "--set", "variants.2.controller.disturbance_feedforward=[1, true]"])
    assert res.exit_code == 2 and res.output.strip() == (
        "error: --set: variants.2.controller.disturbance_feedforward.0: Input should be true or false, not a number")


def test_a_boolean_in_an_observers_partial_settings_is_a_wrong_type():
    """The CDO's and EO's settings over the scenario's (`cdo: {lmi_decay: ...}`) are checked the same way."""
    res = runner.invoke(app, ["validate", str(ROOT / "configs" / "tijjani_observers.yaml"),
                              "--set", "variants.1.observer.eo.eps=on"])
    assert res.exit_code == 2 and res.output.strip() == (
        "error: --set: variants.1.observer.eo.eps: Input should be a number, not a boolean (YAML reads an unquoted "
        "true, false, yes, no, on or off as a boolean)")


def test_a_key_written_twice_is_an_error_not_a_silent_override(tiny_config, tmp_path):
    twice = tmp_path / "twice.yaml"
    twice.write_text(tiny_config.read_text() + "seeds: 3\n")  # the tiny config already says seeds: 2
    res = runner.invoke(app, ["run", str(twice), "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and res.output.strip() == f"error: {twice}: invalid YAML: line {len(twice.read_text().splitlines())}, column 1: duplicate key 'seeds'"
    res = runner.invoke(app, ["run", str(tiny_config), "--set", "scenario={horizon: 1, horizon: 2}", "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and res.output.strip() == "error: --set: scenario: duplicate key 'horizon'"
    assert not (tmp_path / "o").exists()


def test_an_output_folder_that_cannot_be_written_fails_before_the_runs(tiny_config, tmp_path):
    a_file = tmp_path / "a_file"
    a_file.write_text("not a folder")
    for out, why in ((a_file, "a file, not a folder"), (a_file / "sub", "cannot write results there (Not a directory)")):
        res = runner.invoke(app, ["run", str(tiny_config), "--out", str(out), "--quiet"])
        assert res.exit_code == 2 and res.output.strip() == f"error: --out: {out}: {why}", res.output
        res = runner.invoke(app, ["sweep", "k", "--config", str(ROOT / "configs" / "torben_fig3.yaml"), "--n", "2",
                                  "--horizon", "5", "--out", str(out), "--quiet"])
        assert res.exit_code == 2 and res.output.strip() == f"error: --out: {out}: {why}", res.output
    for command in (["report", str(ROOT / "results" / "bejarano_fig6"), "--out"],
                    ["compare", str(ROOT / "results" / "bejarano_fig6"), str(ROOT / "results" / "bejarano_fig6"), "--output"]):
        res = runner.invoke(app, [*command, str(a_file / "x")])
        assert res.exit_code == 2 and res.output.strip() == f"error: {command[-1]}: {a_file / 'x'}: a parent is a file, not a folder"
    assert a_file.read_text() == "not a folder"


def test_an_interrupted_sweep_says_what_it_kept_and_the_same_command_resumes(tmp_path, monkeypatch):
    """Ctrl-C after the first of three batches: one line naming the kept batch and exit 130; the same command
    then runs only the two others, says so (its times cover only those: the manifest's ``chunks_run`` of
    ``chunks``), and gives the numbers of an uninterrupted sweep."""
    from marinebench.experiments import chunks

    real, calls = chunks.run_chunk, []

    def first_then_ctrl_c(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    args = ["sweep", "k", "--config", str(ROOT / "configs" / "torben_fig3.yaml"), "--n", "3", "--horizon", "2",
            "--chunk-size", "2", "--jobs", "1"]
    monkeypatch.setattr(chunks, "run_chunk", first_then_ctrl_c)
    res = runner.invoke(app, [*args, "--out", str(tmp_path / "a")])
    partial = tmp_path / "a" / ".torben_fig3_sweep_k_n3_2s.partial"
    assert res.exit_code == 130, res.output
    assert res.output.strip().splitlines()[-1] == (
        f"interrupted: 1 of 3 batch(es) finished and kept in {partial}; the same command resumes from them")
    monkeypatch.setattr(chunks, "run_chunk", real)
    res = runner.invoke(app, [*args, "--out", str(tmp_path / "a")])
    assert res.exit_code == 0 and "summed over the 2 batch(es) run, 1 kept from the interrupted sweep)" in res.output
    assert not partial.exists()
    whole = runner.invoke(app, [*args, "--out", str(tmp_path / "b")])
    assert whole.exit_code == 0 and "summed over the 3 batch(es) run)" in whole.output, whole.output
    name = "torben_fig3_sweep_k_n3_2s"
    resumed, uninterrupted = (json.loads((tmp_path / d / name / "manifest.json").read_text()) for d in "ab")
    assert (resumed["chunks"], resumed["chunks_run"]) == (3, 2) and (uninterrupted["chunks"], uninterrupted["chunks_run"]) == (3, 3)
    assert (tmp_path / "a" / name / "metrics.csv").read_text() == (tmp_path / "b" / name / "metrics.csv").read_text()


def test_a_sweep_writes_the_same_metrics_csv_whatever_its_batches(tmp_path):
    """One run per batch or all in one: the same rows in the same order, byte for byte (before, each batch listed
    its own rows metric by metric, so ``--chunk-size`` reordered metrics.csv). Two observer kinds that share a
    diagnostic (``n_resets``) are in the sweep."""
    args = ["sweep", "--config", str(ROOT / "configs" / "torben_fig1.yaml"), "gnss_sigma", "--n", "2", "--variants",
            "npo,resetting", "--horizon", "3", "--set", "metrics.1.t_start=1", "--set", "metrics.1.t_end=3", "--seeds",
            "2", "--jobs", "1", "--quiet"]
    for out, size in (("one", "300"), ("each", "1")):
        res = runner.invoke(app, [*args, "--chunk-size", size, "--out", str(tmp_path / out)])
        assert res.exit_code == 0, res.output
    one, each = (next((tmp_path / out).glob("*/metrics.csv")) for out in ("one", "each"))
    assert json.loads((each.parent / "manifest.json").read_text())["chunks"] == 4
    assert one.read_bytes() == each.read_bytes()


@pytest.mark.parametrize("thing", ["file", "link", "folder"])
def test_a_sweep_leaves_what_is_not_its_kept_batches_where_it_keeps_them(tmp_path, thing):
    """``.<folder>.partial`` is where a sweep keeps its finished batches, and removes them when they are another
    sweep's: a file there was a traceback; a folder of other files would have been removed. Both are refused before
    anything runs, and left as they were; a folder of a sweep's own files only (here another sweep's batch) is
    still cleared and used."""
    partial = tmp_path / "o" / ".torben_fig3_sweep_k_dgnss_n2_2s.partial"
    partial.parent.mkdir()
    if thing == "file":
        partial.write_text("mine")
    elif thing == "link":
        partial.symlink_to(tmp_path)
    else:
        partial.mkdir()
        (partial / "notes.txt").write_text("mine")
        (partial / "chunk-0000.csv").write_text("a batch of another sweep")
    args = ["sweep", "k", "--config", str(ROOT / "configs" / "torben_fig3.yaml"), "--n", "2", "--horizon", "2",
            "--gnss", "dgnss", "--jobs", "1", "--quiet", "--out", str(tmp_path / "o")]
    res = runner.invoke(app, args)
    what = "a folder of other files (notes.txt)" if thing == "folder" else "a file or symbolic link"
    assert res.exit_code == 2 and res.output.strip() == (
        f"error: {partial}: {what} where a sweep keeps its finished batches: not replaced (move it, or choose another "
        "--out)"), res.output
    assert (partial / "notes.txt").read_text() == "mine" if thing == "folder" else \
        partial.is_symlink() if thing == "link" else partial.read_text() == "mine"
    assert not (tmp_path / "o" / "torben_fig3_sweep_k_dgnss_n2_2s").exists()
    if thing == "folder":  # without the other file: another sweep's batches, removed, and the sweep runs
        (partial / "notes.txt").unlink()
        assert runner.invoke(app, args).exit_code == 0 and not partial.exists()


@pytest.mark.parametrize("stop, code", [(KeyboardInterrupt, 130), ("terminated", 143)])
def test_an_interrupted_run_says_how_to_go_on(tiny_config, tmp_path, monkeypatch, stop, code):
    """Ctrl-C, or SIGTERM, which the console entry point turns into cli.Terminated: one line, 130 or 143."""
    from marinebench import cli

    def interrupt(*args, **kwargs):
        raise cli.Terminated if stop == "terminated" else stop

    monkeypatch.setattr(cli.run, "_run_and_write", interrupt)
    res = runner.invoke(app, ["run", str(tiny_config), "--out", str(tmp_path / "o"), "--jobs", "1", "--quiet"])
    assert res.exit_code == code and res.output.strip() == (
        "interrupted: the experiments already written are complete, the others untouched; the same command with "
        "--resume runs only those not written")
    assert not (tmp_path / "o").exists()  # not even the --out folder the command made: nothing was written in it


def test_an_interrupted_run_leaves_an_existing_out_folder_and_removes_only_the_empty_ones_it_made(tiny_config, tmp_path,
                                                                                                monkeypatch):
    from marinebench import cli

    def interrupt(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli.run, "_run_and_write", interrupt)
    (tmp_path / "kept").mkdir()
    res = runner.invoke(app, ["run", str(tiny_config), "--out", str(tmp_path / "kept" / "a" / "b"), "--jobs", "1", "--quiet"])
    assert res.exit_code == 130
    assert (tmp_path / "kept").is_dir() and list((tmp_path / "kept").iterdir()) == []


def test_the_entry_point_turns_sigterm_into_an_interruption(monkeypatch):
    """A cancelled CI job or ``timeout`` sends SIGTERM: main() installs a handler that raises cli.Terminated (a
    KeyboardInterrupt), so the command unwinds as on Ctrl-C instead of dying mid-write."""
    import signal

    from marinebench import cli

    monkeypatch.setattr(signal, "signal", lambda signum, handler: installed.update({signum: handler}))
    installed = {}
    with pytest.raises(SystemExit):
        main(["--version"])
    assert installed == {signal.SIGTERM: cli.common.raise_terminated}
    with pytest.raises(KeyboardInterrupt) as stopped:
        cli.common.raise_terminated(signal.SIGTERM, None)
    assert isinstance(stopped.value, cli.Terminated)


def test_bad_set_names_the_option(tiny_config, tmp_path):
    res = runner.invoke(app, ["run", str(tiny_config), "--out", str(tmp_path), "--set", "scenario.horizon=-1"])
    assert res.exit_code == 2 and res.output.startswith("error: --set: scenario.horizon")
    res = runner.invoke(app, ["run", str(tiny_config), "--set", "variants[nope].observer.eps=1"])
    assert res.exit_code == 2 and "no item named 'nope'" in res.output
    res = runner.invoke(app, ["run", str(tiny_config), "--set", "seeds"])
    assert res.exit_code == 2 and "expected dotted.key=value" in res.output
    res = runner.invoke(app, ["run", str(tiny_config), "--set", "variants[liu_eps0.2].observer.k=[3, 3]"])  # a named item
    assert res.exit_code == 2 and res.output.startswith("error: --set: variants.0.observer.k"), res.output
    res = runner.invoke(app, ["run", str(tiny_config), "--set", "engine.nosuch.deeper=1"])  # a new key, and its parent
    assert res.exit_code == 2 and res.output.strip() == ("error: --set: engine.nosuch: unknown key "
                                                        "(allowed here: check_step, stiffness_limit, trace_dt, write_traces)")
    # a setting that makes a mapping where a list belongs: the error is at the list, and the --set made it
    res = runner.invoke(app, ["run", str(tiny_config), "--set", "claims.0.text=x"])  # tiny has no claims
    assert res.exit_code == 2 and res.output.startswith("error: --set: claims: Input should be a valid list"), res.output
    # a cross-field check of the world names its key, and so the --set it came from
    res = runner.invoke(app, ["run", str(tiny_config), "--set", "scenario.horizon=1e7"])
    assert res.exit_code == 2 and res.output.strip() == ("error: --set: scenario.horizon: 1e+07 s at dt=0.01 s is 1e+09 "
                                                        "steps per run; at most 1e+08"), res.output
    # a check of a pair names the one of the two that the --set gave, not the file's other
    res = runner.invoke(app, ["run", str(tiny_config), "--set", "scenario.dt=1e-9"])
    assert res.exit_code == 2 and res.output.strip() == ("error: --set: scenario.dt: 4 s at dt=1e-09 s is 4e+09 "
                                                        "steps per run; at most 1e+08"), res.output
    res = runner.invoke(app, ["run", str(tiny_config), "--set", "scenario.dt=5"])
    assert res.exit_code == 2 and res.output.strip() == "error: --set: scenario.dt: dt=5 s exceeds horizon=4 s", res.output
    # a horizon that leaves a metric's window empty: the --set, not the file's metric (which a --set of the metric,
    # or the file alone, still gets); in a study, the horizon of the world the --set named
    res = runner.invoke(app, ["run", str(tiny_config), "--set", "scenario.horizon=0.5"])
    assert res.exit_code == 2 and res.output.strip() == ("error: --set: scenario.horizon: metric 'std' window [1, 0.5] s "
                                                        "is empty in a run of 0.5 s"), res.output
    res = runner.invoke(app, ["run", str(tiny_config), "--set", "metrics.0.t_start=9"])
    assert res.exit_code == 2 and res.output.startswith("error: --set: metrics.0: metric 'std' window [9, 4] s"), res.output
    res = runner.invoke(app, ["validate", str(ROOT / "configs" / "bejarano_fig4_5.yaml"), "--set",
                              "scenarios.noise_free.horizon=3"])
    assert res.exit_code == 2 and res.output.strip() == ("error: --set: scenarios.noise_free.horizon: metric 'std' window "
                                                        "[5, 3] s is empty in a run of 3 s"), res.output


def test_a_world_too_extreme_to_build_is_one_line_at_validation(tmp_path):
    """A notch at 1e300 rad/s is in range (> 0) but overflows the world's filter design: before, a traceback
    from inside the run; now the world is built once (one seed) before anything runs."""
    res = runner.invoke(app, ["run", str(ROOT / "configs" / "torben_fig1.yaml"), "--out", str(tmp_path / "o"),
                              "--set", "scenario.sensors.notch_w0=1e300"])
    assert res.exit_code == 2 and res.output.strip() == ("error: --set: scenario: the world cannot be built from these "
                                                        "values (OverflowError: (34, 'Numerical result out of range'))")
    assert not (tmp_path / "o").exists()


def test_set_into_the_wrong_world_says_where_the_key_goes():
    multi = str(ROOT / "configs" / "tijjani_table3.yaml")
    res = runner.invoke(app, ["validate", multi, "--set", "scenario.cdo.theta=30"])
    assert res.exit_code == 2 and res.output.strip() == (
        "error: --set: scenario.cdo.theta: this experiment's worlds are under 'scenarios' (S1, S2-C1, S2-C2, S3): "
        "set scenarios.<name>.cdo.theta")
    res = runner.invoke(app, ["validate", multi, "--set", "scenarios.S9.horizon=3"])
    assert res.exit_code == 2 and "no scenario 'S9' (have: S1, S2-C1, S2-C2, S3)" in res.output
    assert runner.invoke(app, ["validate", multi, "--set", "scenarios.S1.horizon=3"]).exit_code == 0
    res = runner.invoke(app, ["validate", str(ROOT / "configs" / "bejarano_table4.yaml"), "--set", "scenarios.S1.horizon=3"])
    assert res.exit_code == 2 and "one world, under 'scenario': set scenario.horizon" in res.output


def test_a_whole_world_set_to_a_scenario_file_is_read_as_the_configs_own_reference(tmp_path, monkeypatch):
    """``--set scenario=FILE`` runs a config in another world: FILE (its own ``from:`` too, or ``{from: FILE, key:
    value}``) read as the config's reference would be, relative to the working directory; its keys' errors name it,
    and what the config said of the world it replaces is forgotten. In a profile, FILE is relative to the config."""
    import marinebench as mb

    monkeypatch.chdir(ROOT / "scenarios")
    exp = mb.load(ROOT / "configs" / "torben_fig1.yaml", sets=["scenario={from: dp_sweep.yaml, horizon: 400}"])
    assert (exp.scenario.name, exp.scenario.horizon) == ("dp_sweep", 400)
    study = mb.load(ROOT / "configs" / "tijjani_table3.yaml", sets=["scenarios.S1=rov_s3.yaml"])
    assert study.scenarios["S1"].model_dump(exclude={"name"}) == study.scenarios["S3"].model_dump(exclude={"name"})
    (tmp_path / "short.yaml").write_text("from: " + str(ROOT / "scenarios" / "rov_s3.yaml") + "\nhorizon: -3\n")
    config = str(ROOT / "configs" / "tijjani_observers.yaml")
    monkeypatch.chdir(tmp_path)
    res = runner.invoke(app, ["validate", config, "--set", "scenario=short.yaml"])
    assert res.exit_code == 2 and res.output.strip() == "error: short.yaml: scenario.horizon: Input should be greater than 0"
    res = runner.invoke(app, ["validate", config, "--set", "scenario=rov_s9.yaml"])
    assert res.exit_code == 2 and res.output.strip() == (
        f"error: --set: scenario: scenario file not found: rov_s9.yaml (relative to the working directory: looked for "
        f"{tmp_path.resolve() / 'rov_s9.yaml'})")
    res = runner.invoke(app, ["validate", config, "--set", f"scenario={config}"])  # an experiment, by mistake
    assert res.exit_code == 2 and res.output.strip() == (
        f"error: --set: scenario: {config} is an experiment file (it has variants), not a scenario: name the scenario "
        "file it runs in (its 'scenario:')")
    res = runner.invoke(app, ["validate", config, "--set", "scenario.from=short.yaml"])
    assert res.exit_code == 2 and "set the whole world to run on another scenario file, scenario=FILE" in res.output
    (tmp_path / "listed.yaml").write_text("scenarios: [a]\nvariants: []\n")  # worlds in a list: one line, no traceback
    res = runner.invoke(app, ["validate", "listed.yaml", "--set", "scenarios.0=short.yaml"])
    assert res.exit_code == 2 and res.output.startswith("error: --set: scenarios: Input should be a valid dictionary")
    doc = yaml.safe_load((ROOT / "configs" / "torben_fig1.yaml").read_text())
    (tmp_path / "fig1.yaml").write_text(yaml.safe_dump(doc | {"scenario": str(ROOT / "scenarios" / "dp_impulse.yaml"),
                                                              "profiles": {"swept": ["scenario=../sub/dp_sweep.yaml"]}}))
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "dp_sweep.yaml").write_text((ROOT / "scenarios" / "dp_sweep.yaml").read_text().replace(
        "name: dp_sweep", "name: dp_sub"))
    res = runner.invoke(app, ["validate", "fig1.yaml", "--profile", "swept"])
    assert res.exit_code == 2 and "profiles.swept.0: scenario: scenario file not found: ../sub/dp_sweep.yaml (relative to " \
        "the file's folder" in res.output, res.output  # the profile's file is the config's reference: ../ from tmp_path
    (tmp_path / "fig1.yaml").write_text((tmp_path / "fig1.yaml").read_text().replace("../sub/", "sub/"))
    assert mb.load("fig1.yaml", profile="swept").scenario.name == "dp_sub"


def test_design_prints_the_solved_gains_without_simulating():
    """``design``: what the manifest records, recomputed for other settings with --set."""
    config = str(ROOT / "configs" / "tijjani_observers.yaml")
    res = runner.invoke(app, ["design", config, "--json"])
    assert res.exit_code == 0, res.output
    cdo = json.loads(res.output)["tijjani_observers"]["world_cdo"]
    committed = json.loads((ROOT / "results" / "tijjani_observers" / "manifest.json").read_text())["designs"]["world_cdo"]
    # the interior-point LMI solution agrees across machines to the solver's accuracy, not to the last digit
    # (1.4e-6 relative between an AVX-512 and an AVX2 host)
    assert cdo["k_star"] == pytest.approx(committed["k_star"], rel=1e-4) and cdo["lmi_decay"] == 0.35
    slower = json.loads(runner.invoke(app, ["design", config, "--json", "--set", "scenario.cdo.lmi_decay=0.2"]).output)
    slow = slower["tijjani_observers"]["world_cdo"]
    assert slow["lmi_decay"] == 0.2 and max(slow["poles"]) > max(cdo["poles"])  # a slower design: its slowest pole moves right
    res = runner.invoke(app, ["design", str(ROOT / "configs" / "bejarano_table4.yaml")])  # YAML, rounded for reading
    doc = yaml.safe_load(res.output)["bejarano_table4"]
    assert set(doc) == {"liu_eps0.2", "liu_eps0.1", "proposed_d1.2", "proposed_d2.2"}
    assert doc["liu_eps0.1"]["gains"] == [30.0, 300.0, 1000.0]  # k / eps, k / eps^2, k / eps^3 to 6 digits
    res = runner.invoke(app, ["design", str(ROOT / "configs" / "bejarano_table4.yaml"), "--json",
                              "--set", "variants.1.observer.k=[4, 5, 2]"])  # each k_i with its own power of eps
    assert json.loads(res.output)["bejarano_table4"]["liu_eps0.1"]["gains"] == pytest.approx([40.0, 500.0, 2000.0])
    assert doc["proposed_d2.2"]["slowest_pole_p"] <= -2.2  # the LMI region: poles left of -delta_p1
    res = runner.invoke(app, ["design", config, "--set", "scenario.cdo.lmi_decay=-1"])
    assert res.exit_code == 2 and res.output.startswith("error: --set: scenario.cdo.lmi_decay")
    dp = json.loads(runner.invoke(app, ["design", str(ROOT / "configs" / "torben_fig1.yaml"), "--json"]).output)["torben_fig1"]
    assert not any(key.endswith("L2") or "_L2_" in key for key in dp["npo"])  # the NPO runs L1 alone
    assert max(dp["resetting"]["poles_L2_re"]) < min(dp["resetting"]["poles_L1_re"])  # L2 the more aggressive gain


def test_validate_all_committed_configs_and_scenarios():
    files = sorted(str(p) for p in (ROOT / "configs").glob("*.yaml")) + sorted(str(p) for p in (ROOT / "scenarios").glob("*.yaml"))
    res = runner.invoke(app, ["validate", *files])
    assert res.exit_code == 0, res.output
    assert res.output.count(": ok") == len(files)


def test_every_committed_results_resolved_config_validates():
    """A result's config.resolved.yaml is a config in its own right (``run`` reruns it); two --variants sweeps'
    were not: they kept parameters that are no setting of every variant swept."""
    files = sorted(str(p) for p in (ROOT / "results").glob("*/config.resolved.yaml"))
    assert len(files) >= 30
    res = runner.invoke(app, ["validate", *files])
    assert res.exit_code == 0, res.output
    assert res.output.count(": ok") == len(files)


def test_validate_takes_set_and_profile_as_run_does():
    config = str(ROOT / "configs" / "torben_fig1.yaml")
    assert runner.invoke(app, ["validate", config, "--profile", "quick", "--set", "seeds=2"]).exit_code == 0
    res = runner.invoke(app, ["validate", config, "--set", "scenario.dt=-1"])
    assert res.exit_code == 2 and res.output.startswith("error: --set: scenario.dt: Input should be greater than 0")
    res = runner.invoke(app, ["validate", config, "--profile", "nope"])
    assert res.exit_code == 2 and "no profile 'nope' (have: quick)" in res.output, res.output
    res = runner.invoke(app, ["validate", str(ROOT / "scenarios" / "dp_impulse.yaml"), "--set", "horizon=5"])
    assert res.exit_code == 2 and "a scenario file; --set and --profile apply to experiment files" in res.output


@pytest.mark.parametrize("kind, folder", [("experiment", "configs"), ("scenario", "scenarios")])
def test_schema_accepts_every_committed_file_as_written_and_flags_typos(kind, folder):
    """The schema an editor uses must take the files as written (``from:``, scenario paths, partial overrides)
    and still flag what the loader refuses: an unknown key at any depth, a wrong type, an unknown kind."""
    import jsonschema

    from marinebench.loading import read_yaml

    res = runner.invoke(app, ["schema", "--kind", kind])
    assert res.exit_code == 0, res.output
    schema = json.loads(res.output)
    jsonschema.Draft202012Validator.check_schema(schema)
    check = jsonschema.Draft202012Validator(schema)
    files = sorted((ROOT / folder).glob("*.yaml"))
    assert len(files) >= 8
    if kind == "experiment":  # the examples, and what `run` writes: a resolved document is a valid file too
        files += sorted((ROOT / "examples").glob("*/*.yaml")) + sorted((ROOT / "results").glob("*/config.resolved.yaml"))
    for f in files:
        assert not list(check.iter_errors(read_yaml(f))), f
    derived = {"from": "x.yaml"}  # a file of overrides: every key optional, unknown keys still refused
    assert check.is_valid(derived) and not check.is_valid({**derived, "horizn": 5})
    doc = read_yaml(files[0])
    if kind == "experiment":
        assert check.is_valid({**doc, "scenario": "../scenarios/cs2_noisy.yaml"})
        assert check.is_valid({**doc, "scenario": {"from": "../scenarios/cs2_noisy.yaml", "horizon": 10.0}})
        assert not check.is_valid({**doc, "scenario": {"from": "../scenarios/cs2_noisy.yaml", "horizn": 10.0}})
        assert not check.is_valid({**doc, "seeds": "five"})
        bad = {**doc, "variants": [{**doc["variants"][0], "observer": {"kind": "liu_eso", "epsilon": 0.1}}]}
        assert not check.is_valid(bad)  # a typo inside an observer
        assert not check.is_valid({**doc, "variants": [{"name": "x", "observer": {"kind": "kalman"}}]})
        assert not check.is_valid({k: v for k, v in doc.items() if k != "variants"})  # required without from:
    else:
        assert not check.is_valid({**doc, "horizon": "long"})
        assert not check.is_valid({**doc, "sensors": {"position_noise": {"kind": "none", "bound": 1}}})
        assert check.is_valid({"from": "cs2_noiseless.yaml", "sensors": {"position_noise": {"kind": "none"}}})


@pytest.mark.parametrize("kind", ["experiment", "scenario"])
def test_committed_schemas_are_current_and_every_file_names_its_schema(kind):
    """schemas/*.schema.json (which the configs' yaml-language-server lines point editors at) are what
    `marinebench schema` prints now; regenerate them after changing a model."""
    from marinebench.schema import file_schema

    committed = json.loads((ROOT / "schemas" / f"{kind}.schema.json").read_text())
    assert committed == file_schema(kind), f"stale: marinebench schema --kind {kind} > schemas/{kind}.schema.json"
    folder = {"experiment": "configs", "scenario": "scenarios"}[kind]
    for f in (ROOT / folder).glob("*.yaml"):
        assert f.read_text().startswith(f"# yaml-language-server: $schema=../schemas/{kind}.schema.json\n"), f


@pytest.mark.parametrize("kind", ["experiment", "scenario"])
def test_every_key_of_the_files_has_a_description_for_editors(kind):
    """An editor shows a key's schema description on hover and in completion: every field of every model a file is
    read into says what it is (``kind``, the discriminator, names its model, which has the docstring)."""
    from marinebench.schema import file_schema

    schema = file_schema(kind)
    models = {**schema["$defs"], kind: schema}
    bare = sorted(f"{name}.{key}" for name, model in models.items() for key, field in model.get("properties", {}).items()
                  if key != "kind" and "description" not in field)
    assert not bare


def test_list_shows_registered_kinds():
    res = runner.invoke(app, ["list"])
    assert res.exit_code == 0
    for kind in ("cybership2", "bejarano", "liu_eso", "random_sinusoid", "bandlimited_uniform", "std",
                 "dp_supply", "supply_dp_linear", "npo", "resetting_fto", "impulse", "j_tot"):
        assert kind in res.output
    from marinebench.registry import kinds

    observers = kinds()["observers"]
    assert len(set(observers.values())) == len(observers)  # each kind its own line, even when classes are shared
    scenarios = kinds()["scenarios"]  # with the world keys their runs may set
    assert scenarios["dp_supply"].endswith("Per run (world:, world.<key> sweeps): gnss_sigma, heading_sigma_deg, "
                                           "gm_time_constant, hs; any other setting by its dotted path "
                                           "(sensors.ts, a number a sweep may vary; a switch, text, list or section "
                                           "too), in a world of its own.")
    assert "estimate_offset_depth, estimate_offset_yaw_deg, depth_noise" in scenarios["rov_tracking"]
    assert "Per run (world:, world.<key> sweeps): position_noise_scale; any other" in scenarios["open_loop_asv"]


def test_list_takes_groups():
    res = runner.invoke(app, ["list", "metrics", "observers"])
    assert res.exit_code == 0, res.output
    headers = [line for line in res.output.splitlines() if not line.startswith(" ")]
    assert headers == ["observers", "metrics"]  # the registry's order
    assert "  j_tot " in res.output and "  bejarano " in res.output and "cybership2" not in res.output
    res = runner.invoke(app, ["list", "observer"])
    assert res.exit_code == 2 and res.output.startswith("error: GROUP: no group or kind 'observer' (did you mean observers?); "
                                                        "groups: scenarios, vessels, observers"), res.output
    res = runner.invoke(app, ["list", "bejaran"])
    assert res.exit_code == 2 and "(did you mean bejarano?)" in res.output, res.output


def test_list_of_a_kind_gives_its_settings_with_type_default_and_meaning():
    res = runner.invoke(app, ["list", "bejarano"], env={"COLUMNS": "250"})
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert lines[0].startswith("bejarano (observers): Tuning of the proposed estimator") and "[open_loop_asv, dp_supply]" in lines[0]
    assert any(line.split()[:4] == ["delta_p1", "float", "=", "0.05"] for line in lines), res.output
    assert not any(line.split()[0] == "kind" for line in lines[1:])
    # a nested mapping's settings under their dotted names, as --set and a sweep's KEY write them
    res = runner.invoke(app, ["list", "dp_supply"], env={"COLUMNS": "250"})
    assert "  sensors.gnss_sigma " in res.output and "  horizon " in res.output and "float = required" in res.output
    assert "{kind: supply_dp_linear} | {kind: supply_shipx_lf}" in res.output  # a kind's own settings: list that kind
    # a name in two groups: both
    res = runner.invoke(app, ["list", "custom"], env={"COLUMNS": "250"})
    assert "custom (observers):" in res.output and "custom (controllers):" in res.output
    # one model read by several kinds (the controllers): each kind lists the settings it reads, not the others'
    names = {kind: [line.split()[0] for line in runner.invoke(app, ["list", kind]).output.splitlines()[1:]]
             for kind in ("rise", "srise")}
    controllers = runner.invoke(app, ["list", "custom"]).output.split("custom (controllers):")[1].splitlines()[1:]
    common = ["feedback", "output_scale", "disturbance_feedforward"]
    assert names == {"rise": [*common, "preset", "depth", "yaw"], "srise": [*common, "depth", "yaw"]}
    assert [line.split()[0] for line in controllers] == [*common, "source", "params"]


@pytest.mark.parametrize("config", ["bejarano_table3", "torben_fig1", "tijjani_observers"])
def test_a_scenario_kind_lists_the_signals_its_world_scores_and_only_those(config):
    """`list <scenario kind>` names every signal a metric or figure may name there, each once with what it is: each
    has an estimate (from some observer) and a truth in a world of that kind. Before, nothing listed them."""
    import numpy as np

    from marinebench.experiments.runner import make_world
    from marinebench.loading import load_experiment

    exp, _ = load_experiment(ROOT / "configs" / f"{config}.yaml")
    kind, runs = exp.scenario.kind, np.arange(len(exp.variants))
    world = make_world(exp, runs, np.zeros_like(runs))
    if kind == "dp_supply":  # its lumped disturbance only when an experiment asks for it
        from marinebench.dp_scenario import DpWorld

        world = DpWorld(exp.scenario, 0, np.zeros(1, dtype=int), lumped=True)
    truth = set(world.truth(0.0, world.x0))
    if kind == "rov_tracking":  # the world's own observers
        estimated = set(world.estimates(0.0, world.x0))
    else:  # the built-in observers, which run on both ship worlds (the DP ones reporting the lumped disturbance)
        from marinebench.observers.bejarano import BejaranoObserver
        from marinebench.observers.dp import LUMPED_SIGNALS, DpObserver
        from marinebench.observers.liu_eso import LiuEsoObserver

        estimated = {*BejaranoObserver.signals, *LiuEsoObserver.signals, *DpObserver.signals, *LUMPED_SIGNALS}
    listed = exp.scenario.SIGNALS
    assert set(listed) == truth & estimated, listed
    res = runner.invoke(app, ["list", kind], env={"COLUMNS": "250"})
    lines = res.output.split("signals (what a metric's or figure's signals: may name; est - truth):\n")[1].splitlines()
    assert [line.split()[0] for line in lines] == list(listed) and all(len(line.split()) > 2 for line in lines)


def test_a_setting_another_controller_kind_reads_is_refused():
    """Before, S+RISE took a RISE preset without a word, and ran Table II's gains."""
    from marinebench.controllers.spec import ControllerSpec

    with pytest.raises(ValueError, match="preset chooses RISE's gains; S\\+RISE's are Table II's"):
        ControllerSpec(kind="srise", preset="table2_equivalent")
    assert ControllerSpec(kind="rise", preset="table2_equivalent").preset == "table2_equivalent"


def test_every_listed_kind_has_its_settings_and_every_model_is_listed():
    from marinebench.registry import fields_of, kind_models, kinds

    listed, models = kinds(), kind_models()
    assert {g: set(k) for g, k in models.items()} == {g: set(k) for g, k in listed.items()}
    for group, entries in models.items():
        for kind, model in entries.items():
            rows = fields_of(model)
            assert all(name and type_ and default for name, type_, default, _ in rows), (group, kind)


def test_experiment_from_another_experiment(tiny_config, tmp_path):
    """`from:` starts from another experiment: its (relative) scenario, variants and metrics; mappings merge
    key by key, lists are replaced; the derived file names itself; a bad override names the derived file."""
    from marinebench.loading import load_experiment

    (tmp_path / "sub").mkdir()
    derived = tmp_path / "sub" / "derived.yaml"
    derived.write_text(yaml.safe_dump({"from": f"../{tiny_config.name}", "scenario": {"horizon": 2.0}, "seeds": 3}))
    base, _ = load_experiment(tiny_config)
    exp, origins = load_experiment(derived)
    assert exp.name == "derived" and exp.seeds == 3 and exp.scenario.horizon == 2.0
    assert exp.scenario.dt == base.scenario.dt and [v.name for v in exp.variants] == [v.name for v in base.variants]
    assert origins["from"] == tiny_config.resolve()
    res = runner.invoke(app, ["validate", str(derived)])
    assert res.exit_code == 0, res.output  # recognised as an experiment, not a scenario
    derived.write_text(yaml.safe_dump({"from": f"../{tiny_config.name}", "scenario": {"dt": -1}}))
    res = runner.invoke(app, ["validate", str(derived)])
    assert res.exit_code == 2 and res.output.startswith(f"error: {derived}: scenario.dt"), res.output
    derived.write_text(yaml.safe_dump({"from": "derived.yaml", "variants": []}))
    res = runner.invoke(app, ["validate", str(derived)])
    assert res.exit_code == 2 and "circular experiment reference" in res.output, res.output


def test_a_bad_key_is_named_in_the_file_of_the_from_chain_that_holds_it(tiny_config, tmp_path):
    """derived -> middle -> tiny: a bad key is reported in the file it is written in, and a file later in the
    chain that sets the key again takes it over."""
    middle, derived = tmp_path / "middle.yaml", tmp_path / "derived.yaml"
    middle.write_text(yaml.safe_dump({"from": tiny_config.name, "seeds": 0}))
    derived.write_text(yaml.safe_dump({"from": "middle.yaml", "description": "d"}))
    res = runner.invoke(app, ["validate", str(derived)])
    assert res.exit_code == 2 and res.output.strip() == f"error: {middle}: seeds: Input should be greater than or equal to 1", res.output
    derived.write_text(yaml.safe_dump({"from": "middle.yaml", "seeds": 3}))
    assert runner.invoke(app, ["validate", str(derived)]).exit_code == 0
    derived.write_text(yaml.safe_dump({"from": "middle.yaml", "seeds": 3, "table": {"metric": "nope"}}))
    res = runner.invoke(app, ["validate", str(derived)])
    assert res.exit_code == 2 and res.output.startswith(f"error: {derived}: "), res.output
    middle.write_text(yaml.safe_dump({"from": tiny_config.name, "bogus": 1}))
    derived.write_text(yaml.safe_dump({"from": "middle.yaml", "seeds": 3}))
    res = runner.invoke(app, ["validate", str(derived)])
    assert res.exit_code == 2 and res.output.startswith(f"error: {middle}: bogus: unknown key (allowed here: "), res.output


def test_two_configs_that_would_write_one_folder_are_refused(tiny_config, tmp_path):
    """Two files with the same stem write the same results/<stem>/: the second would silently replace the
    first, so the run is refused before anything runs; one file named twice (overlapping globs) runs once."""
    (tmp_path / "other").mkdir()
    other = tmp_path / "other" / tiny_config.name
    other.write_text(yaml.safe_dump({"from": str(tiny_config), "seeds": 1}))
    res = runner.invoke(app, ["run", str(tiny_config), str(other), "--out", str(tmp_path / "o"), "--quiet"])
    assert res.exit_code == 2 and res.output.strip() == (
        f"error: {other}: writes {tmp_path / 'o' / 'tiny'}, as {tiny_config} does; run them with different --out")
    assert not (tmp_path / "o").exists()
    twice = runner.invoke(app, ["run", str(tiny_config), str(tmp_path / "." / "tiny.yaml"), "--out", str(tmp_path / "o"),
                                "--jobs", "1"])
    assert twice.exit_code == 0 and twice.output.count("-> ") == 1, twice.output


def test_wrong_kind_of_input_is_one_line(tmp_path):
    scenario = ROOT / "scenarios" / "rov_s1.yaml"
    res = runner.invoke(app, ["run", str(scenario), "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and res.output.strip() == (
        f"error: {scenario}: a scenario file (a world), not an experiment: experiments name it under 'scenario:' "
        "(marinebench validate checks scenario files)")
    # an experiment that lacks its variants is still an experiment (before: read as a scenario file, by run and validate)
    unfinished = tmp_path / "unfinished.yaml"
    unfinished.write_text(yaml.safe_dump({"name": "x", "scenario": str(scenario), "metrics": [{"kind": "rmse"}]}))
    for command in ("run", "validate"):
        res = runner.invoke(app, [command, str(unfinished), *(["--out", str(tmp_path / "o")] if command == "run" else [])])
        assert res.exit_code == 2 and res.output.strip() == f"error: {unfinished}: variants: Field required", res.output
    bench = runner.invoke(app, ["bench", "--config", str(ROOT / "configs" / "bejarano_table4.yaml"), "--params", "delta_p1"])
    assert bench.exit_code == 2 and "reference of the DP observers, which exists for dp_supply scenarios" in bench.output
    assert not (tmp_path / "o").exists()
    # a DP world whose swept variant is no DP observer (before: an AttributeError after the batch), and parameters
    # the config does not sweep (before: named sweep.params, though --params had chosen them)
    cross = ROOT / "configs" / "cross_dp_impulse.yaml"
    for args, expected in [
        (["--config", str(cross), "--params", "eps"], (f"error: {cross}: sweep.variant: liu_eps0.1: bench's per-run "
                                                      "reference is of the DP observers (npo, resetting_fto)")),
        (["--config", str(ROOT / "configs" / "torben_fig1.yaml")], ("error: --params: k,delta,eps: "
         f"{ROOT / 'configs' / 'torben_fig1.yaml'} has no sweep parameter 'k' (its sweep.params: gnss_sigma)")),
    ]:
        bench = runner.invoke(app, ["bench", *args, "--horizon", "2", "--n", "2", "--runs", "1"])
        assert bench.exit_code == 2 and bench.output.startswith(expected) and len(bench.output.splitlines()) == 1, bench.output


@pytest.mark.parametrize("args, expected", [
    (["--n", "-3"], "error: --n: must be from 2 to 1000 points per parameter"),  # before: numpy's traceback
    (["--n", "0"], "error: --n: must be from 2 to 1000 points per parameter"),  # before: the config's n, silently
    (["--horizon", "inf"], "error: --horizon: must be a positive, finite number of seconds"),
    (["--params", "k,k", "--n", "2"], "error: --params: k,k: a parameter given more than once"),  # before: "PARAM:"
])
def test_bench_options_out_of_range_are_one_line_as_in_sweep(args, expected):
    res = runner.invoke(app, ["bench", "--config", str(ROOT / "configs" / "torben_fig3.yaml"), *args])
    assert res.exit_code == 2 and res.output.strip() == expected, res.output


def test_bench_times_both_engines_on_the_same_runs_and_they_agree(tmp_path, monkeypatch):
    """bench: 12 runs of 2 s of the Torben sweep, batched and by the per-run reference; the ratio, the
    extrapolation and their agreement are printed, and nothing is written."""
    monkeypatch.chdir(tmp_path)
    res = runner.invoke(app, ["bench", "--config", str(ROOT / "configs" / "torben_fig3.yaml"), "--n", "2",
                              "--horizon", "2", "--runs", "2"])
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert lines[0] == "runs: 12 x 2 s (sweep k,delta,eps); reference on 2 of them"
    assert re.search(r"^speed-up \(same process\): [0-9.]+x$", res.output, re.MULTILINE)
    assert "extrapolated full sweep (12 x 1000 s)" in res.output
    worst = float(re.search(r"batched vs reference: (\S+)$", res.output, re.MULTILINE).group(1))
    assert worst < 1e-9
    assert list(tmp_path.iterdir()) == []


def test_sweep_outside_the_repository_says_where_the_default_config_is_looked_for(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for command in (["sweep", "k"], ["bench"]):
        res = runner.invoke(app, command)
        assert res.exit_code == 2 and len(res.output.strip().splitlines()) == 1, res.output
        assert res.output.startswith(f"error: configs/torben_fig3.yaml: file not found in {tmp_path}: the default --config")
    assert list(tmp_path.iterdir()) == []


def test_run_jobs_gives_the_same_files_as_one_process(tmp_path, monkeypatch):
    """By default run puts the experiments side by side in local worker processes, one per core: the same
    metrics, tables and resolved configs as a run in this process (--jobs 1)."""
    from marinebench.experiments import cluster

    pools = []
    monkeypatch.setattr(cluster, "available_cores", lambda: 2)
    monkeypatch.setattr(cluster, "local_pool", lambda n, make=cluster.local_pool: pools.append(n) or make(n))
    configs = [str(ROOT / "configs" / "bejarano_table4.yaml"), str(ROOT / "configs" / "torben_fig3.yaml")]
    sets = ["--seeds", "2", "--set", "scenario.horizon=20", "--quiet"]
    one = CliRunner().invoke(app, ["run", *configs, *sets, "--jobs", "1", "--out", str(tmp_path / "one")])
    assert pools == []
    two = CliRunner().invoke(app, ["run", *configs, *sets, "--out", str(tmp_path / "two")])
    assert pools == [2]
    assert one.exit_code == 0 and two.exit_code == 0, (one.output, two.output)
    for stem in ("bejarano_table4", "torben_fig3"):
        for name in ("metrics.csv", "table.md", "config.resolved.yaml"):
            assert (tmp_path / "one" / stem / name).read_text() == (tmp_path / "two" / stem / name).read_text()


def test_an_experiment_that_crashes_in_a_worker_is_one_line_and_the_others_are_written(tmp_path, monkeypatch):
    """An exception that is not a config error (a bug) in a --jobs worker: one line naming the config, exit 2,
    after the other experiments are written."""
    from marinebench import cli

    real = cli.run._run_and_write

    def crash_on_torben(path, *args, **kwargs):
        if path.stem == "torben_fig3":
            raise RuntimeError("boom")
        return real(path, *args, **kwargs)

    monkeypatch.setattr(cli.run, "_run_and_write", crash_on_torben)  # inherited by the forked workers
    configs = [str(ROOT / "configs" / "bejarano_table4.yaml"), str(ROOT / "configs" / "torben_fig3.yaml")]
    res = CliRunner().invoke(app, ["run", *configs, "--seeds", "1", "--set", "scenario.horizon=10", "--quiet",
                                   "--jobs", "2", "--out", str(tmp_path)])
    assert res.exit_code == 2, res.output
    assert res.output.strip().splitlines()[-1] == (
        f"error: {configs[1]}: failed in a --jobs worker process (RuntimeError: boom; --jobs 1 shows the traceback)")
    assert not (tmp_path / "torben_fig3").exists() and (tmp_path / "bejarano_table4" / "metrics.csv").exists()


def test_files_are_named_relative_to_the_working_directory_when_below_it(tmp_path, monkeypatch):
    """Manifests and errors name a scenario as the user would (``scenarios/x.yaml`` from the repository's root),
    not by a machine's absolute path; a file outside the working directory keeps its absolute path."""
    from marinebench.loading import load_experiment

    monkeypatch.chdir(ROOT)
    _, origins = load_experiment(Path("configs/bejarano_table4.yaml"))
    assert origins["scenario"] == Path("scenarios/cs2_noisy.yaml")
    _, origins = load_experiment(Path("configs/torben_fig1_matched.yaml"))  # from: torben_fig1.yaml
    assert origins["from"] == Path("configs/torben_fig1.yaml") and origins["scenario"] == Path("scenarios/dp_impulse.yaml")
    (tmp_path / "w").mkdir()
    bad = yaml.safe_load((ROOT / "scenarios" / "cs2_noisy.yaml").read_text()) | {"dt": -1, "from": str(ROOT / "scenarios" / "cs2_noiseless.yaml")}
    (tmp_path / "w" / "bad.yaml").write_text(yaml.safe_dump(bad))
    (tmp_path / "exp.yaml").write_text("from: " + str(ROOT / "configs" / "bejarano_table4.yaml") + "\nscenario: w/bad.yaml\n")
    res = runner.invoke(app, ["validate", str(tmp_path / "exp.yaml")])
    assert res.exit_code == 2 and res.output.startswith(f"error: {tmp_path / 'w' / 'bad.yaml'}: scenario.dt:"), res.output
    monkeypatch.chdir(tmp_path)
    res = runner.invoke(app, ["validate", "exp.yaml"])
    assert res.exit_code == 2 and res.output.startswith("error: w/bad.yaml: scenario.dt:"), res.output


def test_a_worker_that_dies_is_one_line(tmp_path, monkeypatch):
    """A --jobs worker killed mid-run (out of memory, a signal): one line naming the config, exit 2, no traceback."""
    import os

    from marinebench import cli

    def die(path, *args, **kwargs):
        os._exit(9)  # as if killed: the pool breaks

    monkeypatch.setattr(cli.run, "_run_and_write", die)  # inherited by the forked workers
    config = str(ROOT / "configs" / "bejarano_table4.yaml")
    res = CliRunner().invoke(app, ["run", config, config.replace("table4", "fig6"), "--seeds", "1", "--quiet",
                                   "--jobs", "2", "--out", str(tmp_path)])
    assert res.exit_code == 2 and len(res.output.strip().splitlines()) == 1, res.output
    assert res.output.startswith("error: ") and "its --jobs worker process died (BrokenProcessPool" in res.output


def test_run_warns_when_diverged_runs_are_left_out(tiny_config, tmp_path):
    """A run that diverged is flagged, not averaged (test_engine), and run says so in one warning line."""
    res = runner.invoke(app, ["run", str(tiny_config), "--out", str(tmp_path / "out"), "--quiet",
                              "--set", "variants.0.observer.eps=0.001", "--set", "engine.check_step=false"])
    assert res.exit_code == 0, res.output
    assert "warning: tiny: " in res.output and "metric values from diverged runs excluded" in res.output


EXTREME = {
    # eps = 1e-300 makes the ESO's gains overflow: before, NaN poles and a LinAlgError traceback
    "liu_eso_eps": ("bejarano_fig2_3", "variants.0.observer.eps=1e-300",
                    "scenario.dt: dt=0.005 s is too large for observer poles up to |lambda|=1e+300 rad/s"),
    # CLARABEL (Rust) >= 0.9 panics on a weight of 1e300 (the solver crashed; before, a pyo3 PanicException, a
    # BaseException, went through), older ones fail (solver failed); test_design has the panic on every version
    "solver_panic": ("bejarano_fig7", "variants.0.observer.trace_weight=1e300",
                     re.compile(r"variants\.0\.observer: rotational LMI \(delta_psi1=0\.0, rho=50\.0\): (the solver "
                                r"crashed|solver failed) \(")),
    "singular_model": ("cross_dp_impulse", "scenario.design_vessel.L=1e-300",
                       "scenario.design_vessel: the vessel model cannot be built from these values (LinAlgError"),
    # the CDO's per-sample map overflows: before, a LinAlgError (inf in expm) or an OverflowError (theta**3)
    "cdo_period": ("tijjani_observers", "scenario.sensors.depth_period=1e300",
                   "scenario.cdo: CDO depth: the per-sample error map has spectral radius inf >= 1 at h = 1e+300 s"),
    "cdo_theta": ("tijjani_observers", "scenario.cdo.theta=1e300",
                  "scenario.cdo: CDO depth: the per-sample error map has spectral radius inf >= 1 at h = 0.05 s"),
    "cdo_k_w": ("tijjani_observers", "scenario.cdo.k_w=-1e300",
                "scenario.cdo: CDO depth: the per-sample error map has spectral radius inf >= 1 at h = 0.05 s"),
    # the ROV world's own observers are held to the step check as the others are: before, a stiff EO ran, diverged
    # and its runs were dropped with a warning (and eps = 1e-300 failed `design` with a LinAlgError)
    "rov_eo_stiff": ("tijjani_observers", "variants.1.observer.eo.eps=1e-4",
                     ("scenario.dt: dt=0.002 s is too large for observer poles up to |lambda|=1e+04 rad/s (dt*|lambda| "
                     "= 20 > 0.5); use dt <= 5e-05 (the fastest: variant 'eo')")),
    # a sea state that makes every run non-finite from its first step: before, the runs went on to diverge (and with
    # the resetting observer, the batch stopped on an SVD of NaN at the first window end)
    "sea_state": ("torben_fig1", "scenario.waves.gamma=1e300",
                  "scenario: the world cannot be run from these values (not finite at t = 0: its measurement)"),
    "rov_eo_eps": ("tijjani_observers", "scenario.eo.eps=1e-300", ("rad/s (dt*|lambda| = 2e+297 > 0.5); use dt <= "
                   "5e-301 (every variant alike)")),
}


@pytest.mark.parametrize("case", sorted(EXTREME))
def test_values_in_range_but_extreme_are_one_line_errors(case):
    """In range for their fields, but beyond what a design's numbers hold (found by setting every numeric leaf of
    every config to +-1e300 and 1e-300): a one-line error naming the key, exit 2, no traceback."""
    config, assignment, expected = EXTREME[case]
    res = runner.invoke(app, ["validate", str(ROOT / "configs" / f"{config}.yaml"), "--set", assignment])
    assert res.exit_code == 2 and isinstance(res.exception, SystemExit), res.output
    lines = res.output.strip().splitlines()
    shown = expected.search(lines[0]) if isinstance(expected, re.Pattern) else expected in lines[0]
    assert len(lines) == 1 and lines[0].startswith("error: ") and shown, res.output


def test_liu_eso_gains_of_an_extreme_eps_do_not_overflow():
    """The design summary's ESO gains (manifest, `marinebench design`) are formed in numpy: eps = 1e300 gives
    gains that underflow to 0 where Python's float power raised OverflowError."""
    res = runner.invoke(app, ["design", str(ROOT / "configs" / "bejarano_fig2_3.yaml"), "--json",
                              "--set", "variants.0.observer.eps=1e300"])
    assert res.exit_code == 0, res.output
    design = json.loads(res.output)
    gains = next(iter(design.values()))["liu_eps0.2"]["gains"]
    assert gains == [pytest.approx(3e-300), 0.0, 0.0]


def test_an_empty_study_names_its_key():
    """Before, the line named '(top level)'."""
    res = runner.invoke(app, ["validate", str(ROOT / "configs" / "tijjani_table3.yaml"), "--set", "scenarios={}"])
    assert res.exit_code == 2 and res.output.strip() == (
        "error: --set: scenarios: empty (name at least one world, or give scenario: instead)"), res.output


def test_a_sweep_claim_on_a_signal_its_metric_does_not_record_is_refused():
    """Before, it validated, and the sweep left the claim out of claims.md without a word."""
    res = runner.invoke(app, ["validate", str(ROOT / "configs" / "torben_fig3.yaml"), "--set",
                              "sweep.claims=[{kind: probe, param: k, at: 0.7, vs: 0, text: t, signal: psi}]"])
    assert res.exit_code == 2 and res.output.strip() == (
        "error: --set: sweep.claims.0.signal: 'psi' is not recorded by metric 'J_tot' (it records: z)"), res.output
    res = runner.invoke(app, ["validate", str(ROOT / "configs" / "bejarano_fig7.yaml"), "--set",
                              "sweep.claims.0.signal=sigma_v"])  # a signal its std records (v, sigma_v)
    assert res.exit_code == 0, res.output


def test_a_studys_paper_values_are_keyed_by_scenario_metric_and_signal():
    res = runner.invoke(app, ["validate", str(ROOT / "configs" / "tijjani_table3.yaml"), "--set",
                              "table.paper.values={rise: {S9/rmse/depth: 1}}"])
    assert res.exit_code == 2 and res.output.strip() == (
        "error: --set: table.paper.values: rise: ['S9/rmse/depth'] are not keyed as the table reads them: "
        "'scenario/metric/signal' (scenarios: S1, S2-C1, S2-C2, S3)"), res.output


def test_results_are_utf8_whatever_the_locales_encoding(tmp_path):
    """Tables, claims, configs and manifests hold δ, σ, ≈: they are written as UTF-8 under any locale. Before, a
    process whose locale encoding is ASCII (here forced: no UTF-8 mode, no C-locale coercion; a Latin-1 locale is
    alike) wrote nothing, with a UnicodeEncodeError traceback."""
    import codecs
    import os
    import subprocess
    import sys

    env = {**os.environ, "LC_ALL": "C", "LANG": "C", "PYTHONUTF8": "0", "PYTHONCOERCECLOCALE": "0"}
    probe = [sys.executable, "-c", "import locale; print(locale.getpreferredencoding(False))"]
    encoding = subprocess.run(probe, env=env, capture_output=True, text=True, check=True).stdout.strip()
    assert codecs.lookup(encoding).name == "ascii"  # ANSI_X3.4-1968 on glibc, US-ASCII elsewhere
    out = tmp_path / "out"
    res = subprocess.run([sys.executable, "-m", "marinebench.cli", "run", str(ROOT / "configs" / "bejarano_fig6.yaml"),
                          "--profile", "quick", "--seeds", "1", "--jobs", "1", "--quiet", "--out", str(out)],
                         env=env, capture_output=True, text=True, cwd=tmp_path, check=False)
    assert res.returncode == 0, res.stderr
    texts = {p.name: p.read_text(encoding="utf-8") for p in (out / "bejarano_fig6").iterdir() if p.is_file()}
    assert set(texts) == {"config.resolved.yaml", "manifest.json", "metrics.csv", "table.md", "claims.md"}
    assert any(not t.isascii() for t in texts.values())


def _long_options() -> dict[str, list[list[str]]]:
    """command -> its options, each as its long names (aliases such as --gnss, --groups together), --help left out."""
    import typer.main

    return {name: [names for p in command.params if p.param_type_name == "option"
                   if (names := [o for o in p.opts + p.secondary_opts if o.startswith("--")]) != ["--help"]]
            for name, command in typer.main.get_command(app).commands.items()}


@pytest.mark.parametrize("page", ["README.md", "docs/commands.md"])
def test_the_command_synopses_list_every_option_of_every_command(page):
    """The synopsis block of the README and docs/commands.md (``marinebench run CONFIG... [--out DIR] ...``) names
    each command's options, no more and no fewer (an option added to the CLI and not to the synopsis fails here)."""
    text = (ROOT / page).read_text(encoding="utf-8")
    block = re.search(r"```\n(marinebench run .*?)```", text, re.DOTALL)[1]
    written: dict[str, set[str]] = {}
    for line in block.splitlines():
        if m := re.match(r"marinebench (\w+) (.*)", line):
            written.setdefault(m[1], set()).update(re.findall(r"--[a-z][a-z-]*", m[2].split("#")[0]))
    options = _long_options()
    assert set(written) == set(options), page
    for name, aliases in options.items():  # an option may be written by any one of its names
        assert written[name] == {next((o for o in names if o in written[name]), names[0]) for names in aliases}, (page, name)


def test_the_command_reference_describes_every_option_beyond_its_synopsis():
    """docs/commands.md promises every option of every command: each long option is named in its text too."""
    body = (ROOT / "docs" / "commands.md").read_text(encoding="utf-8").split("```", 2)[2]  # after the synopsis
    silent = {o for aliases in _long_options().values() for names in aliases for o in names
              if not re.search(re.escape(o) + r"\b", body)}
    assert not silent
