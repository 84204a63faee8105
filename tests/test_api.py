"""The Python API (``marinebench.load/run/sweep/write``) gives what the command line gives."""

import time

import numpy as np
import pytest
from typer.testing import CliRunner

import marinebench as mb
from marinebench.cli import app
from marinebench.errors import ConfigError, MarinebenchError

from .conftest import ROOT

CONFIG = ROOT / "configs" / "torben_fig1.yaml"
SETS = ["seeds=2", "scenario.horizon=120"]


def test_load_run_write_match_the_cli(tmp_path):
    exp = mb.load(CONFIG, sets=SETS)
    result = mb.run(exp)
    assert set(result.metrics["variant"]) == {"npo", "resetting"} and (result.metrics["status"] == "ok").all()
    out = mb.write(result, tmp_path / "api", config=CONFIG)
    res = CliRunner().invoke(app, ["run", str(CONFIG), "--out", str(tmp_path / "cli"), "--quiet",
                                   *[a for s in SETS for a in ("--set", s)]])
    assert res.exit_code == 0, res.output
    cli = tmp_path / "cli" / "torben_fig1"
    for name in ("metrics.csv", "table.md", "config.resolved.yaml"):
        assert (out / name).read_text() == (cli / name).read_text(), name
    assert sorted(p.name for p in (out / "figures").iterdir()) == sorted(p.name for p in (cli / "figures").iterdir())


def test_bad_input_raises_a_config_error_naming_file_and_key(tmp_path):
    with pytest.raises(ConfigError, match=r"--set: scenario\.dt: Input should be greater than 0"):
        mb.load(CONFIG, sets=["scenario.dt=-1"])
    bad = tmp_path / "bad.yaml"
    bad.write_text(f"from: {CONFIG}\nseeds: 0\n")
    with pytest.raises(ConfigError, match=r"bad\.yaml: seeds: Input should be greater than or equal to 1"):
        mb.load(bad)


def test_one_override_may_be_a_plain_string():
    """``sets="seeds=3"`` is one override, not a sequence of one-character ones; None is none; anything but strings
    is a TypeError that says what it takes (before: "argument of type 'int' is not iterable")."""
    assert mb.load(CONFIG, sets="seeds=3").seeds == 3
    assert mb.load(CONFIG, sets=None).seeds == mb.load(CONFIG).seeds
    with pytest.raises(TypeError, match="each of sets is a 'dotted.key=value' string, not 1"):
        mb.load(CONFIG, sets=[1])
    with pytest.raises(ConfigError, match=r"--set: scenario\.dt: Input should be greater than 0"):
        mb.load(CONFIG, sets="scenario.dt=-1")


def test_the_manifest_gives_the_step_of_one_world_at_the_top_and_of_several_per_scenario(tmp_path):
    import json

    one = mb.write(mb.run(mb.load(CONFIG, sets=SETS)), tmp_path / "one", config=CONFIG)
    man = json.loads((one / "manifest.json").read_text())
    assert (man["dt"], man["horizon"], man["steps"]) == (0.05, 120.0, 2400) and "scenarios" not in man
    rov = ROOT / "configs" / "tijjani_table3.yaml"
    sets = [f"scenarios.{s}.horizon=0.2" for s in ("S1", "S2-C1", "S2-C2", "S3")] + ["seeds=1"]
    several = mb.write(mb.run(mb.load(rov, sets=sets)), tmp_path / "several", config=rov)
    per = json.loads((several / "manifest.json").read_text())["scenarios"]
    assert set(per) == {"S1", "S2-C1", "S2-C2", "S3"} and per["S1"]["horizon"] == 0.2


def test_a_dp_world_names_a_model_mismatch_only_where_the_observers_model_differs():
    from marinebench.dp_scenario import DpScenario
    from marinebench.results.outputs import model_assumptions

    plant = DpScenario(name="p", horizon=10).vessel
    same = DpScenario(name="same", horizon=10, design_vessel=plant.model_dump())
    other = DpScenario(name="other", horizon=10, vessel={"kind": "supply_shipx_lf"}, design_vessel={"kind": "supply_dp_linear"})
    assert model_assumptions({"a": DpScenario(name="none", horizon=10), "b": same}) == []
    assert model_assumptions({"c": other}) == [
        "scenario other: plant supply_shipx_lf, observers designed and run on supply_dp_linear (model mismatch)"]


def test_an_rov_manifest_says_where_the_observers_start_from_the_world_not_the_config_text():
    """The initial estimation error decides Fig. 2's claims (docs/tijjani.md), so the manifest states the one that ran,
    with a --set included, grouping the worlds that share it; and so for the thrusters' lag."""
    from marinebench.results.outputs import model_assumptions

    table3 = mb.load(ROOT / "configs" / "tijjani_table3.yaml", sets=["scenarios.S3.estimate_offset=[0.01, 2]",
                                                                       "scenarios.S2-C2.vessel.thrust_time_constant=0.05"])
    assert model_assumptions({n: table3.part(n).scenario for n in table3.scenario_names}) == [
        ("scenarios S1, S2-C1, S3: the thrust follows the command at once (vessel.thrust_time_constant; the paper gives "
         "no thruster dynamics)"),
        ("scenarios S1, S2-C1, S2-C2: the CDO's and EO's estimates start at the true depth and yaw (estimate_offset; no "
        "initial estimation error is given in the paper)"),
        ("scenario S2-C2: each thruster's thrust lags its command, first order with T = 0.05 s "
         "(vessel.thrust_time_constant; the paper gives no thruster dynamics)"),
        ("scenario S3: the CDO's and EO's estimates start 0.01 m and 2 deg from the true depth and yaw (estimate_offset; "
        "no initial estimation error is given in the paper)")]
    fig2 = mb.load(ROOT / "configs" / "tijjani_observers.yaml", sets=["scenario.estimate_offset=[0.03, 0]"])
    assert "S1: the CDO's and EO's estimates start 0.03 m and 0 deg from" in model_assumptions({"": fig2.scenario})[1]


def test_a_multi_scenario_run_stacks_its_parts_and_counts_their_cost():
    """Tijjani's Table III runs three variants on S1, S2-C1 and S2-C2 and CDO-S+RISE alone on S3: the cost counts
    runs x steps per scenario, the stacked metrics are indexed afresh, the parts keep their own traces."""
    from marinebench.experiments.runner import run_steps, steps

    rov = ROOT / "configs" / "tijjani_table3.yaml"
    exp = mb.load(rov, sets=[f"scenarios.{s}.horizon=0.02" for s in ("S1", "S2-C1", "S2-C2", "S3")] + ["seeds=2"])
    n = 10  # 0.02 s at the ROV world's 2-ms step
    assert steps(exp) == 4 * n and run_steps(exp) == (3 + 3 + 3 + 1) * 2 * n
    t0 = time.perf_counter()
    result = mb.run(exp)
    elapsed = time.perf_counter() - t0
    assert 0 < result.wall_time <= elapsed
    assert list(result.metrics.index) == list(range(len(result.metrics)))
    assert set(result.parts) == {"S1", "S2-C1", "S2-C2", "S3"}
    assert result.traces[0].size == 0 and result.traced.size == 0  # the figures draw from the parts
    s3 = result.parts["S3"]
    assert list(s3.traced) == [0] and s3.traces[0].size > 0  # seed 0 of its one variant is drawn
    untraced = mb.run(exp.part("S3"), traces=False)
    assert untraced.traced.size == 0 and untraced.traces[0].size == 0


def test_run_takes_a_path_and_wrong_arguments_are_a_type_error(tmp_path):
    """``mb.run("configs/x.yaml")`` loads the file (before: AttributeError 'str' object has no attribute
    'scenarios'); anything else but an Experiment, and a write of anything but a RunResult, is a TypeError."""
    tiny = tmp_path / "tiny.yaml"
    tiny.write_text(f"from: {CONFIG}\nseeds: 1\nscenario: {{horizon: 160}}\n")
    assert len(mb.run(tiny, traces=False).metrics) == len(mb.run(mb.load(tiny), traces=False).metrics) > 0
    with pytest.raises(TypeError, match="run\\(\\) takes an Experiment .* not dict"):
        mb.run({"seeds": 1})
    with pytest.raises(TypeError, match="write\\(\\) takes the RunResult .* not NoneType"):
        mb.write(None, tmp_path / "w")
    assert not (tmp_path / "w").exists()


def test_sweep_gives_the_runs_the_sweep_command_writes(tmp_path):
    """``mb.sweep``: the command's sweep in one batch in this process, nothing written; the same runs, tags and
    numbers as its ``metrics.csv`` (which rounds them to 7 digits), in the same order (the command's in batches)."""
    import pandas as pd

    config = ROOT / "configs" / "torben_fig3.yaml"
    res = CliRunner().invoke(app, ["sweep", "k", "eps", "--config", str(config), "--n", "3", "--horizon", "40",
                                   "--seeds", "2", "--chunk-size", "10", "--jobs", "1", "--out", str(tmp_path), "--quiet"])
    assert res.exit_code == 0, res.output
    written = pd.read_csv(tmp_path / "torben_fig3_sweep_k_eps_n3_40s_2seeds" / "metrics.csv")
    cwd = sorted(tmp_path.iterdir())
    swept = mb.sweep(mb.load(config, sets=["seeds=2"]), ["k", "eps"], n=3, horizon=40).metrics
    assert sorted(tmp_path.iterdir()) == cwd  # nothing written
    assert len(swept) == len(written) and swept["variant"].nunique() == 2 * 3 * 2  # parameters x points x groups
    keys = ["variant", "seed", "signal", "metric"]
    assert swept[keys].astype(str).equals(written[keys].astype(str))
    both = written.merge(swept, on=keys, suffixes=("_cli", "_api"), validate="one_to_one")
    for column in ("param", "gnss", "status"):
        assert (both[f"{column}_cli"] == both[f"{column}_api"]).all(), column
    assert np.allclose(both["param_value_api"], both["param_value_cli"], rtol=1e-6, atol=0)
    assert np.allclose(both["value_api"], both["value_cli"], rtol=1e-6, atol=0)
    grid = mb.sweep(config, ["k", "delta"], grid=True, n=np.int64(2), groups=["dgnss"], horizon=40).metrics
    assert sorted(set(zip(grid["param_value"], grid["param2_value"]))) == [(0.0, 0.15), (0.0, 10.0), (1.0, 0.15), (1.0, 10.0)]
    assert set(grid["gnss"]) == {"dgnss"} and set(grid["param2"]) == {"delta"}


def test_sweep_takes_parameters_given_in_place_as_the_command_does(tmp_path):
    """``mb.sweep(config, "KEY=LO..HI")``: the command's ``sweep KEY=LO..HI`` runs, on a path or a loaded
    experiment, with or without a ``sweep:`` section; the section's claims outside the new range are left out."""
    import pandas as pd

    fig6 = ROOT / "configs" / "bejarano_fig6.yaml"  # no sweep section
    res = CliRunner().invoke(app, ["sweep", "delta_p1=0.5..3:log", "--config", str(fig6), "--n", "3", "--horizon", "6",
                                   "--out", str(tmp_path), "--quiet"])
    assert res.exit_code == 0, res.output
    (folder,) = tmp_path.iterdir()
    written = pd.read_csv(folder / "metrics.csv")
    for given in (fig6, mb.load(fig6)):
        swept = mb.sweep(given, "delta_p1=0.5..3:log", n=3, horizon=6).metrics
        both = written.merge(swept, on=["variant", "seed", "signal", "metric"], suffixes=("_cli", "_api"),
                             validate="one_to_one")
        assert len(both) == len(written) == len(swept) and set(both["param_api"]) == {"delta_p1"}
        assert np.allclose(both["param_value_api"], both["param_value_cli"], rtol=1e-6, atol=0)
        assert np.allclose(both["value_api"], both["value_cli"], rtol=1e-6, atol=0)
    assert np.allclose(sorted(set(swept["param_value"])), [0.5, 0.5 * 6 ** 0.5, 3.0])
    torben = ROOT / "configs" / "torben_fig3.yaml"  # its claim compares k = 0.7 with k = 0, outside 0.5..1
    mixed = mb.sweep(mb.load(torben), ["k=0.5..1", "eps"], n=2, horizon=5, groups=["dgnss"]).metrics
    values = {p: sorted(set(v)) for p, v in mixed.groupby("param")["param_value"]}
    assert values == {"eps": [0.1, 10.0], "k": [0.5, 1.0]}


def test_sweep_refuses_what_the_command_refuses():
    config = ROOT / "configs" / "torben_fig3.yaml"
    for kwargs, error, message in [
        ({"n": 1}, ValueError, "n must be from 2 to 1000 points per parameter, not 1"),
        ({"n": 2.5}, ValueError, "not 2.5"),
        ({"horizon": float("nan")}, ValueError, "horizon must be a positive, finite number of seconds, not nan"),
        ({"params": ["k"], "grid": True}, ValueError, r"grid=True takes two different parameters, not \['k'\]"),
        ({"params": "nope"}, ConfigError, r"torben_fig3\.yaml: sweep\.params: unknown parameter\(s\) \['nope'\]"),
        ({"groups": ["x"]}, ConfigError, r"sweep\.groups: unknown group\(s\) \['x'\]"),
        ({"params": "k=-1..2:log"}, ConfigError, r"^k=-1\.\.2:log: bad range \(-1\.0, 2\.0\) for log spacing"),
        ({"params": "observer.nope=1..2"}, ConfigError,
         r"^observer\.nope=1\.\.2: 'observer\.nope' is not a setting of variant 'resetting'"),
        ({"params": "k=1..2..3"}, ConfigError, r"^params: k=1\.\.2\.\.3: expected a name of sweep\.params or KEY=LO"),
        ({"params": ["k=0..1", "k=1..2"]}, ConfigError, r"^params: k=1\.\.2: 'k' is swept twice"),
        ({"params": ["k=0..1", "k"]}, ConfigError, r"^params: parameter\(s\) \['k'\] given more than once"),
        ({"params": [3]}, TypeError, r"each of params is a name of sweep\.params or 'KEY=LO\.\.HI\[:log\]', not 3"),
    ]:
        with pytest.raises(error, match=message):
            mb.sweep(config, **kwargs)
    with pytest.raises(ConfigError, match=r"^bejarano_fig6: sweep: no 'sweep' section: give a parameter in place, "
                       r"sweep\(exp, 'KEY=LO\.\.HI'\), or load the experiment with one, sets="):
        mb.sweep(mb.load(ROOT / "configs" / "bejarano_fig6.yaml"))
    with pytest.raises(ConfigError, match=r"^horizon: 4 s: metric 'std' window \[5, 4\] s is empty"):
        mb.sweep(ROOT / "configs" / "cross_asv_table4.yaml", "world.position_noise_scale=0..1", n=2, horizon=4)
    with pytest.raises(TypeError, match="sweep\\(\\) takes an Experiment"):
        mb.sweep(3)
    fig6 = mb.load(ROOT / "configs" / "bejarano_fig6.yaml",  # a parameter the config has no section for
                   sets=["seeds=1", "sweep.params.dp={key: delta_p1, range: [0.5, 3]}"])
    assert sorted(set(mb.sweep(fig6, n=2, horizon=6).metrics["param_value"])) == [0.5, 3.0]


def test_compare_gives_the_table_the_command_prints():
    """``mb.compare``: the command's comparison as a DataFrame, nothing written; the same cells, numbers and
    verdicts as ``compare --format csv``, between two folders or two variants of one."""
    import io

    import pandas as pd

    table3 = ROOT / "results" / "bejarano_table3"
    for args, kwargs in [([str(table3), str(table3)], {}),
                         ([str(table3), "--variants", "liu_eps0.1", "proposed_d0.05", "--metric", "std"],
                          {"variants": ("liu_eps0.1", "proposed_d0.05"), "metrics": "std"})]:
        res = CliRunner().invoke(app, ["compare", *args, "--format", "csv"])
        assert res.exit_code in (0, 1), res.output
        printed = pd.read_csv(io.StringIO(res.output))
        table = mb.compare(table3, None if kwargs else table3, **kwargs)
        assert list(table.columns) == list(printed.columns) and len(table) == len(printed) >= 6
        assert list(table["verdict"]) == list(printed["verdict"]) and list(table["signal"]) == list(printed["signal"])
        assert np.allclose(table["candidate"], printed["candidate"], rtol=1e-12, equal_nan=True)
    assert set(table["verdict"]) == {"worse"} and set(table["variant"]) == {"proposed_d0.05 vs liu_eps0.1"}


def test_compare_refuses_what_the_command_refuses():
    results = ROOT / "results"
    for kwargs, error, message in [
        ({"candidate": results, "rtol": -1}, ValueError, r"^compare\(\): rtol/atol: tolerances must be non-negative"),
        ({"candidate": results, "interval": "x"}, ValueError, r"interval: 'bootstrap' or 't', not 'x'"),
        ({"candidate": results, "paired": False, "interval": "t"}, ValueError, r"paired=False always uses Welch's t"),
        ({}, ValueError, r"^compare\(\): missing a candidate \(or use variants=\(A, B\)\)$"),
        ({"candidate": results, "variants": ("a", "b")}, ValueError, r"give either a candidate or variants=\(A, B\)"),
        ({"variants": ("a", "a")}, ValueError, r"variants: A and B are both 'a'"),
        ({"variants": "ab"}, ValueError, r"variants is two variant names \(A, B\), not 'ab'"),
        ({"variants": ("liu_eps0.1", "zz")}, MarinebenchError, r"no variant 'zz' \(have: "),
        ({"candidate": ROOT / "reference" / "quick"}, MarinebenchError, r"mismatched configs for experiment"),
    ]:
        with pytest.raises(error, match=message):
            mb.compare(results, **kwargs)
