"""A variant's ``world:`` (a sweep group's, a sweep's ``world.<key>``) may set any numeric setting of its world by its
dotted path (``waves.tp``, ``sensors.ts``), beside the per-run keys the world batches: such runs get a world of their
own, simulated as a batch apart (``runner.world_batches``) and merged as if run together."""

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from marinebench.cli import app
from marinebench.errors import ConfigError
from marinebench.experiments.runner import run, steps, world_batches
from marinebench.loading import load_checked
from marinebench.results.outputs import METRICS_FLOAT

from .conftest import ROOT

CONFIG = ROOT / "configs" / "torben_fig1.yaml"
SHORT = ["scenario.horizon=120", "seeds=2"]


def _load(*sets):
    return load_checked(CONFIG, [*SHORT, *sets])[0]


def _values(result, variant):
    m = result.metrics
    return m[m.variant == variant].set_index(["seed", "signal", "metric"])["value"].sort_index()


def test_a_variant_with_a_world_setting_runs_where_the_scenario_has_it_to_the_bit():
    """npo given Tp 8 s gives, to the bit, the NPO of an experiment whose scenario has Tp 8 s, while resetting, beside
    it in the scenario's world, gives what it gives without that variant's setting; the setting acts (npo moves)."""
    mixed = run(_load("variants[npo].world={waves.tp: 8, gnss_sigma: 0.5}"), traces=False)
    own = run(_load("scenario.waves.tp=8", "variants[npo].world={gnss_sigma: 0.5}"), traces=False)
    plain = run(_load("variants[npo].world={gnss_sigma: 0.5}"), traces=False)
    pd.testing.assert_series_equal(_values(mixed, "npo"), _values(own, "npo"))
    pd.testing.assert_series_equal(_values(mixed, "resetting"), _values(plain, "resetting"))
    assert (_values(mixed, "npo") != _values(plain, "npo")).any()
    assert list(mixed.run_variant) == [0, 0, 1, 1] and list(mixed.run_seed) == [0, 1, 0, 1]


def test_the_worlds_batches_and_their_traces_merge_as_one_run():
    """Two worlds, two batches, twice the steps of one; the figures' traces hold each variant's seed 0 from its own
    world, as its own run has them."""
    exp = _load("variants[resetting].world={sensors.ts: 2}")
    assert world_batches(exp) == [({}, [0]), ({"sensors.ts": 2.0}, [1])]
    assert steps(exp) == 2 * steps(_load())
    mixed = run(exp).trace_frame()
    alone = run(_load("scenario.sensors.ts=2")).trace_frame()
    pick = [(f[f.variant == "resetting"].drop(columns="scenario").reset_index(drop=True)) for f in (mixed, alone)]
    pd.testing.assert_frame_equal(*pick)
    assert set(mixed.variant) == {"npo", "resetting"} and set(mixed.seed) == {0}


@pytest.mark.parametrize("world, expected", [
    ("{waves.tp: -1}", "variants.0.world.waves.tp: Input should be greater than 0"),
    ("{sensors.ts: 1.01}", "variants.0.world.sensors.ts: 1.01 s must be a multiple of dt=0.05 s (one step or more)"),
    ("{waves.n_components: 20.5}", ("variants.0.world.waves.n_components: Input should be a valid integer, got a number "
                                   "with a fractional part")),
    ("{waves.tpp: 3}", "variants.0.world: unknown world keys ['waves.tpp'] (did you mean waves.tp?)"),
    ("{horizon: 10}", ("variants.0.world: unknown world keys ['horizon'] (per run: ['gnss_sigma', 'heading_sigma_deg', "
                      "'gm_time_constant', 'hs'], or a setting of the world by its dotted path, e.g. sensors.<key>; "
                      "horizon and dt are every run's)")),
    ("{waves.rao: 1}", "variants.0.world.waves.rao: Input should be a valid tuple"),  # a list, not a number
    ("{name: calm}", "variants.0.world: unknown world keys ['name'] (per run: "),  # the world's name stays its own
    ("{kind: rov_tracking}", "variants.0.world: unknown world keys ['kind'] (per run: "),
    ("{sensors.hold: held}", "variants.0.world.sensors.hold: Input should be 'noise' or 'measurement'"),
    ("{gnss_sigma: loud}", "variants.0.world.gnss_sigma: Input should be a number (a per-run key), not 'loud'"),
    ("{hs: true}", "variants.0.world.hs: Input should be a number, not a boolean (YAML reads an unquoted true, "),
    ("{waves.tp: on}", "variants.0.world.waves.tp: Input should be a number, not a boolean (YAML reads an unquoted "),
    ("{sensors.notch: 1}", "variants.0.world.sensors.notch: Input should be true or false, not a number"),
    ("{waves.rao: [0.2, yes, 0.01]}", "variants.0.world.waves.rao.1: Input should be a number, not a boolean"),
    ("{waves: null, waves.tp: 8}", ("variants.0.world.waves.tp: inside waves, which these settings set too (give one "
                                    "or the other)")),
    ("{waves.tp: 8, waves: null}", "variants.0.world.waves.tp: inside waves, which these settings set too"),
    # a world that builds but cannot run: found at validation, in the variant's own world
    ("{waves.gamma: 1e300}", ("variants.0.world: the world cannot be run from these values (not finite at t = 0: its "
                             "measurement)")),
])
def test_a_world_setting_is_checked_as_the_files_own(world, expected):
    with pytest.raises(ConfigError) as err:
        _load(f"variants[npo].world={world}")
    assert str(err.value).startswith(f"--set: {expected}")


def test_a_setting_in_a_section_the_scenario_sets_to_null_says_so():
    with pytest.raises(ConfigError) as err:
        _load("scenario.waves=null", "variants[npo].world={waves.tp: 8}")
    assert str(err.value) == "--set: variants.0.world.waves.tp: not a setting of this world, whose waves is null"


@pytest.mark.parametrize("sets", [
    ["variants[npo].world={waves: {tp: 8}}"],  # nested, as a scenario file writes it
    ["variants[npo].world.waves.tp=8"],  # --set's own dotted path: the same key
    ["variants[npo].world={waves.tp: 5}", "variants[npo].world.waves.tp=8"],  # --set replaces the file's dotted key
    ["variants[npo].world={waves: {tp: 5}}", "variants[npo].world.waves.tp=8"],  # ... and its nested one
])
def test_a_world_setting_may_be_nested_or_set_by_its_dotted_path(sets):
    exp = _load(*sets)
    assert exp.variants[0].world == {"waves.tp": 8.0}
    assert world_batches(exp) == [({"waves.tp": 8.0}, [0]), ({}, [1])]


def test_a_sweep_groups_world_may_be_nested():
    exp = _load("sweep.groups={calm: {hs: 0.5, waves: {tp: 5}}}")
    assert exp.sweep.groups == {"calm": {"hs": 0.5, "waves.tp": 5.0}}


@pytest.mark.parametrize("world, expected", [
    ("{waves: {tp: 8}, waves.tp: 3}", "variants.0.world: 'waves.tp' is given twice (as a dotted key and inside a mapping)"),
    ("{waves: {tpp: 8}}", "variants.0.world: unknown world keys ['waves.tpp'] (did you mean waves.tp?)"),
    ("{waves: {}}", "variants.0.world: 'waves': an empty mapping sets nothing (give its keys, e.g. waves: {<key>: <value>})"),
])
def test_a_nested_world_setting_is_checked_by_its_dotted_path(world, expected):
    with pytest.raises(ConfigError) as err:
        _load(f"variants[npo].world={world}")
    assert str(err.value).startswith(f"--set: {expected}")


def test_a_sweep_of_a_world_setting_runs_each_point_in_its_world(tmp_path):
    """`sweep world.waves.tp=5..8`: a point's runs are those of the scenario with that Tp (to the bit); the variant's
    own value, the one the figure marks, is the scenario's 6.3 s."""
    res = CliRunner().invoke(app, ["sweep", "--config", str(CONFIG), "world.waves.tp=5..8", "--n", "2", "--horizon",
                                   "120", "--seeds", "2", "--out", str(tmp_path), "--quiet"])
    assert res.exit_code == 0, res.output
    (folder,) = tmp_path.iterdir()
    m = pd.read_csv(folder / "metrics.csv")
    at8 = m[(m.param_value == 8.0) & (m.metric == "J_tot")].set_index("seed")["value"].sort_index()
    own = run(_load("scenario.waves.tp=8"), traces=False).metrics
    want = own[(own.variant == "resetting") & (own.metric == "J_tot")].set_index("seed")["value"].sort_index()
    np.testing.assert_array_equal(at8.to_numpy(), [float(METRICS_FLOAT % v) for v in want])  # as metrics.csv writes it
    assert m[m.metric == "J_tot"].groupby("param_value")["value"].mean().nunique() == 2
    from marinebench.experiments.settings import tuning
    from marinebench.loading import load_experiment

    swept, _ = load_experiment(folder / "config.resolved.yaml")
    assert tuning(swept, "tp") == pytest.approx(6.3)


def test_a_worlds_own_design_is_kept_for_each_world():
    """An ROV world's CDO design (``world_cdo``) under its key for the scenario's world, and under the settings' for
    a variant's world that changes it; S3, where only that variant runs, has the latter alone."""
    exp = load_checked(ROOT / "configs" / "tijjani_table3.yaml",
                       ["variants[cdo_srise].world={cdo: {theta: 3}}", "seeds=1", "scenarios.*.horizon=0.5"])[0]
    designs = run(exp, traces=False).designs
    assert designs["S1"]["world_cdo (cdo.theta=3)"]["theta"] == 3.0
    assert designs["S1"]["world_cdo"]["theta"] == exp.scenarios["S1"].cdo.theta != 3.0
    assert [k for k in designs["S3"] if k.startswith("world_cdo")] == ["world_cdo (cdo.theta=3)"]


@pytest.mark.parametrize("world, scenario", [
    ("{sensors: {hold: measurement, notch: false}}", ["scenario.sensors.hold=measurement", "scenario.sensors.notch=false"]),
    ("{design_vessel: null}", ["scenario.design_vessel=null"]),  # the observers on the plant's model: no mismatch
    ("{waves: null}", ["scenario.waves=null"]),  # calm water
])
def test_a_variant_may_switch_a_worlds_text_switch_or_section(world, scenario):
    """Any setting of the world, not only a number, by its path: npo with it gives, to the bit, the NPO of the
    scenario with it, and the variant's line under the table names it."""
    exp = _load(f"variants[npo].world={world}")
    mixed = run(exp, traces=False)
    own = run(_load(*scenario), traces=False)
    pd.testing.assert_series_equal(_values(mixed, "npo"), _values(own, "npo"))
    assert (_values(mixed, "npo") != _values(run(_load(), traces=False), "npo")).any()
    from marinebench.results.tables import markdown_table

    (line,) = [x for x in markdown_table(exp, mixed.summary).splitlines() if x.startswith("- `npo`")]
    assert "; world: " in line and line.endswith(", ".join(f"{k}={v}" for k, v in exp.variants[0].world.items()))


def test_design_and_the_manifest_give_a_variants_design_on_its_own_world():
    """npo with `design_vessel: null` is designed on the plant's model: `marinebench design` prints, and the run
    records, the design of a config whose scenario has it, while resetting keeps the scenario's."""
    import json

    from marinebench.experiments.runner import design_summary

    sets = ["--set", "variants[npo].world={design_vessel: null}"]
    res = CliRunner().invoke(app, ["design", str(CONFIG), "--json", *sets])
    assert res.exit_code == 0, res.output
    shown = json.loads(res.output)["torben_fig1"]
    plain = json.loads(json.dumps(design_summary(_load("scenario.design_vessel=null")), default=float))
    mismatched = json.loads(json.dumps(design_summary(_load()), default=float))
    assert shown["npo"] == plain["npo"] != mismatched["npo"] and shown["resetting"] == mismatched["resetting"]
    recorded = json.loads(json.dumps(run(_load(sets[1]), traces=False).designs, default=float))
    assert recorded == shown
