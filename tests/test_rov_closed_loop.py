"""Closed-loop ROV world through the engine (Tijjani groundwork): tracking, loads, INT, config rules."""

import numpy as np
import pytest
import yaml

from marinebench.errors import ConfigError
from marinebench.experiments.runner import run
from marinebench.loading import load_checked, load_experiment
from marinebench.rov_scenario import Payload, Push, RandomLoad, RovScenario, RovSensors, RovWorld, min_jerk
from marinebench.sim.recorders import ControlEnergy

from .conftest import ROOT, accepts_and_refuses


def experiment(tmp_path, variants, *sets, metrics=None):
    doc = {"scenario": str(ROOT / "scenarios" / "rov_s1.yaml"), "seeds": 1, "variants": variants,
           "metrics": metrics or [{"kind": "rmse", "t_start": 0.0, "signals": ["depth", "yaw"]}, {"kind": "int"}]}
    path = tmp_path / "rov.yaml"
    path.write_text(yaml.safe_dump(doc))
    return load_experiment(path, list(sets))[0], path


def world_of(runs: int, observers=None, **scenario) -> RovWorld:
    """A Leonard-like world holding depth 0 and yaw 0 (the references never move), RISE on every run."""
    from marinebench.controllers.spec import ControllerSpec

    sc = RovScenario(name="w", depth_ref=[(0, 0.0)], yaw_ref_deg=[(0, 0.0)], horizon=10, **scenario)
    return RovWorld(sc, 0, np.zeros(runs, dtype=int), [(ControllerSpec(kind="rise"), list(range(runs)))], observers)


def test_min_jerk_reference():
    pts = [(0.0, 0.0), (5.0, 1.0), (10.0, 1.0)]
    assert min_jerk(-1, pts) == (0.0, 0.0) and min_jerk(12, pts) == (1.0, 0.0)
    v, r = min_jerk(2.5, pts)
    assert v == pytest.approx(0.5) and r == pytest.approx(30 * 0.25 * 0.25 / 5)


def test_min_jerk_holds_before_the_first_waypoint_and_between_moves():
    """Waypoints from t = 2 s: the first value is held until then; a waypoint that repeats its predecessor's value
    holds it; a later move starts from where the previous one ended (s = 1/4 of a 4 s move from 0.8 down to 0.2)."""
    pts = [(2.0, 0.5), (4.0, 0.8), (6.0, 0.8), (10.0, 0.2)]
    assert min_jerk(1.0, pts) == (0.5, 0.0) and min_jerk(2.0, pts) == (0.5, 0.0)
    assert min_jerk(5.0, pts) == (0.8, 0.0)
    v, r = min_jerk(7.0, pts)
    s = 0.25
    assert v == pytest.approx(0.8 - 0.6 * s**3 * (10 - 15 * s + 6 * s**2))
    assert r == pytest.approx(-0.6 * 30 * s**2 * (1 - s) ** 2 / 4)


@pytest.mark.parametrize("model, base, ok, bad", [
    (Push, {"t_start": 1.0, "duration": 0.5, "force": (10.0, 0.0)}, [{"t_start": 0.0}, {"t_start": 0.4}],
     [{"t_start": -0.1}, {"duration": 0.0}]),
    (Payload, {}, [{"weight_fraction": 0.5, "floor_depth": 0.1}], [{"weight_fraction": 0.0}, {"floor_depth": 0.0}]),
    (RandomLoad, {"std": (1.0, 0.1)}, [{"time_constant": 0.5, "period": 0.02}], [{"time_constant": 0.0}, {"period": 0.0}]),
    (RovSensors, {}, [{"depth_noise": 0.0, "yaw_noise_deg": 0.0, "gyro_noise_dps": 0.0, "depth_period": 0.02}],
     [{"depth_period": 0.0}, {"attitude_period": 0.0}, {"depth_noise": -1e-4}, {"yaw_rate": "imu"}]),
])
def test_rov_scenario_parts_refuse_out_of_range_values(model, base, ok, bad):
    """Times and periods start at or after 0 and are positive; noise may be switched off but not negative."""
    accepts_and_refuses(model, base, ok, bad)


def test_rise_tracks_s1_reference_in_closed_loop(tmp_path):
    exp, _ = experiment(tmp_path, [{"name": "rise", "controller": {"kind": "rise"}}])
    m = run(exp, traces=False).metrics.set_index(["signal", "metric"])["value"]
    assert m["depth", "rmse"] < 0.01 and m["yaw", "rmse"] < np.deg2rad(1.0)
    assert m["depth", "int"] > 0 and m["yaw", "int"] > 0


def test_a_thruster_lag_costs_rise_tracking_and_vanishes_as_it_shrinks(tmp_path):
    """End to end through the engine: RISE's S1 tracking error grows with the thrusters' lag and tends to the
    lag-free run's as the lag shrinks (12 s, one seed: RMSE 0.57 cm / 0.0028 rad without a lag, 0.57 cm / 0.0028
    rad at 1 ms, 8.6 cm / 0.068 rad at 0.3 s)."""
    def rmse(lag):
        exp, _ = experiment(tmp_path, [{"name": "rise", "controller": {"kind": "rise"}}], "scenario.horizon=12",
                            f"scenario.vessel.thrust_time_constant={lag}")
        return run(exp, traces=False).metrics.set_index(["signal", "metric"])["value"]

    none, tiny, slow = rmse(0.0), rmse(1e-3), rmse(0.3)
    for sig in ("depth", "yaw"):
        assert abs(tiny[sig, "rmse"] / none[sig, "rmse"] - 1) < 0.02
    assert slow["yaw", "rmse"] > 3 * none["yaw", "rmse"] and slow["depth", "rmse"] > 3 * none["depth", "rmse"]


def test_payload_hangs_until_the_floor_and_pushes_act_in_their_window():
    w = world_of(2, payload={"weight_fraction": 0.04, "floor_depth": 0.25},
                 pushes=[{"t_start": 2.0, "duration": 0.5, "force": [70.0, 0.0]}])
    x = np.array([[0.1, 0, 0, 0], [0.3, 0, 0, 0]])
    f = w.loads(1.0, x)
    assert f[0, 0] == pytest.approx(0.04 * 28 * 9.81) and f[1, 0] == 0.0  # resting on the floor below 0.25 m
    assert w.loads(2.2, x)[1, 0] == pytest.approx(70.0) and w.loads(2.6, x)[1, 0] == 0.0
    at_floor = np.array([[0.25, 0, 0, 0], [0.2499, 0, 0, 0]])
    assert w.loads(1.0, at_floor)[:, 0].tolist() == [0.0, pytest.approx(0.04 * 28 * 9.81)]  # rests from floor_depth on
    assert w.loads(2.0, x)[1, 0] == 70.0 and w.loads(2.5, x)[1, 0] == 0.0  # [t_start, t_start + duration)


def test_rov_defaults_are_table_i_and_the_documented_assumptions():
    """Sensor periods of Tijjani Table I (pressure sensor 50 ms, IMU 40 ms); S2-C1's payload of 4 % of the weight
    that lies on the pool floor from about 0.25 m (Sec. V); the assumed noise, rate sources, control period, step
    and unscaled plant of docs/tijjani.md; no loads unless a scenario adds them."""
    s = RovSensors()
    assert (s.depth_period, s.attitude_period) == (0.05, 0.04)
    assert (s.depth_noise, s.yaw_noise_deg, s.gyro_noise_dps) == (0.00024, 0.01, 0.05)
    assert (s.depth_rate, s.yaw_rate) == ("difference", "difference")
    assert (Payload().weight_fraction, Payload().floor_depth) == (0.04, 0.25)
    load = RandomLoad(std=(3.0, 0.2))
    assert (load.time_constant, load.period) == (2.0, 0.1)
    sc = RovScenario(name="w", depth_ref=[(0, 0.0)], yaw_ref_deg=[(0, 0.0)], horizon=10)
    assert (sc.control_period, sc.dt, sc.damping_scale, sc.buoyancy_scale) == (0.01, 0.002, 1.0, 1.0)
    assert sc.estimate_offset == (0.0, 0.0) and sc.payload is None and sc.pushes == [] and sc.random_load is None
    assert sc.sample_periods() == (("depth", 0.05), ("yaw", 0.04))


def test_world_starts_at_the_first_waypoints_with_the_observers_offset():
    """The plant starts at rest on the references' first values (yaw in degrees in the file); the CDO and the EO
    start at that pose plus ``estimate_offset`` [m, deg] with zero rate and disturbance estimates, the CDO's
    predictor and the held samples at the pose itself."""
    from marinebench.controllers.spec import ControllerSpec

    sc = RovScenario(name="w", depth_ref=[(0, 0.15), (5, 0.3)], yaw_ref_deg=[(0, 30.0)], horizon=10,
                     estimate_offset=(0.02, -3.0))
    w = RovWorld(sc, 0, np.zeros(2, dtype=int), [(ControllerSpec(kind="rise"), [0, 1])])
    pose = [0.15, np.deg2rad(30.0)]
    np.testing.assert_allclose(w.x0[:, :4], [[*pose, 0, 0]] * 2, rtol=1e-15)
    cdo, pred = w.cdo_view(w.x0)
    start = [[0.17, 0, 0], [np.deg2rad(27.0), 0, 0]]
    np.testing.assert_allclose(cdo, [start] * 2, rtol=1e-12)
    np.testing.assert_allclose(w.eo_view(w.x0), [start] * 2, rtol=1e-12)
    np.testing.assert_allclose(pred, [pose] * 2, rtol=1e-15)
    np.testing.assert_allclose(w.y, [pose] * 2, rtol=1e-15)
    np.testing.assert_allclose(w.at_sample[:3], [[pose] * 2] * 3, rtol=1e-15)


def test_thrust_follows_the_command_through_the_thrusters_first_order_lag():
    """``vessel.thrust_time_constant`` T: between control updates the thrust approaches the held command as
    1 - exp(-t/T) (T = 0: at once); the plant feels the thrust, the observers take the command."""
    w = world_of(1, vessel={"thrust_time_constant": 0.1})
    cmd = np.array([[10.0, -1.5]])
    w.tau_cmd, w.tau = cmd.copy(), np.zeros((1, 2))
    for k in range(1, 5):  # steps with no sample and no control update (dt 2 ms, control every 10 ms)
        w.begin_step(k, k * w.sc.dt, w.x0)
    np.testing.assert_allclose(w.tau, cmd * (1 - np.exp(-4 * w.sc.dt / 0.1)), rtol=1e-12)
    before = w.observers_derivative(w.x0)
    w.tau = w.tau + 3.0  # the thrust is not measured: the observers do not see it
    np.testing.assert_array_equal(w.observers_derivative(w.x0), before)
    w.tau_cmd = cmd + [[2.0, 0.5]]
    moved = w.observers_derivative(w.x0) - before  # only the rate rows of the CDO and the EO, by B (u' - u)
    want = np.zeros_like(moved)
    want[0, [1, 4, 9, 12]] = np.tile([2.0, 0.5] / w.m_hat, 2)
    np.testing.assert_allclose(moved, want, rtol=1e-9, atol=1e-12)
    instant = world_of(1)
    instant.tau_cmd = cmd.copy()
    instant.begin_step(1, instant.sc.dt, instant.x0)
    np.testing.assert_array_equal(instant.tau, cmd)


def test_the_plant_sees_the_scenarios_damping_and_buoyancy_scales():
    """S2-C2 changes the plant only: RovWorld's plant derivative is the model's with damping x damping_scale and
    net buoyancy x buoyancy_scale (the observers keep their nominal inertia)."""
    sc_kw = {"damping_scale": 1.9, "buoyancy_scale": 2.5, "vessel": {"net_buoyancy": 7.0}}
    w = world_of(1, **sc_kw)
    x = w.x0.copy()
    x[0, :4] = [0.2, 0.3, 0.1, -0.2]
    w.tau = np.array([[4.0, -0.5]])
    got = w.derivative(0.0, x)[0][0, :4]
    want = w.plant.derivative(x[:, :4], w.tau, w.loads(0.0, x), 1.9, 7.0 * 2.5)[0]
    np.testing.assert_allclose(got, want, rtol=1e-14)
    assert not np.allclose(got, w.plant.derivative(x[:, :4], w.tau, w.loads(0.0, x), 1.9, 7.0 / 2.5)[0])


def test_a_variants_plant_scales_hold_for_its_runs_only(tmp_path):
    """damping_scale and buoyancy_scale are per-run world keys (a variant's world:, a world.<key> robustness sweep):
    a run with S2-C2's 1.9 and 2.0 there is, to the bit, the run of a world that says so, beside a nominal run of the
    same batch; a multiplier the scenario's field would refuse is refused naming the variant's key."""
    rise = {"kind": "rise"}
    scales = {"damping_scale": 1.9, "buoyancy_scale": 2.0}
    exp, _ = experiment(tmp_path, [{"name": "nominal", "controller": rise},
                                   {"name": "mismatch", "controller": rise, "world": scales}], "scenario.horizon=6")
    world, _ = experiment(tmp_path, [{"name": "mismatch", "controller": rise}], "scenario.horizon=6",
                          *(f"scenario.{key}={value}" for key, value in scales.items()))
    both, alone = (run(e).metrics.set_index(["variant", "signal", "metric"])["value"] for e in (exp, world))
    assert both["mismatch"].to_dict() == alone["mismatch"].to_dict()
    assert both["nominal"]["depth"]["rmse"] != both["mismatch"]["depth"]["rmse"]
    _, path = experiment(tmp_path, [{"name": "bad", "controller": rise, "world": {"buoyancy_scale": 0.0}}])
    with pytest.raises(ConfigError, match=r"variants\.0\.world\.buoyancy_scale: Input should be greater than 0"):
        load_checked(path)


def test_cdo_and_eo_designs_report_their_gains_and_per_sample_figures():
    """``cdo_design``: K*, its source and, only for the LMI design, the decay rate, LMI (40)'s residual and the
    poles (theta times the normalised ones); per DOF the per-sample radius and noise gain. ``eo_design``: a/eps^i and
    a triple pole at -1/eps for a = (3, 3, 1)."""
    from marinebench.observers.cdo import CdoParams, EoParams

    sc = RovScenario(name="w", depth_ref=[(0, 0.0)], yaw_ref_deg=[(0, 0.0)], horizon=10)
    lmi = sc.cdo_design()
    assert lmi["mode"] == "lmi" and lmi["lmi_decay"] == 0.35 and lmi["lmi40_max_eig"] < 0
    assert max(lmi["poles"]) <= -0.35 * 24.39 + 1e-3
    # the real parts of the roots of s^3 + g1 s^2 + g2 s + g3, g = Delta_theta K* (the error dynamics of eq. (38))
    roots = np.roots([1.0, *CdoParams().injection()])
    np.testing.assert_allclose(lmi["poles"], np.sort(roots.real), atol=2e-3)
    binomial = sc.cdo_design(CdoParams(k_star="binomial", theta=10.0))
    assert binomial["k_star"] == [3.0, 3.0, 1.0] and binomial["mode"] == "binomial" and binomial["theta"] == 10.0
    assert not {"lmi_decay", "lmi40_max_eig", "poles"} & set(binomial)
    assert {"sampled_radius_depth", "sampled_radius_yaw", "noise_gain_depth", "noise_gain_yaw"} <= set(binomial)
    assert sc.cdo_design(CdoParams(k_star=(2.0, 1.5, 0.3)))["mode"] == "given"
    eo = sc.eo_design(EoParams(eps=0.05))
    assert eo["gain"] == [60.0, 1200.0, 8000.0]
    np.testing.assert_allclose(eo["poles"], [-20.0] * 3, atol=0.05)  # a triple root, to its numerical splitting
    assert {"noise_gain_depth", "noise_gain_yaw"} <= set(eo)
    # the defaults' per-sample figures at 50 ms quoted in docs/tijjani.md: the EO's held samples pass less noise
    assert sc.eo_design()["noise_gain_depth"] == pytest.approx(1.061, abs=1e-3)
    assert (lmi["sampled_radius_depth"], lmi["noise_gain_depth"]) == pytest.approx((0.778, 1.351), abs=1e-3)


def test_control_energy_starts_when_the_reference_is_reached():
    """From the first time the tracking error (the world's truth: reference ``depth_ref`` less ``depth``) is within
    tol; the estimate a run reports (an observer's, here far off) does not count."""
    rec = ControlEnergy(["depth"], ["tau_depth"], [0.01], 0.1)
    errors = [0.5, 0.2, 0.005, 0.3, 0.0]
    far = {"depth": np.array([9.0])}
    for k, e in enumerate(errors):
        truth = {"depth": np.array([0.0]), "depth_ref": np.array([e]), "tau_depth": np.array([2.0])}
        rec.update(k, 0.1 * k, truth, far)
    assert rec.value["depth"][0] == pytest.approx(3 * 4.0 * 0.1)  # from the 3rd sample on, even if it leaves
    at_tol = ControlEnergy(["depth"], ["tau_depth"], [0.25], 0.5)  # an error of exactly tol has reached it
    for k, e in enumerate([0.5, 0.25, 0.5]):  # at 1 m: the error is reference minus depth
        truth = {"depth": np.array([1.0]), "depth_ref": np.array([1.0 + e]), "tau_depth": np.array([2.0])}
        at_tol.update(k, 0.5 * k, truth, far)
    assert at_tol.value["depth"][0] == 2 * 4.0 * 0.5


def test_closed_loop_needs_controllers_and_estimation_needs_observers(tmp_path):
    from marinebench.preflight import preflight

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
    with pytest.raises(ValidationError, match="horizon\\|dt: 2e\\+06 s at dt=0.002 s is 1e\\+09 steps per run"):
        RovScenario(**common, horizon=2e6, dt=0.002)
    with pytest.raises(ValidationError, match="control_period: 0.003 s must be a multiple"):
        RovScenario(**common, horizon=1, control_period=0.003)
    with pytest.raises(ValidationError, match="sensors.ts: 0.07 s must be a multiple"):
        DpScenario(name="d", horizon=10, sensors={"ts": 0.07})


def test_cdo_and_its_inter_sample_predictor_follow_eq_38():
    """x_hat' = A x_hat + B u + Delta_theta K* (w - x_hat_1) and w' = x_hat_2 + K_w (w - x_hat_1), per DOF."""
    from marinebench.observers.cdo import RovObserverSpec

    w = world_of(1, [RovObserverSpec(kind="cdo")])
    x = w.x0.copy()
    cdo, pred = w.cdo_view(x)
    cdo[0] = [[0.10, 0.05, 0.2], [0.3, -0.1, 0.4]]  # [eta, eta_dot, delta*] for depth and yaw
    pred[0] = [0.12, 0.25]  # the predictors w, ahead of the estimates
    innovation = pred[0] - cdo[0, :, 0]
    d = w.observers_derivative(x)[0]
    d_cdo, d_w = d[:6].reshape(2, 3), d[6:8]
    gain = w.sc.cdo.injection()
    acc = w.tau[0] / w.m_hat
    np.testing.assert_allclose(d_w, cdo[0, :, 1] + w.sc.cdo.k_w * innovation, rtol=1e-12)
    np.testing.assert_allclose(d_cdo[:, 0], cdo[0, :, 1] + gain[0] * innovation, rtol=1e-12)
    np.testing.assert_allclose(d_cdo[:, 1], cdo[0, :, 2] + acc + gain[1] * innovation, rtol=1e-12)
    np.testing.assert_allclose(d_cdo[:, 2], gain[2] * innovation, rtol=1e-12)


def test_observation_error_at_the_samples_is_each_runs_own_observers():
    """``*_meas``: a CDO run compares the CDO's estimate just before the sample with the sample, an EO run the EO's."""
    from marinebench.observers.cdo import RovObserverSpec

    w = world_of(2, [RovObserverSpec(kind="cdo"), RovObserverSpec(kind="eo")], sensors={"depth_noise": 0.0,
                                                                                          "yaw_noise_deg": 0.0})
    x = w.x0.copy()
    w.cdo_view(x)[0][:, 0, 0] = 0.03  # the CDO's depth estimate in both runs
    w.eo_view(x)[:, 0, 0] = -0.02  # the EO's
    w.begin_step(0, 0.0, x)  # both sensors sample at k = 0
    est, truth = w.estimates(0.0, x), w.truth(0.0, x)
    np.testing.assert_array_equal(est["depth_meas"], [0.03, -0.02])
    np.testing.assert_array_equal(truth["depth_meas"], [0.0, 0.0])


def test_truth_and_estimates_name_the_state_columns_of_each_runs_observer():
    """State [z, psi, w, r | CDO (depth, yaw) x [eta, eta_dot, delta*] | predictors | EO (depth, yaw) x 3]: truth is
    the plant's pose and rates; the estimate of ``depth``/``yaw`` and their rates is the reference (no observer),
    the CDO's or the EO's, per run; ``*_cdo``/``*_eo`` are both observers' outputs in every run."""
    from marinebench.observers.cdo import RovObserverSpec

    w = world_of(3, [None, RovObserverSpec(kind="cdo"), RovObserverSpec(kind="eo")])
    x = np.tile(np.arange(18.0) + 0.5, (3, 1))
    truth, est = w.truth(0.0, x), w.estimates(0.0, x)
    for name, col in {"depth": 0, "yaw": 1, "depth_rate": 2, "yaw_rate": 3}.items():
        np.testing.assert_array_equal(truth[name], x[:, col])
    for name, cols in {"depth": (4, 12), "yaw": (7, 15), "depth_rate": (5, 13), "yaw_rate": (8, 16)}.items():
        assert est[name].tolist() == [0.0, *(x[0, c] for c in cols)]  # the references hold 0 at rest
    for name, col in {"depth_cdo": 4, "yaw_cdo": 7, "depth_eo": 12, "yaw_eo": 15}.items():
        np.testing.assert_array_equal(est[name], x[:, col])
        np.testing.assert_array_equal(truth[name], x[:, 0 if "depth" in name else 1])


def test_the_disturbance_is_the_acceleration_that_the_command_over_the_nominal_inertia_leaves():
    """``*_disturbance``: truth d = eta_ddot - tau_c / M_hat (the observers' model, eq. (38) x_3) from the plant's
    thrust (lagging the command), damping, net buoyancy and loads (a push); the estimate is x_hat_3 of the run's
    observer (none: NaN), ``*_disturbance_cdo`` / ``_eo`` both observers' in every run."""
    from marinebench.observers.cdo import RovObserverSpec

    w = world_of(3, [None, RovObserverSpec(kind="cdo"), RovObserverSpec(kind="eo")],
                 pushes=[{"t_start": 0.0, "duration": 1.0, "force": [5.0, -2.0]}])
    p, (m_z, i_r) = w.plant.p, w.plant.inertia
    x = np.tile(np.arange(18.0) + 0.5, (3, 1))
    x[:, 2:4] = [0.1, -0.2]  # heave and yaw rates
    w.tau, w.tau_cmd = np.array([[20.0, 1.0]] * 3), np.array([[25.0, 0.5]] * 3)
    truth, est = w.truth(0.5, x), w.estimates(0.5, x)
    heave = (20.0 - (p.d_heave_lin + p.d_heave_quad * 0.1) * 0.1 - p.net_buoyancy + 5.0) / m_z - 25.0 / m_z
    yaw = (1.0 + (p.d_yaw_lin + p.d_yaw_quad * 0.2) * 0.2 - 2.0) / i_r - 0.5 / i_r
    for suffix in ("", "_cdo", "_eo"):
        np.testing.assert_allclose(truth[f"depth_disturbance{suffix}"], heave, rtol=1e-12)
        np.testing.assert_allclose(truth[f"yaw_disturbance{suffix}"], yaw, rtol=1e-12)
    np.testing.assert_array_equal(est["depth_disturbance"], [np.nan, 6.5, 14.5])  # x_hat_3: columns 6 and 14
    np.testing.assert_array_equal(est["yaw_disturbance"], [np.nan, 9.5, 17.5])
    np.testing.assert_array_equal(est["depth_disturbance_cdo"], [6.5] * 3)
    np.testing.assert_array_equal(est["yaw_disturbance_eo"], [17.5] * 3)


def test_the_cdo_follows_the_payloads_disturbance_and_a_run_without_an_observer_has_no_such_rows(tmp_path):
    """S2-C1 (the payload hangs, then rests on the floor from 0.25 m): the CDO-S+RISE run's disturbance estimate
    follows the truth, its RMSE within half the truth's RMS after the first 2 s (0.26: the depth sensor's noise);
    the RISE run (no observer) reports no depth_disturbance, but the CDO it carries does (depth_disturbance_cdo)."""
    exp, _ = experiment(tmp_path, [
        {"name": "cdo_srise", "controller": {"kind": "srise", "feedback": "cdo", "disturbance_feedforward": True},
         "observer": {"kind": "cdo"}},
        {"name": "rise", "controller": {"kind": "rise"}}],
        f"scenario={{from: {ROOT / 'scenarios' / 'rov_s2_c1.yaml'}, horizon: 12}}",
        metrics=[{"kind": "rmse", "t_start": 2.0, "signals": ["depth_disturbance", "depth_disturbance_cdo"]}])
    res = run(exp)
    rows = res.metrics.set_index(["variant", "signal"])["value"]
    assert ("rise", "depth_disturbance") not in rows.index and ("rise", "depth_disturbance_cdo") in rows.index
    t, truth, _ = res.traces
    d = truth["depth_disturbance"][t >= 2.0, 0]
    assert d.max() - d.min() > 0.1  # m/s^2: the payload's 4 % of the weight, on and off
    assert rows["cdo_srise", "depth_disturbance"] < 0.5 * np.sqrt(np.mean(d**2))  # 0.26 (an estimate of 0: 1)


def test_the_disturbance_truth_is_computed_only_at_the_steps_something_reads_it(tmp_path, monkeypatch):
    """It costs a plant evaluation per step: computed once at each step of a run with a metric of it, at the traced
    steps of a run that traces it, and not at all otherwise (the truth is an ``OnDemand`` mapping that names it)."""
    calls = []
    original = RovWorld.disturbance
    monkeypatch.setattr(RovWorld, "disturbance", lambda self, t, x: calls.append(t) or original(self, t, x))
    variants = [{"name": "cdo", "controller": {"kind": "srise", "feedback": "cdo"}, "observer": {"kind": "cdo"}}]
    plain, _ = experiment(tmp_path, variants, "scenario.horizon=1")
    with_metric, _ = experiment(tmp_path, variants, "scenario.horizon=1", metrics=[
        {"kind": "rmse", "t_start": 0.0, "signals": ["depth", "depth_disturbance", "yaw_disturbance_eo"]}])
    n_steps = round(1 / plain.scenario.dt)
    run(plain, traces=False)
    assert calls == []
    run(with_metric, traces=False)
    assert len(calls) == n_steps + 1 == len(set(calls))
    calls.clear()
    run(plain, traces=True)
    assert len(calls) == round(1 / plain.engine.trace_dt) + 1


def test_a_controller_without_an_observer_is_scored_at_the_samples_on_the_reference():
    """``*_meas`` of a run seen through no observer: the reference at the sample instant against the sample, so
    a moving reference enters it (depth from 0.1 m to 0.3 m over 1 s, sampled at 0.5 s)."""
    from marinebench.controllers.spec import ControllerSpec

    sc = RovScenario(name="w", depth_ref=[(0, 0.1), (1, 0.3)], yaw_ref_deg=[(0, 0.0)], horizon=10,
                     sensors={"depth_noise": 0.0, "yaw_noise_deg": 0.0})
    w = RovWorld(sc, 0, np.zeros(1, dtype=int), [(ControllerSpec(kind="rise"), [0])])
    x = w.x0.copy()
    k = round(0.5 / sc.dt)
    w.begin_step(k, 0.5, x)
    assert w.estimates(0.5, x)["depth_meas"][0] == pytest.approx(min_jerk(0.5, sc.depth_ref)[0]) == 0.2
    assert w.truth(0.5, x)["depth_meas"][0] == 0.1  # the held sample of the plant, still at its start


def test_gyro_rate_is_the_true_rate_plus_the_gyros_noise():
    """``yaw_rate: gyro`` feeds the true rate plus white noise of ``gyro_noise_dps``; ``true`` the rate itself."""
    errors = {}
    for source in ("gyro", "true"):
        w = world_of(1, sensors={"yaw_rate": source, "gyro_noise_dps": 2.0})
        every = w.every[1]  # steps between attitude samples
        x = w.x0.copy()
        x[:, 3] = 0.3  # yaw rate
        errors[source] = []
        for k in range(0, 240 * every, every):  # 240 attitude samples over the 10 s horizon
            w.begin_step(k, k * w.sc.dt, x)
            errors[source].append(w.ydot[0, 1] - 0.3)
    assert np.std(errors["gyro"]) == pytest.approx(np.deg2rad(2.0), rel=0.15)
    assert np.all(np.array(errors["true"]) == 0.0)


def test_a_differenced_rate_starts_at_zero_at_the_first_sample():
    """``difference``: no rate before there are two samples, whatever the first sample's noise; then the
    difference of the last two samples over the sensor's period."""
    w = world_of(1, sensors={"depth_noise": 0.01, "yaw_noise_deg": 1.0})
    x = w.x0.copy()
    w.begin_step(0, 0.0, x)
    assert np.all(w.y != 0.0) and np.all(w.ydot == 0.0)
    first = w.y.copy()
    every = w.every[0]  # the depth sensor's steps; the IMU samples at other steps
    w.begin_step(every, every * w.sc.dt, x)
    assert w.ydot[0, 0] == pytest.approx((w.y[0, 0] - first[0, 0]) / 0.05, rel=1e-12) and w.ydot[0, 0] != 0.0
