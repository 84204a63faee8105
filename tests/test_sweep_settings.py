"""Sweeps of any setting of a variant: controller gains, the ROV observers' settings and per-run world keys, and one
scenario of a multi-scenario experiment."""

import json

import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from marinebench.cli import app
from marinebench.errors import ConfigError
from marinebench.experiments.runner import run
from marinebench.experiments.settings import MISSING, put_setting, setting_at, setting_path
from marinebench.experiments.sweep import sweep_experiment
from marinebench.loading import load_checked, load_experiment
from marinebench.preflight import preflight

from .conftest import ROOT

OBSERVERS = ROOT / "configs" / "tijjani_observers.yaml"
TABLE3 = ROOT / "configs" / "tijjani_table3.yaml"


def test_a_sweep_key_is_a_path_in_the_variants_settings():
    assert setting_path("k") == ["observer", "k"]  # a bare key is an observer field
    assert setting_path("controller.yaw.alpha") == ["controller", "yaw", "alpha"]
    settings = {"observer": {"k": 0.5}, "controller": {"yaw": {}}}
    assert setting_at(settings, ["observer", "k"]) == 0.5
    assert setting_at(settings, ["observer", "eps"]) is MISSING
    assert setting_at(settings, ["observer", "k", "x"]) is MISSING  # below a number
    assert setting_at(settings, ["controller", "yaw", "alpha"]) is None  # a declared mapping's key, not set yet
    put_setting(settings, ["world", "gnss_sigma"], 1.5)
    put_setting(settings, ["controller", "yaw", "alpha"], 2.0)
    assert settings == {"observer": {"k": 0.5}, "controller": {"yaw": {"alpha": 2.0}}, "world": {"gnss_sigma": 1.5}}


def test_sweep_points_set_the_swept_gain_and_keep_the_rest_of_the_variant():
    base, _ = load_experiment(TABLE3)
    exp = sweep_experiment(base, ["yaw_alpha"], None, 3, 2.0, TABLE3)
    assert exp.scenarios is None and exp.scenario.name == "S1"  # the sweep's scenario of the study
    source = next(v for v in base.variants if v.name == "srise").controller
    assert [v.controller.yaw["alpha"] for v in exp.variants] == pytest.approx(np.geomspace(0.5, 20.0, 3))
    assert all(v.controller.model_copy(update={"yaw": {}}) == source for v in exp.variants)
    assert [v.controller.gains()[1].alpha for v in exp.variants] == pytest.approx(np.geomspace(0.5, 20.0, 3))


def test_sweep_points_keep_the_variants_own_world_settings_under_the_groups():
    """A swept variant's per-run world settings carry over to its points; a world group's settings win over them."""
    fig3 = ROOT / "configs" / "torben_fig3.yaml"
    base, _ = load_experiment(fig3, ["variants[resetting].world={gnss_sigma: 0.5, heading_sigma_deg: 0.1}"])
    exp = sweep_experiment(base, ["k"], None, 2, 10.0, fig3)
    groups = base.sweep.groups
    assert {v.tags["gnss"] for v in exp.variants} == set(groups)
    for v in exp.variants:
        assert v.world == {"heading_sigma_deg": 0.1, **groups[v.tags["gnss"]]}


def _metrics(config, *sets):
    exp, _ = load_experiment(config, ["scenario.horizon=6", "seeds=1", "figures=[]", *sets])
    return run(exp, traces=False).metrics.set_index(["variant", "signal", "metric"])["value"].sort_index()


def test_a_variants_cdo_setting_acts_on_its_runs_only():
    """{lmi_decay: 0.2} on the cdo variant gives exactly what scenario.cdo.lmi_decay = 0.2 gives it, while the
    other variant of the same batch keeps the scenario's CDO."""
    per_variant = _metrics(OBSERVERS, "variants[cdo].observer.cdo={lmi_decay: 0.2}")
    in_world = _metrics(OBSERVERS, "scenario.cdo.lmi_decay=0.2")
    default = _metrics(OBSERVERS)
    np.testing.assert_array_equal(per_variant.loc["cdo"], in_world.loc["cdo"])
    np.testing.assert_array_equal(per_variant.loc["eo"], default.loc["eo"])
    assert not np.allclose(per_variant.loc["cdo"], default.loc["cdo"])


def test_a_variants_rov_world_settings_act_on_its_runs_only():
    """Where the estimates start and the sensor noise, set per run in the cdo variant's world:, give exactly what the
    same values in the scenario give it, while the eo variant of the same batch keeps the scenario's."""
    world = "variants[cdo].world={estimate_offset_depth: 0.02, estimate_offset_yaw_deg: 3.0, yaw_noise_deg: 0.05}"
    per_variant = _metrics(OBSERVERS, world)
    in_world = _metrics(OBSERVERS, "scenario.estimate_offset=[0.02, 3.0]", "scenario.sensors.yaw_noise_deg=0.05")
    default = _metrics(OBSERVERS)
    np.testing.assert_array_equal(per_variant.loc["cdo"], in_world.loc["cdo"])
    np.testing.assert_array_equal(per_variant.loc["eo"], default.loc["eo"])
    assert not np.allclose(per_variant.loc["cdo"], default.loc["cdo"])


def test_sweeps_of_per_run_world_keys_set_each_points_world():
    """``world.<key>`` sweep parameters: each point's world: holds its value over the variant's own settings; the
    manifest's line on where the estimates start says that the runs set it."""
    base, _ = load_experiment(OBSERVERS, ["sweep.params.theta.key=world.estimate_offset_yaw_deg",
                                          "sweep.params.theta.fixed={world.depth_noise: 0.001}",
                                          "variants[cdo].world={gyro_noise_dps: 0.1}"])
    exp = sweep_experiment(base, ["theta"], None, 3, 6.0, OBSERVERS)
    assert [v.world for v in exp.variants] == [{"gyro_noise_dps": 0.1, "depth_noise": 0.001, "estimate_offset_yaw_deg": x}
                                               for x in np.geomspace(8.0, 50.0, 3)]
    result = run(exp, traces=False)
    yaw_cdo = result.metrics.query("metric == 'rmse_each' and signal == 'yaw_cdo'").groupby("variant")["value"].mean()
    assert yaw_cdo.is_monotonic_increasing  # the further the estimates start, the larger the error over the run
    from marinebench.results.outputs import model_assumptions

    (start,) = [a for a in model_assumptions({"": exp.scenario}, exp.variants) if "estimates start" in a]
    assert start.endswith("except in the runs whose variant's world: sets estimate_offset_yaw_deg")
    assert not any("except" in a for a in model_assumptions({"": base.scenario}, base.variants))


def test_the_asv_position_noise_scales_per_run():
    """``position_noise_scale`` 0 on the noisy world gives exactly its noise-free twin (the same excitation), 1 exactly
    the default; a scale on a world without noise, or a negative one, is refused at the variant's key."""
    fig45 = ROOT / "configs" / "bejarano_fig4_5.yaml"
    sets = ["scenarios.noisy.horizon=8", "scenarios.noise_free.horizon=8", "seeds=2", "figures=[]", "claims=[]"]

    def std(*more):
        exp, _ = load_experiment(fig45, [*sets, *more])
        m = run(exp, traces=False).metrics
        return m[m.variant == "proposed_dp3"].set_index(["scenario", "seed", "signal"])["value"].sort_index()

    default = std()
    silent = std("variants[proposed_dp3].world={position_noise_scale: 0.0}", "variants[proposed_dp3].scenarios=[noisy]")
    np.testing.assert_array_equal(silent.loc["noisy"], default.loc["noise_free"])
    once = std("variants[proposed_dp3].world={position_noise_scale: 1.0}")
    np.testing.assert_array_equal(once, default)
    with pytest.raises(ConfigError, match=r"variants\.1\.world\.position_noise_scale: scenario 'noise_free' has no "
                                          r"position noise to scale \(its sensors\.position_noise is none\)"):
        load_checked(fig45, [*sets, "variants[proposed_dp3].world={position_noise_scale: 2.0}"])
    with pytest.raises(ConfigError, match=r"variants\.1\.world\.position_noise_scale: Input should be greater than or "
                                          r"equal to 0"):
        load_checked(fig45, [*sets, "variants[proposed_dp3].world={position_noise_scale: -1.0}",
                             "variants[proposed_dp3].scenarios=[noisy]"])


def test_a_world_key_swept_in_one_group_replaces_the_groups_value():
    """Torben's GNSS groups set gnss_sigma: swept in one group (--groups dgnss), the swept value replaces the group's."""
    fig3 = ROOT / "configs" / "torben_fig3.yaml"
    base, _ = load_experiment(fig3, ["sweep.params.k.key=world.gnss_sigma"])
    exp = sweep_experiment(base, ["k"], ["dgnss"], 3, 10.0, fig3)
    assert [v.world["gnss_sigma"] for v in exp.variants] == [0.0, 0.5, 1.0]
    assert {v.tags["gnss"] for v in exp.variants} == {"dgnss"}


def test_groups_is_the_gnss_options_other_name(tmp_path):
    """`--groups` names the world groups as `--gnss` does (the folder and the runs are the same)."""
    for option in ("--gnss", "--groups"):
        res = CliRunner().invoke(app, ["sweep", "k", "--config", str(ROOT / "configs" / "torben_fig3.yaml"), option, "dgnss",
                                       "--n", "2", "--horizon", "20", "--out", str(tmp_path / option), "--quiet"])
        assert res.exit_code == 0, res.output
    a, b = (tmp_path / o / "torben_fig3_sweep_k_dgnss_n2_20s" / "metrics.csv" for o in ("--gnss", "--groups"))
    assert a.read_text() == b.read_text()


def test_bad_world_sweep_keys_are_config_errors():
    def refused(config, sets, param, match):
        base, _ = load_experiment(config, sets)
        with pytest.raises(ConfigError, match=match):
            sweep_experiment(base, [param], None, 2, 10.0, config)

    refused(OBSERVERS, ["sweep.params.theta.key=world.gnss_sigma"], "theta",
            r"sweep\.params\.theta\.key: 'world\.gnss_sigma' is neither a per-run world key \(its per-run keys: "
            r"estimate_offset_depth, estimate_offset_yaw_deg, depth_noise, yaw_noise_deg, gyro_noise_dps, damping_scale, "
            r"buoyancy_scale\) nor a numeric setting of the world by its dotted path \(e\.g\. world\.sensors\.<key>; "
            r"horizon and dt are every run's\)")
    refused(OBSERVERS, ["sweep.params.theta.key=world.depth_noise", "sweep.params.theta.range=[-0.001, 0.001]",
                        "sweep.params.theta.spacing=linear", "sweep.params.theta.probes=[]"], "theta",
            r"sweep\.params\.theta: theta=-0\.001: Input should be greater than or equal to 0")
    fig3 = ROOT / "configs" / "torben_fig3.yaml"
    refused(fig3, ["sweep.params.k.key=world.gnss_sigma"], "k",
            r"sweep\.params\.k\.key: 'world\.gnss_sigma' is also set by world group\(s\) \['dgnss', 'dualband'\], which "
            r"would not differ in it: sweep it in one group \(--groups NAME\)")
    table4 = ROOT / "configs" / "bejarano_table4.yaml"
    refused(table4, ["sweep.params.k_omega.key=world.gnss_sigma"], "k_omega",
            r"sweep\.params\.k_omega\.key: 'world\.gnss_sigma' is neither a per-run world key \(its per-run keys: "
            r"position_noise_scale\) nor a numeric setting")
    refused(table4, ["sweep.params.k_omega.key=world.horizon"], "k_omega",  # a setting, but every run's
            r"'world\.horizon' is neither a per-run world key .* horizon and dt are every run's\)")


def test_bad_sweep_and_observer_settings_are_config_errors():
    with pytest.raises(ConfigError, match=r"variants\.0\.observer.*cdo: unknown key\(s\) \['mu'\]"):
        load_experiment(OBSERVERS, ["variants[cdo].observer.cdo={mu: 0.2}"])
    unstable, _ = load_experiment(OBSERVERS, ["variants[cdo].observer.cdo={lmi_decay: 1.5}"])
    with pytest.raises(ConfigError, match=r"variants\.0\.observer\.cdo: CDO depth: the per-sample error map has spectral"):
        preflight(unstable, OBSERVERS)
    base, _ = load_experiment(OBSERVERS, ["sweep.params.theta.key=observer.cdo_theta"])
    with pytest.raises(ConfigError, match=r"sweep\.params\.theta\.key: 'observer\.cdo_theta' is not a setting of variant 'cdo'"):
        sweep_experiment(base, ["theta"], None, 2, 1.0, OBSERVERS)
    base, _ = load_experiment(TABLE3, ["sweep.params.yaw_k0.key=controller.yaw.kzero"])
    with pytest.raises(ConfigError, match=r"sweep\.params\.yaw_k0: .*unknown srise gain\(s\) \['kzero'\]"):
        sweep_experiment(base, ["yaw_k0"], None, 2, 1.0, TABLE3)
    with pytest.raises(ConfigError, match=r"sweep\.scenario: unknown scenario 'S9'"):
        load_experiment(TABLE3, ["sweep.scenario=S9"])
    with pytest.raises(ConfigError, match=r"sweep\.variant: 'srise' does not run on scenario 'S3'"):
        load_experiment(TABLE3, ["sweep.scenario=S3"])


def test_cli_sweeps_a_rov_observer_setting(tmp_path):
    res = CliRunner().invoke(app, ["sweep", "lmi_decay", "--config", str(OBSERVERS), "--n", "2", "--horizon", "6",
                                   "--seeds", "1", "--out", str(tmp_path), "--quiet"])
    assert res.exit_code == 0, res.output
    m = pd.read_csv(tmp_path / "tijjani_observers_sweep_lmi_decay_n2_6s" / "metrics.csv")
    cdo = m[(m["metric"] == "rmse_each") & (m["signal"] == "depth_cdo")].sort_values("param_value")
    assert cdo["param_value"].tolist() == pytest.approx([0.05, 1.0])
    assert cdo["value"].iloc[0] != cdo["value"].iloc[1]
    assert (tmp_path / "tijjani_observers_sweep_lmi_decay_n2_6s" / "figures" / "sweep.png").exists()


def test_sweep_applies_a_profile_and_names_it_in_the_folder(tmp_path):
    """`sweep --profile NAME`, as `run` and `validate` take it (before: no such option): the profile's settings are
    applied, and the folder is named after it, so that a quick sweep does not replace the full one's."""
    config = tmp_path / "observers.yaml"
    config.write_text(yaml.safe_dump({"from": str(OBSERVERS), "profiles": {"short": ["seeds=1", "scenario.horizon=6"]}}))
    args = ["sweep", "lmi_decay", "--config", str(config), "--n", "2", "--out", str(tmp_path / "o"), "--quiet"]
    res = CliRunner().invoke(app, [*args, "--profile", "short"])
    assert res.exit_code == 0, res.output
    folder = tmp_path / "o" / "observers_sweep_lmi_decay_n2_profile=short"
    manifest = json.loads((folder / "manifest.json").read_text())
    assert (manifest["profile"], manifest["horizon"], manifest["seeds"]) == ("short", 6.0, 1)
    res = CliRunner().invoke(app, [*args, "--profile", "nope"])
    assert res.exit_code == 2 and res.output.strip() == f"error: {config}: profiles: no profile 'nope' (have: quick, short)"
    assert [p.name for p in (tmp_path / "o").iterdir()] == [folder.name]


@pytest.mark.parametrize("sets, expected", [
    (["sweep.params.theta.key=world.nope"], "sweep.params.theta.key: 'world.nope' is neither a per-run world key"),
    (["sweep.params.theta.key=observer.cdo_theta"], ("sweep.params.theta.key: 'observer.cdo_theta' is not a setting of "
                                                     "variant 'cdo'")),
    (["sweep.params.offset_yaw.key=world.yaw_noise_deg", "sweep.params.offset_yaw.range=[-1, 1]",
      "sweep.params.offset_yaw.probes=[]"], "sweep.params.offset_yaw: offset_yaw=-1: Input should be greater than or equal to 0"),
])
def test_validate_checks_the_sweep_section(sets, expected):
    """A sweep parameter that names no setting, or whose range leaves the setting's bounds, fails `validate` (and `run`),
    not only `sweep`."""
    res = CliRunner().invoke(app, ["validate", str(OBSERVERS), *[a for s in sets for a in ("--set", s)]])
    assert res.exit_code == 2 and res.output.startswith(f"error: --set: {expected}"), res.output
    assert len(res.output.strip().splitlines()) == 1


def test_a_sweep_of_another_variant_checks_only_the_parameters_it_sweeps(tmp_path):
    """With --set sweep.variant=rise, Table III's S+RISE gains name no RISE setting; sweeping only the world key
    added beside them still runs (validate, which checks every parameter, refuses the same config)."""
    sets = ["--set", "sweep.params.yaw_noise={key: world.yaw_noise_deg, range: [0.005, 0.2]}", "--set", "sweep.variant=rise"]
    res = CliRunner().invoke(app, ["sweep", "yaw_noise", "--config", str(TABLE3), "--n", "2", "--horizon", "4",
                                   "--seeds", "1", "--out", str(tmp_path), "--quiet", *sets])
    assert res.exit_code == 0, res.output
    res = CliRunner().invoke(app, ["validate", str(TABLE3), *sets])
    assert res.exit_code == 2 and "sweep.params.yaw_alpha: yaw_alpha=0.5: yaw: unknown rise gain(s) ['alpha']" in res.output


def test_compare_pairs_two_variants_sweeps_point_by_point(tmp_path):
    """docs/commands.md: one sweep per variant (--set sweep.variant) gives cells that compare pairs by point and seed."""
    for variant in ("cdo", "eo"):
        res = CliRunner().invoke(app, ["sweep", "offset_yaw", "--config", str(OBSERVERS), "--n", "2", "--horizon", "6",
                                       "--seeds", "2", "--set", f"sweep.variant={variant}", "--out", str(tmp_path / variant),
                                       "--quiet"])
        assert res.exit_code == 0, res.output
    (a,), (b,) = (list((tmp_path / v).iterdir()) for v in ("cdo", "eo"))
    res = CliRunner().invoke(app, ["compare", str(a), str(b), "--metric", "rmse", "--format", "json"])
    report = json.loads(res.output)
    assert report["paired"] and report["renamed"].startswith("Compared as one experiment")
    assert {c["variant"] for c in report["cells"]} == {"offset_yaw=0", "offset_yaw=10"}  # by point
    assert all(c["n"] == 2 and c["unpaired"] == 0 for c in report["cells"])
    assert any(c["verdict"] != "same" for c in report["cells"])  # the EO-fed loop differs from the CDO-fed one


def test_sweep_horizon_shorter_than_a_metric_window_is_one_line(tmp_path):
    res = CliRunner().invoke(app, ["sweep", "lmi_decay", "--config", str(OBSERVERS), "--n", "2", "--horizon", "3",
                                   "--out", str(tmp_path / "short"), "--quiet"])
    assert res.exit_code == 2 and len(res.output.strip().splitlines()) == 1, res.output
    assert "--horizon: 3 s: metric 'rmse_steady' window [5, 3] s is empty in a run of 3 s (" in res.output
    assert not (tmp_path / "short").exists()


def test_sweep_folder_names_keep_subsets_and_monte_carlo_sweeps_apart():
    """A sweep of some parameters or groups, with other points, another horizon or several seeds, must not
    replace the full one-seed sweep's folder; the config's own values add nothing to the name."""
    from marinebench.experiments.sweep import sweep_suffix

    exp, _ = load_experiment(ROOT / "configs" / "torben_fig3.yaml")
    every = ["k", "delta", "eps"]
    assert sweep_suffix(exp, ["eps", "k", "delta"]) == "_sweep"  # all, any order
    assert sweep_suffix(exp, every, ["dualband", "dgnss"], exp.sweep.n, exp.scenario.horizon) == "_sweep"
    assert sweep_suffix(exp, ["eps", "k"]) == "_sweep_k_eps"  # the config's order
    assert sweep_suffix(exp, ["k"], ["dgnss"], 21, 200.0) == "_sweep_k_dgnss_n21_200s"
    many = exp.model_copy(update={"seeds": 20})
    assert sweep_suffix(many, ["eps"]) == "_sweep_eps_20seeds"
    assert sweep_suffix(many, every) == "_sweep_20seeds"
    # --set and --seed are in the name as given (a probe on another world must not replace the reference)
    gm = ["scenario.sensors.gm_time_constant=100", "seed=7"]
    assert sweep_suffix(many, ["eps"], overrides=gm) == "_sweep_eps_scenario.sensors.gm_time_constant=100_seed=7_20seeds"
    assert sweep_suffix(exp, every, overrides=["variants[resetting].observer.eps=[0.1, 0.1, 0.01]"]) == \
        "_sweep_variants[resetting].observer.eps=0.1,0.1,0.01"
    assert sweep_suffix(exp, every, overrides=["scenario.events.0.force=[1e6, 0, 0]"]) != \
        sweep_suffix(exp, every, overrides=["scenario.events.1.force=[1e6, 0, 0]"])
    long = sweep_suffix(exp, every, overrides=[f"scenario.events.{i}.force=[1e6, 2e6, 3e7]" for i in range(3)])
    assert long.startswith("_sweep_set-") and len(long) == len("_sweep_set-") + 8
    assert long != sweep_suffix(exp, every, overrides=[f"scenario.events.{i}.force=[1e6, 2e6, 4e7]" for i in range(3)])


@pytest.mark.parametrize(("key", "value", "name"), [("sweep.params", '{"a/b": {key: k, range: [0, 1]}}', "a/b"),
                                                    ("sweep.groups", '{"x | y": {gnss_sigma: 0.1}}', "x | y")])
def test_sweep_parameter_and_group_names_are_names(key, value, name):
    """They name the sweep's points (variants 'name=value'), its folder and rows of its tables: 'a/b' or 'x | y' is
    refused at validation, naming the key; before, validate accepted them and the sweep failed on a point's name."""
    res = CliRunner().invoke(app, ["validate", str(ROOT / "configs" / "torben_fig3.yaml"), "--set", f"{key}={value}",
                                   "--set", "sweep.claims=[]"])
    assert res.exit_code == 2 and res.output.strip() == (
        f"error: --set: {key}: name '{name}': use letters, digits and _ . + - (it names the sweep's points and folder)")


@pytest.mark.parametrize(("config", "key", "value", "message"), [
    ("examples/first_experiment/asv_observers.yaml", "scenario.name", "a|b", "String should match pattern '^[A-Za-z0-9_.+-]+$'"),
    ("configs/tijjani_table3.yaml", "scenarios", '{"S|1": {from: ../scenarios/rov_s1.yaml}}',
     "name 'S|1': use letters, digits and _ . + - (it names the scenario in metrics.csv)")])
def test_a_scenarios_name_is_a_name_too(config, key, value, message):
    """A world's name (or a study's key, which names its scenario) fills metrics.csv's scenario column and the tables,
    as a variant's name does: held to the same pattern (before: any text)."""
    res = CliRunner().invoke(app, ["validate", str(ROOT / config), "--set", f"{key}={value}"])
    assert res.exit_code == 2 and res.output.strip() == f"error: --set: {key}: {message}", res.output
