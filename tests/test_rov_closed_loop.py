"""Closed-loop ROV world through the engine (Tijjani groundwork): tracking, loads, INT, config rules."""

import numpy as np
import pytest
import yaml

from marinebench.errors import ConfigError
from marinebench.experiments.runner import run
from marinebench.loading import load_experiment
from marinebench.rov_scenario import RovScenario, RovWorld, min_jerk
from marinebench.sim.recorders import ControlEnergy

from .conftest import ROOT


def experiment(tmp_path, variants, *sets, metrics=None):
    doc = {"scenario": str(ROOT / "scenarios" / "rov_s1.yaml"), "seeds": 1, "variants": variants,
           "metrics": metrics or [{"kind": "rmse", "t_start": 0.0, "signals": ["depth", "yaw"]}, {"kind": "int"}]}
    path = tmp_path / "rov.yaml"
    path.write_text(yaml.safe_dump(doc))
    return load_experiment(path, list(sets))[0], path


def test_min_jerk_reference():
    pts = [(0.0, 0.0), (5.0, 1.0), (10.0, 1.0)]
    assert min_jerk(-1, pts) == (0.0, 0.0) and min_jerk(12, pts) == (1.0, 0.0)
    v, r = min_jerk(2.5, pts)
    assert v == pytest.approx(0.5) and r == pytest.approx(30 * 0.25 * 0.25 / 5)


def test_rise_tracks_s1_reference_in_closed_loop(tmp_path):
    exp, _ = experiment(tmp_path, [{"name": "rise", "controller": {"kind": "rise"}}])
    m = run(exp, traces=False).metrics.set_index(["signal", "metric"])["value"]
    assert m["depth", "rmse"] < 0.01 and m["yaw", "rmse"] < np.deg2rad(1.0)
    assert m["depth", "int"] > 0 and m["yaw", "int"] > 0


def test_payload_hangs_until_the_floor_and_pushes_act_in_their_window():
    sc = RovScenario(name="p", depth_ref=[(0, 0.0)], yaw_ref_deg=[(0, 0.0)], horizon=10,
                     payload={"weight_fraction": 0.04, "floor_depth": 0.25},
                     pushes=[{"t_start": 2.0, "duration": 0.5, "force": [70.0, 0.0]}])
    from marinebench.controllers.spec import ControllerSpec

    w = RovWorld(sc, 0, np.zeros(2, dtype=int), [(ControllerSpec(kind="rise"), [0, 1])])
    x = np.array([[0.1, 0, 0, 0], [0.3, 0, 0, 0]])
    f = w.loads(1.0, x)
    assert f[0, 0] == pytest.approx(0.04 * 28 * 9.81) and f[1, 0] == 0.0  # resting on the floor below 0.25 m
    assert w.loads(2.2, x)[1, 0] == pytest.approx(70.0) and w.loads(2.6, x)[1, 0] == 0.0


def test_control_energy_starts_when_the_reference_is_reached():
    rec = ControlEnergy(["depth"], ["tau_depth"], [0.01], 0.1)
    errors = [0.5, 0.2, 0.005, 0.3, 0.0]
    for k, e in enumerate(errors):
        rec.update(k, 0.1 * k, {"depth": np.array([0.0]), "tau_depth": np.array([2.0])}, {"depth": np.array([e])})
    assert rec.value["depth"][0] == pytest.approx(3 * 4.0 * 0.1)  # from the 3rd sample on, even if it leaves


def test_closed_loop_needs_controllers_and_estimation_needs_observers(tmp_path):
    from marinebench.loading import preflight

    exp, path = experiment(tmp_path, [{"name": "x", "controller": {"kind": "srise"}}])
    preflight(exp, path)
    bad, path = experiment(tmp_path, [{"name": "x", "controller": {"kind": "srise"}}])
    bad = bad.model_copy(update={"variants": [bad.variants[0].model_copy(update={"controller": None, "observer": {"kind": "liu_eso"}})]})
    with pytest.raises(ConfigError, match="needs a 'controller'"):
        preflight(bad, path)
    with pytest.raises(ConfigError, match="give an .observer. or a .controller."):
        experiment(tmp_path, [{"name": "x"}])



def test_cdo_feedback_rescues_srise_on_sampled_sensors(tmp_path):
    """Noise-free 50 ms depth / 40 ms attitude samples, 2 ms control, Table II gains read as kgf:
    S+RISE on the held samples loses the depth (metres of error); fed by the CDO it tracks within 1 cm."""
    variants = [{"name": "srise", "controller": {"kind": "srise", "output_scale": 9.81}},
                {"name": "cdo_srise", "controller": {"kind": "srise", "output_scale": 9.81, "feedback": "cdo"}}]
    sets = ["scenario.sensors.depth_noise=0", "scenario.sensors.yaw_noise_deg=0", "scenario.control_period=0.002"]
    exp, _ = experiment(tmp_path, variants, *sets)
    m = run(exp, traces=False).metrics.set_index(["variant", "signal", "metric"])["value"]
    assert m["srise", "depth", "rmse"] > 0.3
    assert m["cdo_srise", "depth", "rmse"] < 0.01 and m["cdo_srise", "yaw", "rmse"] < np.deg2rad(1.5)



def test_every_scenario_kind_shares_the_step_checks():
    from pydantic import ValidationError

    from marinebench.dp_scenario import DpScenario

    common = {"name": "x", "depth_ref": [(0, 0.0)], "yaw_ref_deg": [(0, 0.0)]}
    with pytest.raises(ValidationError, match="exceeds horizon"):
        RovScenario(**common, horizon=0.001, dt=0.002)
    with pytest.raises(ValidationError, match="horizon: 2e\\+06 s at dt=0.002 s is 1e\\+09 steps per run"):
        RovScenario(**common, horizon=2e6, dt=0.002)
    with pytest.raises(ValidationError, match="control_period: 0.003 s must be a multiple"):
        RovScenario(**common, horizon=1, control_period=0.003)
    with pytest.raises(ValidationError, match="sensors.ts: 0.07 s must be a multiple"):
        DpScenario(name="d", horizon=10, sensors={"ts": 0.07})
