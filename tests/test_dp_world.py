"""DP world and observers through the engine: events, KPI, NPO = resetting with k = 0, CLI run."""

import numpy as np
import pytest
import yaml
from pydantic import ValidationError
from typer.testing import CliRunner

from marinebench.cli import app
from marinebench.dp_scenario import DpScenario, DpWorld
from marinebench.errors import ConfigError
from marinebench.experiments.runner import DESIGNS_UP_TO, design_summary, make_observer, plant_of, run
from marinebench.loading import load_checked, load_experiment
from marinebench.observers.dp import ResettingTuning
from marinebench.sim.recorders import NormIntegral

from .conftest import ROOT, accepts_and_refuses

CONFIG = ROOT / "configs" / "torben_fig1.yaml"  # plant ShipX LF (model B), observers on model A
MATCHED = ROOT / "configs" / "torben_fig1_matched.yaml"  # plant = observers' model (model A)


def test_events_happen_at_configured_times():
    sc = DpScenario(name="e", horizon=100, events=[
        {"kind": "impulse", "t_start": 50, "duration": 10, "force": [0, 5e6, 0]},
        {"kind": "slow", "t_start": 20, "duration": 40, "rise": 10, "force": [1e5, 0, 0]}])
    w = DpWorld(sc, 0, np.zeros(1, dtype=int))
    assert w.events(49.99)[1] == 0 and w.events(50.0)[1] == 5e6 and w.events(59.99)[1] == 5e6 and w.events(60.0)[1] == 0
    assert w.events(20.0)[0] == 0 and np.isclose(w.events(30.0)[0], 1e5) and np.isclose(w.events(25.0)[0], 0.5e5)
    assert np.isclose(w.events(60.0)[0], 0)
    # a raised cosine, 0.5 (1 - cos(pi s)) of the rise fraction s, on the way up and (mirrored) on the way down
    quarter = 1e5 * 0.5 * (1 - np.cos(np.pi / 4))
    assert np.isclose(w.events(22.5)[0], quarter) and np.isclose(w.events(57.5)[0], quarter)


def test_truth_bias_is_the_drifting_bias_plus_the_events_load_in_ned():
    """KPI truth (module docstring): b_true = b + R(psi) tau_d, tau_d the body-frame events at t; the pose and
    velocity are the plant state's."""
    sc = DpScenario(name="e", horizon=100, waves=None, events=[
        {"kind": "impulse", "t_start": 5, "duration": 10, "force": [2e5, -3e5, 4e6]}])
    w = DpWorld(sc, 0, np.zeros(1, dtype=int))
    x = np.array([[1.0, 2.0, 0.6, 0.1, -0.2, 0.01, 1e4, -2e4, 3e5]])
    c, s_ = np.cos(0.6), np.sin(0.6)
    truth = w.truth(6.0, x)
    want = {"b_x": 1e4 + c * 2e5 + s_ * 3e5, "b_y": -2e4 + s_ * 2e5 - c * 3e5, "b_n": 3e5 + 4e6}
    for name, value in want.items():
        assert truth[name][0] == pytest.approx(value, rel=1e-12)
    assert [truth[n][0] for n in ("x", "y", "psi", "u", "v", "r")] == [1.0, 2.0, 0.6, 0.1, -0.2, 0.01]
    assert [w.truth(20.0, x)[n][0] for n in ("b_x", "b_y", "b_n")] == [1e4, -2e4, 3e5]  # after the impulse


@pytest.mark.parametrize("model, base, ok, bad", [
    ("Impulse", {"t_start": 1.0, "duration": 2.0, "force": (1.0, 0.0, 0.0)}, [{"t_start": 0.0}, {"t_start": 0.5}],
     [{"t_start": -1.0}, {"duration": 0.0}]),
    ("SlowLoad", {"t_start": 1.0, "duration": 2.0, "rise": 0.5, "force": (1.0, 0.0, 0.0)}, [{"t_start": 0.0}],
     [{"t_start": -1.0}, {"duration": 0.0}, {"rise": 0.0}]),
    ("Waves", {}, [{"hs": 0.0, "n_components": 1, "w_max_factor": 1.01, "rao_rolloff": 0.0}, {"n_components": 1000},
                   {"gamma": None, "tp": 0.5}],
     [{"hs": -0.1}, {"tp": 0.0}, {"gamma": 0.0}, {"n_components": 0}, {"n_components": 1001}, {"w_max_factor": 1.0},
      {"rao_rolloff": -1.0}]),
    ("DpSensors", {}, [{"gnss_sigma": 0.0, "heading_sigma_deg": 0.0, "ts": 0.5, "gm_time_constant": 0.5}],
     [{"gnss_sigma": -0.1}, {"heading_sigma_deg": -0.1}, {"gm_time_constant": 0.0}, {"ts": 0.0}, {"notch_w0": 0.0},
      {"notch_wc": 0.0}, {"hold": "sample"}]),
])
def test_dp_scenario_parts_refuse_out_of_range_values(model, base, ok, bad):
    """Event times from 0 and positive durations; a sea may be calm (hs = 0) and has 1 to 1000 components up to
    above its peak; noise may be off, never negative; time constants, sample times and notch frequencies positive."""
    import marinebench.dp_scenario as dp

    accepts_and_refuses(getattr(dp, model), base, ok, bad)


def measured(world: DpWorld, n_steps: int, pose=None) -> np.ndarray:
    """The measurement y after ``begin_step`` at each of the first ``n_steps`` steps, ``(n_steps, B, 3)``; the plant
    state is ``pose(t)`` (default: at rest at the origin)."""
    rest = np.zeros((len(world.x0), 9))
    ys = []
    for k in range(n_steps):
        t = k * world.sc.dt
        world.begin_step(k, t, rest if pose is None else pose(t))
        ys.append(world.y.copy())
    return np.array(ys)


def test_stationary_gauss_markov_reading():
    sc = DpScenario(name="n", horizon=10, waves=None, sensors={"gnss_sigma": 1.5, "sigma_is": "stationary"})
    w = DpWorld(sc, 0, np.arange(4000))
    assert abs(w.gm[:, 0].std() / 1.5 - 1) < 0.05  # starts in the stationary distribution
    # and stays in it: eq. (48)'s driving std sigma*sqrt(1 - exp(-2 c Ts)) keeps the variance (c Ts = 0.5 here, so
    # a wrong driving std shows within a few samples)
    for ts, tc in ((1.0, 2.0), (0.5, 1.0)):  # c Ts = 0.5 both times; Ts enters the driving std too
        fast = DpWorld(sc.model_copy(update={"sensors": sc.sensors.model_copy(update={"gm_time_constant": tc, "ts": ts})}),
                       0, np.arange(4000))
        measured(fast, round(10 * ts / 0.05) + 1)  # ten samples
        assert abs(fast.gm[:, :2].std() / 1.5 - 1) < 0.05
        assert abs(fast.gm[:, 2].std() / np.deg2rad(0.3) - 1) < 0.05  # the heading's own sigma (Table I: 0.3 deg)
    lit = DpWorld(sc.model_copy(update={"sensors": sc.sensors.model_copy(update={"sigma_is": "driving"})}), 0, np.arange(3))
    assert np.allclose(lit.sigma[:, 0], 1.5) and np.allclose(lit.gm, 0)


def test_sensor_sample_time_must_be_on_the_step_grid():
    with pytest.raises(ValidationError, match=r"sensors.ts: 1.025 s must be a multiple of dt=0.05 s"):
        DpScenario(name="t", horizon=10, sensors={"ts": 1.025})
    assert DpScenario(name="t", horizon=10, dt=0.05, sensors={"ts": 0.15}).sensors.ts == 0.15  # 3 steps, despite rounding
    # a period far below the step rounds to 0 steps: before, it passed, and the world divided by zero in its first step
    with pytest.raises(ValidationError, match=r"sensors.ts: 1e-12 s must be a multiple of dt=0.05 s \(one step or more\)"):
        DpScenario(name="t", horizon=10, sensors={"ts": 1e-12})


def test_gauss_markov_between_samples_hold_or_linear():
    """'linear' passes through the same eq. (48) samples as 'hold' and interpolates in between."""
    base = {"name": "g", "horizon": 5, "waves": None, "sensors": {"gnss_sigma": 1.0, "notch": False}}
    hold, lin = (measured(DpWorld(DpScenario(**{**base, "sensors": {**base["sensors"], "between_samples": mode}}), 3,
                                  np.arange(2)), 81) for mode in ("hold", "linear"))
    np.testing.assert_array_equal(hold[::20], lin[::20])  # identical at the 1 s samples
    assert np.ptp(hold[1:20], axis=0).max() == 0  # staircase
    np.testing.assert_allclose(lin[10], 0.5 * (hold[0] + hold[20]))  # halfway between samples


@pytest.mark.parametrize("mode", ["hold", "linear"])
def test_gauss_markov_errors_cover_the_horizon_at_a_faster_sample_time(mode):
    """Ts = 0.5 s over a 5 s horizon: a new eq. (48) sample every 10 steps up to the last step, held (or
    interpolated) in between."""
    sc = DpScenario(name="g", horizon=5, waves=None, sensors={"gnss_sigma": 1.0, "notch": False, "ts": 0.5,
                                                              "between_samples": mode})
    ys = measured(DpWorld(sc, 3, np.arange(2)), 101)
    assert np.all(np.diff(ys[::10, :, 0], axis=0) != 0)  # every sample instant draws anew, to t = 5 s
    if mode == "hold":
        assert np.ptp(ys[91:100], axis=0).max() == 0


def test_wave_components_are_equal_bins_below_the_cutoff_rolled_off_above_the_peak():
    """eta_WF = RAO sum_k A_k cos(w_k t + eps_k): w_k the midpoints of n equal bins up to w_max_factor * w_p,
    A_k = sqrt(2 S(w_k) dw) (the spectrum's variance in each bin), times (w_p / w_k)^rolloff above the peak w_p."""
    from marinebench.environment.waves import component_amplitudes, dnv_gamma

    def components(rolloff, gamma=3.3):
        sc = DpScenario(name="w", horizon=10, waves={"n_components": 40, "w_max_factor": 3.0, "rao_rolloff": rolloff,
                                                     "gamma": gamma})
        omega, amp = DpWorld(sc, 5, np.arange(2)).wave[:2]
        return omega, amp[0]  # one sea state

    omega, flat = components(0.0)
    w_p = 2 * np.pi / 6.3
    edges = np.linspace(0.0, 3.0 * w_p, 41)
    np.testing.assert_allclose(omega, (edges[1:] + edges[:-1]) / 2)
    np.testing.assert_allclose(flat, component_amplitudes(omega, np.diff(edges), 2.0, 6.3, 3.3))
    _, rolled = components(2.0)
    np.testing.assert_allclose(rolled, flat * np.minimum(1.0, (w_p / omega) ** 2))
    _, dnv = components(0.0, gamma=None)  # no gamma: DNV's rule, 1.87 for Hs 2 m, Tp 6.3 s
    assert dnv_gamma(2.0, 6.3) == pytest.approx(1.87, abs=0.01)
    np.testing.assert_allclose(dnv, component_amplitudes(omega, np.diff(edges), 2.0, 6.3, dnv_gamma(2.0, 6.3)))
    # amplitudes scale with Hs, down to a small sea; Hs = 0 is a calm sea with no wave motion
    small = DpWorld(DpScenario(name="w", horizon=10, waves={"hs": 0.5, "rao_rolloff": 0.0}), 5, np.arange(2))
    np.testing.assert_allclose(small.wave[1][0], flat * 0.25, rtol=1e-12)
    calm = DpWorld(DpScenario(name="w", horizon=10, waves={"hs": 0.0}), 5, np.arange(2))
    assert calm.wave is None and not calm.wave_motion(3.0).any()


def test_wave_phases_are_uniform_so_the_sea_has_zero_mean_and_the_spectrums_variance():
    """Over many seeds the surge wave motion at a fixed time has mean 0 and variance RAO^2 sum A_k^2 / 2 (phases
    uniform on [0, 2 pi))."""
    w = DpWorld(DpScenario(name="w", horizon=10), 2, np.arange(4000))
    _, amp, *_ = w.wave
    x = w.wave_motion(7.3)[:, 0]
    std = 0.26 * np.sqrt((amp**2).sum() / 2)
    assert abs(x.mean()) < 4 * std / np.sqrt(4000)
    assert x.std() == pytest.approx(std, rel=0.05)


def test_notch_runs_at_the_measurement_rate_with_held_measurements():
    """hold: measurement — the notch sees one new sample per ts, so it is designed for ts: a pose oscillating at
    the notch frequency w0 (wave-like) is taken out of the measurement once the filter has settled."""
    sc = DpScenario(name="h", horizon=200, waves=None,
                    sensors={"hold": "measurement", "gnss_sigma": 0.0, "heading_sigma_deg": 0.0, "notch_w0": 1.0})
    surge = measured(DpWorld(sc, 0, np.arange(1)), round(sc.horizon / sc.dt),
                     lambda t: np.array([[np.sin(t), *[0.0] * 8]]))[:, 0, 0]
    assert np.abs(surge[-400:]).max() < 0.05


def test_notch_starts_settled_on_the_first_measurement():
    """The notch is started in its steady state for the first measurement: a vessel at rest away from the origin
    is measured where it is from the first step on, with no start-up transient of the filter."""
    sc = DpScenario(name="r", horizon=20, waves=None, initial={"eta": [10.0, -5.0, 0.3]},
                    sensors={"gnss_sigma": 0.0, "heading_sigma_deg": 0.0})
    w = DpWorld(sc, 0, np.arange(2))
    ys = measured(w, 100, lambda t: w.x0)
    np.testing.assert_allclose(ys, np.broadcast_to(w.x0[:, :3], ys.shape), atol=1e-9)


def test_white_heading_noise_option():
    """heading_noise 'white': a fresh N(0, 0.3 deg) every step, uncorrelated; North/East keep eq. (48)."""
    sc = DpScenario(name="w", horizon=100, waves=None,
                    sensors={"heading_sigma_deg": 0.3, "heading_noise": "white", "notch": False})
    psi = measured(DpWorld(sc, 0, np.arange(3)), 2001)[:, :, 2]
    assert abs(psi.std() / np.deg2rad(0.3) - 1) < 0.03
    assert abs(np.corrcoef(psi[1:].ravel(), psi[:-1].ravel())[0, 1]) < 0.05
    gm = DpWorld(sc.model_copy(update={"sensors": sc.sensors.model_copy(update={"heading_noise": "gauss_markov"})}),
                 0, np.arange(3))
    white = DpWorld(sc, 0, np.arange(3))
    assert (white.gm[:, 2] == 0).all() and (gm.gm[:, 2] != 0).all() and np.array_equal(white.gm[:, :2], gm.gm[:, :2])
    # no Gauss-Markov heading error on top: over 1000 s the white error averages out (a drift would not)
    psi = measured(DpWorld(sc.model_copy(update={"horizon": 1000.0}), 0, np.arange(3)), 20001)[:, :, 2]
    assert np.abs(psi.mean(axis=0)).max() < 0.05 * np.deg2rad(0.3)


def test_dp_defaults_are_torben_table_i_and_the_documented_choices():
    """Torben Table I (differential GNSS 0.1 m, heading 0.3 deg, 1/c = 1100 s, Ts = 1 s, notch w0 = 1, wc = 0.5
    rad/s) and Sec. IV-B (Hs = 2 m, Tp = 6.3 s, step 0.05 s); our choices where it is silent (README, models.md 2b):
    gamma 3.3, 40 equal bins up to 3 w_p, the 130 deg RAO magnitudes rolled off as (w_p/w)^2, the GNSS error held
    between samples and sigma as its stationary std, the heading error Gauss-Markov, first-order-hold feed; the
    vessel at rest at the origin without events or bias drift."""
    from marinebench.dp_scenario import DpInitial, DpSensors, Waves

    s = DpSensors()
    assert (s.gnss_sigma, s.heading_sigma_deg, s.gm_time_constant, s.ts) == (0.1, 0.3, 1100.0, 1.0)
    assert (s.notch, s.notch_w0, s.notch_wc) == (True, 1.0, 0.5)
    assert (s.heading_noise, s.sigma_is, s.hold, s.between_samples, s.continuous_feed) == (
        "gauss_markov", "stationary", "noise", "hold", "foh")
    w = Waves()
    assert (w.hs, w.tp, w.gamma, w.n_components, w.w_max_factor) == (2.0, 6.3, 3.3, 40, 3.0)
    assert (w.rao, w.rao_rolloff) == ((0.26, 0.21, 0.0148), 2.0)
    assert DpInitial().model_dump() == {"eta": (0.0, 0.0, 0.0), "nu": (0.0, 0.0, 0.0), "bias": (0.0, 0.0, 0.0)}
    sc = DpScenario(name="d", horizon=10)
    assert (sc.dt, sc.bias_rate, sc.events, sc.design_vessel) == (0.05, (0.0, 0.0, 0.0), [], None)
    assert sc.waves == Waves() and sc.sensors == DpSensors() and sc.model is sc.vessel


def test_a_slow_load_may_rise_and_fall_without_holding():
    """2 rise <= duration: with equality the load is one raised-cosine bump, its peak at mid-duration."""
    from marinebench.dp_scenario import SlowLoad

    bump = {"kind": "slow", "t_start": 10.0, "duration": 20.0, "rise": 10.0, "force": (1e5, 0.0, 0.0)}
    SlowLoad(**bump)
    with pytest.raises(ValidationError, match="2 \\* rise must not exceed duration"):
        SlowLoad(**{**bump, "rise": 10.01})
    w = DpWorld(DpScenario(name="d", horizon=40, events=[bump], waves=None), 0, np.zeros(1, dtype=int))
    assert w.events(20.0)[0] == pytest.approx(1e5) and w.events(15.0)[0] == pytest.approx(0.5e5)
    assert w.events(9.99)[0] == 0.0 and w.events(30.0)[0] == pytest.approx(0.0, abs=1e-6)
    assert w.events(10.5)[0] == pytest.approx(1e5 * 0.5 * (1 - np.cos(np.pi * 0.05)))  # rising from its start


def test_norm_integral_matches_numpy():
    rec = NormIntegral(["a", "psi"], np.array([2.0, 1.0]), {"psi"}, 1.0, 3.0, 0.5)
    rng = np.random.default_rng(0)
    total = np.zeros(2)
    for k in range(10):
        t = 0.5 * k
        ea, ep = rng.normal(size=2), rng.normal(size=2) + 2 * np.pi
        rec.update(k, t, {"a": np.zeros(2), "psi": np.zeros(2)}, {"a": ea, "psi": ep})
        if 1.0 <= t < 3.0:
            total += np.sqrt((ea / 2) ** 2 + (ep - 2 * np.pi) ** 2) * 0.5
    np.testing.assert_allclose(rec.value, total)


def test_a_variants_world_settings_reach_its_own_runs():
    """``variants[].world`` sets per-run sensor settings: the NPO's runs get 15x the GNSS error and 2x the heading
    error of the resetting observer's runs on the same seeds (the same standard-normal draws, scaled)."""
    from marinebench.experiments.runner import make_world

    exp, _ = load_experiment(CONFIG, ["seeds=2", "variants[npo].world={gnss_sigma: 1.5, heading_sigma_deg: 0.6}"])
    run_variant, run_seed = np.repeat([0, 1], 2), np.tile([0, 1], 2)
    world = make_world(exp, run_variant, run_seed)
    assert [v.name for v in exp.variants] == ["npo", "resetting"]
    np.testing.assert_allclose(world.gm[:2] / world.gm[2:], [[15.0, 15.0, 2.0]] * 2)


def test_a_runs_sea_state_and_gauss_markov_time_constant_are_its_own():
    """Per-run ``hs`` and ``gm_time_constant`` (``world:``, ``world.<key>`` sweeps): a run at Hs 1 m sees half the
    wave motion of one at the scenario's 2 m on the same seed (the same phases; with gamma fixed the amplitudes
    scale with Hs), one at Hs 0 none; a run given the scenario's own values is the run without them, to the bit;
    a run's 1/c is the world's it would have as the scenario's own (the same noise, to the bit)."""
    from marinebench.experiments.runner import make_world

    sets = ["seeds=1", "scenario.waves.gamma=3.3"]
    exp, _ = load_experiment(CONFIG, sets)
    plain = make_world(exp, np.array([0]), np.array([0]))
    exp, _ = load_experiment(CONFIG, [*sets, "variants[npo].world={hs: 1, gm_time_constant: 100}"])
    world = make_world(exp, np.array([0, 1, 1]), np.array([0, 0, 0]))  # npo at Hs 1; resetting at the own Hs 2
    eta = world.wave_motion(37.0)
    np.testing.assert_allclose(eta[0], eta[1] / 2, rtol=1e-12)
    assert (eta[1] == plain.wave_motion(37.0)[0]).all() and (world.gm[1:] == plain.gm).all()
    calm, _ = load_experiment(CONFIG, [*sets, "variants[npo].world={hs: 0}"])
    assert not make_world(calm, np.array([0, 1]), np.array([0, 0])).wave_motion(37.0)[0].any()
    short, _ = load_experiment(CONFIG, [*sets, "scenario.sensors.gm_time_constant=100"])
    own = make_world(short, np.array([0]), np.array([0]))
    for k in range(0, 2000, 20):  # 100 s of Gauss-Markov samples (ts 1 s)
        own.begin_step(k, k * exp.scenario.dt, own.x0)
        world.begin_step(k, k * exp.scenario.dt, world.x0)
        assert (world.gm[0] == own.gm[0]).all() and (k == 0 or (world.gm[1] != own.gm[0]).any())  # 1/c 1100 s: other
    with pytest.raises(ConfigError) as err:  # calm water has no sea state to change
        load_checked(CONFIG, ["scenario.waves=null", "variants[npo].world={hs: 1}"])
    assert str(err.value) == ("--set: variants.0.world.hs: this world has no waves (waves: null): give it a sea state, "
                              "scenario.waves, whose hs a run may change")


@pytest.mark.parametrize("world, key", [("{gnss_sigma: -1}", "gnss_sigma"), ("{gnss_sigma: 1, heading_sigma_deg: -0.3}",
                                                                        "heading_sigma_deg"), ("{hs: -1}", "hs")])
def test_a_variants_world_setting_is_bounded_as_the_scenarios_own(world, key):
    """A per-run noise level below zero is refused like ``scenario.sensors.gnss_sigma: -1`` is (it would run: the
    noise is symmetric), naming where it came from and the key."""
    with pytest.raises(ConfigError) as err:
        load_checked(CONFIG, [f"variants[npo].world={world}"])
    assert str(err.value) == f"--set: variants.0.world.{key}: Input should be greater than or equal to 0"
    load_checked(CONFIG, ["variants[npo].world={gnss_sigma: 0, heading_sigma_deg: 0}", "seeds=1"])  # the bound itself


@pytest.mark.parametrize("group, expected", [
    ("gnss_sigma=-1", "sweep.groups.dgnss.gnss_sigma: Input should be greater than or equal to 0"),
    ("foo=1", ("sweep.groups.dgnss: unknown world keys ['foo'] (per run: ['gnss_sigma', 'heading_sigma_deg', "
                "'gm_time_constant', 'hs'], or a setting of the world by its dotted path, e.g. sensors.<key>; horizon "
                "and dt are every run's)")),
    ("gnss_sgima=1", "sweep.groups.dgnss: unknown world keys ['gnss_sgima'] (did you mean gnss_sigma?)"),
    ("dt=0.1", ("sweep.groups.dgnss: unknown world keys ['dt'] (per run: ['gnss_sigma', 'heading_sigma_deg', "
               "'gm_time_constant', 'hs'], or a setting of the world by its dotted path, e.g. sensors.<key>; horizon "
               "and dt are every run's)")),
])
def test_a_sweep_groups_world_settings_are_checked_where_they_are_written(group, expected):
    """A sweep's world group is checked when the config loads (by validate as by sweep), at its own key, not later
    as a point variant of the sweep's experiment."""
    with pytest.raises(ConfigError) as err:
        load_checked(ROOT / "configs" / "torben_fig3.yaml", [f"sweep.groups.dgnss.{group}"])
    assert str(err.value) == f"--set: {expected}"


def short(*sets, config=CONFIG):
    exp, _ = load_experiment(config, ["scenario.horizon=120", "seeds=1", "figures=[]", *sets])
    metrics = run(exp, traces=False).metrics
    # one value per (variant, metric): m["npo", "J_tot"] is then a number on every pandas (the per-signal rmse, which
    # these tests do not read, would make the index non-unique, and pandas < 3 return a Series)
    return metrics[metrics["metric"] != "rmse"].set_index(["variant", "metric"])["value"]


def test_npo_is_resetting_with_k_zero():
    m = short("variants.1.observer.k=0")
    assert m["npo", "J_tot"] == pytest.approx(m["resetting", "J_tot"], rel=1e-12)
    assert m["resetting", "n_jumps"] == 0 and m["resetting", "n_resets"] == 48
    assert m["npo", "n_jumps"] == 0 and m["npo", "n_resets"] == 48  # the NPO's windows: the same 2.5 s (Table I)


def test_resetting_recovers_transient_on_clean_measurements():
    """Noise-free, wave-free, unfiltered measurements: the finite-time resets cut the transient KPI."""
    m = short("scenario.waves=null", "scenario.sensors.notch=false", "scenario.sensors.gnss_sigma=0",
              "scenario.sensors.heading_sigma_deg=0")
    assert m["resetting", "J_tot_transient"] < 0.3 * m["npo", "J_tot_transient"]
    assert m["resetting", "n_jumps"] > 0


def test_fig1_ordering_with_noise_and_waves():
    """Torben Figs 1-2 on the committed tuning, shortened: resets cut the transient KPI by well over 30 %
    and leave no steady-state penalty once the transient is over (J over [300, 400) s within 10 %)."""
    exp, _ = load_experiment(CONFIG, ["scenario.horizon=400", "seeds=2", "figures=[]", "table.metrics=[J_tot_transient]", "sweep=null",
                                      ("metrics=[{kind: j_tot, name: J_tot_transient, t_start: 50, t_end: 150}, "
                                       "{kind: j_tot, name: J_late, t_start: 300}]")])
    m = run(exp, traces=False).metrics.groupby(["variant", "metric"])["value"].mean()
    assert m["resetting", "J_tot_transient"] < 0.7 * m["npo", "J_tot_transient"]
    assert m["resetting", "J_late"] < 1.1 * m["npo", "J_late"]


def test_torben_config_runs_through_cli(tmp_path):
    res = CliRunner().invoke(app, ["run", str(CONFIG), "--out", str(tmp_path), "--quiet", "--profile", "quick",
                                   "--set", "scenario.horizon=80", "--seeds", "1"])
    assert res.exit_code == 0, res.output
    table = (tmp_path / "torben_fig1" / "table.md").read_text()
    assert "J_tot_transient" in table and "npo" in table
    resolved = yaml.safe_load((tmp_path / "torben_fig1" / "config.resolved.yaml").read_text())
    assert resolved["scenario"]["kind"] == "dp_supply"
    assert (tmp_path / "torben_fig1" / "figures" / "fig2_transient.png").exists()


def test_instability_at_delta_equal_dt_without_cond_check():
    """Torben Sec. IV-B2: with delta ~ dt, cond(I - Phi2 Phi1^-1) explodes; without the check the jumps
    destroy the estimate, with the check nothing jumps. Shown in raw SI coordinates (cond ~3e32 here; ~9e22
    bis-scaled at delta = dt, ~7e8 at 3 steps)."""
    common = ["variants.1.observer.delta=0.05", "variants.1.observer.jump_coordinates=raw", "scenario.horizon=100"]
    off = short(*common, "variants.1.observer.check_cond=false")
    on = short(*common, "variants.1.observer.check_cond=true")
    assert off["resetting", "J_tot"] > 1e6 * off["npo", "J_tot"] or not np.isfinite(off["resetting", "J_tot"])
    assert on["resetting", "n_jumps"] == 0 and on["resetting", "J_tot"] == pytest.approx(on["npo", "J_tot"], rel=1e-12)
    assert on["resetting", "cond_max"] > 1e20


def test_resetting_variants_in_bis_and_raw_coordinates_share_a_batch():
    """``jump_coordinates`` per run: two resetting variants, bis and raw, in one batch give what each gives in a
    batch of its own kind (the condition number is the coordinates' own: ~1e2 bis-scaled, far larger raw)."""
    resetting = ["variants.0.observer.kind=resetting_fto", "scenario.horizon=60"]
    mixed = short(*resetting, "variants.1.observer.jump_coordinates=raw")
    bis = short(*resetting)
    raw = short(*resetting, "variants.0.observer.jump_coordinates=raw", "variants.1.observer.jump_coordinates=raw")
    for metric in ("J_tot", "log10_cond_mean", "n_jumps"):
        assert mixed["npo", metric] == pytest.approx(bis["npo", metric], rel=1e-12)
        assert mixed["resetting", metric] == pytest.approx(raw["resetting", metric], rel=1e-12)
    assert mixed["npo", "log10_cond_mean"] < 3 < mixed["resetting", "log10_cond_mean"]


def test_bis_scaled_condition_number_and_check():
    m = short("variants.1.observer.delta=0.05", "scenario.horizon=60")
    assert m["resetting", "cond_max"] > 1e10 and m["resetting", "n_jumps"] == 0  # c_max = 1e10 blocks every jump
    m = short("scenario.horizon=60")
    assert m["resetting", "log10_cond_mean"] < 10  # delta = 2.5 s: well conditioned in bis units
    assert m["resetting", "n_resets"] > 1 and m["resetting", "log10_cond_mean"] <= np.log10(m["resetting", "cond_max"])
    # the NPO runs one gain (Phi2 = Phi1): its cond(I - Phi2 Phi1^-1) is a ratio of rounding errors, not reported
    assert ("npo", "n_resets") in m.index and ("npo", "cond_max") not in m.index and ("npo", "log10_cond_mean") not in m.index


def test_sweep_cli_tiny_grid(tmp_path):
    cfg = ROOT / "configs" / "torben_fig3.yaml"
    res = CliRunner().invoke(app, ["sweep", "k", "eps", "--config", str(cfg), "--n", "2", "--horizon", "20",
                                   "--gnss", "dgnss,dualband", "--out", str(tmp_path), "--quiet"])
    assert res.exit_code == 0, res.output
    d = tmp_path / "torben_fig3_sweep_k_eps_n2_20s"  # a sweep of some parameters, other n and horizon: its own folder
    import pandas as pd

    m = pd.read_csv(d / "metrics.csv")
    assert {"param", "param_value", "gnss"} <= set(m.columns)
    j = m[m["metric"] == "J_tot"]
    assert len(j) == 2 * 2 * 2 and set(j["param"]) == {"k", "eps"} and set(j["gnss"]) == {"dgnss", "dualband"}
    assert sorted(j[j["param"] == "k"]["param_value"].unique()) == [0.0, 1.0]
    assert (d / "figures" / "sweep.png").exists() and "| k | dgnss |" in (d / "table.md").read_text()
    assert "### J_tot at the probe values" in (d / "table.md").read_text()  # the config's probes (k = 0, 0.7, 1)
    claims = (d / "claims.md").read_text()  # Fig. 3's trends on k and eps (delta was not swept)
    assert "J_tot at k = 0.7 at least 20 % below k = 0" in claims and "reset time" not in claims
    assert "| dualband / dgnss | z |" in claims
    mc = CliRunner().invoke(app, ["sweep", "k", "--config", str(cfg), "--n", "2", "--horizon", "20", "--gnss", "dgnss",
                                  "--seeds", "2", "--out", str(tmp_path), "--quiet"])
    assert mc.exit_code == 0, mc.output
    d2 = tmp_path / "torben_fig3_sweep_k_dgnss_n2_20s_2seeds"  # nor does a Monte-Carlo sweep of one group
    assert sorted(pd.read_csv(d2 / "metrics.csv")["seed"].unique()) == [0, 1] and (d / "metrics.csv").exists()
    assert "2 runs per point" in (d2 / "table.md").read_text()
    written = (d2 / "manifest.json").stat().st_mtime_ns
    again = CliRunner().invoke(app, ["sweep", "k", "--config", str(cfg), "--n", "2", "--horizon", "20", "--gnss", "dgnss",
                                     "--seeds", "2", "--out", str(tmp_path), "--resume"])
    assert again.exit_code == 0 and "up to date (same inputs)" in again.output
    assert (d2 / "manifest.json").stat().st_mtime_ns == written
    bad = CliRunner().invoke(app, ["sweep", "gamma", "--config", str(cfg), "--out", str(tmp_path)])
    assert bad.exit_code == 2 and "unknown parameter" in bad.output and "sweepable" in bad.output
    assert "did you mean" not in bad.output  # nothing near 'gamma'
    typo = CliRunner().invoke(app, ["sweep", "k", "delat", "--config", str(cfg), "--out", str(tmp_path)])
    assert typo.exit_code == 2 and "['delat'] (did you mean delta?); sweepable: ['delta', 'eps', 'k']" in typo.output


def test_interrupted_sweep_resumes_without_rerunning_finished_batches(tmp_path, monkeypatch):
    from marinebench.experiments import runner as runner_module
    from marinebench.experiments.chunks import run_chunked
    from marinebench.experiments.sweep import sweep_experiment

    cfg = ROOT / "configs" / "torben_fig3.yaml"
    base, _ = load_experiment(cfg)
    exp = sweep_experiment(base, ["k"], ["dgnss"], 4, 15.0, cfg)
    target = tmp_path / "sweep"
    reference, _, ran = run_chunked(exp, tmp_path / "uninterrupted", chunk_size=2)
    assert ran == 2
    real_run, calls = runner_module.run, []

    def flaky(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt  # the user stops the sweep during the second batch
        return real_run(*args, **kwargs)

    monkeypatch.setattr(runner_module, "run", flaky)
    with pytest.raises(KeyboardInterrupt):
        run_chunked(exp, target, chunk_size=2)
    monkeypatch.setattr(runner_module, "run", real_run)
    resumed, _, ran = run_chunked(exp, target, chunk_size=2)
    assert ran == 1  # only the unfinished batch ran again
    key = ["variant", "metric"]
    a = reference.sort_values(key).reset_index(drop=True)
    b = resumed.sort_values(key).reset_index(drop=True)
    assert a["value"].tolist() == b["value"].tolist()
    # a kept batch damaged since (emptied, or a row of another variant) runs again; before, it counted as finished
    # and the sweep failed reading it after simulating the rest; an unreadable key starts afresh
    partial = target.parent / f".{target.name}.partial"
    chunk = partial / "chunk-0000.csv"
    for damage in ("", chunk.read_text().replace(exp.variants[0].name, "other")):
        chunk.write_text(damage)
        again, _, ran = run_chunked(exp, target, chunk_size=2)
        assert ran == 1 and again.sort_values(key)["value"].tolist() == a["value"].tolist()
    (partial / "key").unlink()
    (partial / "key").mkdir()
    _, _, ran = run_chunked(exp, target, chunk_size=2)
    assert ran == 2 and (partial / "key").is_file()
    # batches left by other code (e.g. before a fix) are not reused, though the config is the same
    (target.parent / f".{target.name}.partial" / "chunk-0001.csv").unlink()
    from marinebench import provenance

    monkeypatch.setattr(provenance, "package_digest", lambda: "other code")
    _, _, ran = run_chunked(exp, target, chunk_size=2)
    assert ran == 2


@pytest.mark.parametrize("scheme", ["predictor", "rk4"])
def test_discrete_fto_is_exact_through_the_engine(scheme):
    """Noise- and wave-free plant with a constant bias (surge only, so the heading stays 0): with the
    'predictor' map the observer error obeys Phi exactly, so one window with k = 1 recovers the true
    state and the error stays zero; the closed-loop RK4 map with y held does not (its O(dt^2) mismatch
    is what the aggressive L2 turns into jump errors)."""
    m = short("scenario.waves=null", "scenario.sensors.gnss_sigma=0", "scenario.sensors.heading_sigma_deg=0",
              "scenario.sensors.notch=false", "scenario.events=[]", "scenario.horizon=10",
              "scenario.initial.nu=[0.5, 0, 0]", "scenario.initial.bias=[2.0e5, 0, 0]",
              "variants.1.observer.k=1", "variants.1.observer.eps=[1.0e-9, 1.0e-9, 1.0e-9]",
              f"variants.0.observer.discretization={scheme}", f"variants.1.observer.discretization={scheme}",
              "metrics=[{kind: j_tot, name: J_before, t_end: 2.5}, {kind: j_tot, name: J_after, t_start: 2.5}]",
              "table.metrics=[J_before, J_after]", "sweep=null", config=MATCHED)
    assert m["resetting", "J_before"] > 1e-3  # the observers start from zero: a real error to remove
    if scheme == "predictor":
        assert m["resetting", "J_after"] < 1e-9 * m["resetting", "J_before"]
    else:
        assert m["resetting", "J_after"] > 1e-4 * m["resetting", "J_before"]


def test_design_vessel_separates_the_observer_model_from_the_plant():
    """Plant: ShipX LF (model B); observers: designed and run on model A (the committed scenarios, as the
    paper's high-fidelity plant against its design model). Without design_vessel: the plant's own."""
    from marinebench.experiments.runner import make_observer, plant_of
    from marinebench.models.supply import SupplyVessel, SupplyVesselParams

    exp, _ = load_experiment(CONFIG, ["scenario.horizon=60", "seeds=1", "figures=[]"])
    world = DpWorld(exp.scenario, 0, np.zeros(1, dtype=int))
    observer = make_observer("npo", [exp.variants[0].observer], exp.scenario, plant_of(exp.scenario))
    model_a = SupplyVessel(SupplyVesselParams())
    np.testing.assert_array_equal(observer.M, model_a.M)
    assert world.plant.params.kind == "supply_shipx_lf" and world.plant.M[1, 1] == pytest.approx(8.546e6)
    np.testing.assert_allclose(world.scale[0], 82.8)  # the KPI's bis units are the simulated vessel's
    # an explicit design_vessel equal to the plant changes nothing
    same = short("scenario.design_vessel={kind: supply_dp_linear}", config=MATCHED)
    default = short(config=MATCHED)
    assert same["resetting", "J_tot"] == pytest.approx(default["resetting", "J_tot"], rel=1e-12)


@pytest.mark.parametrize("scenario, expected", [
    ("dp_impulse.yaml", ["x", "y", "psi", "b_x", "b_y", "b_n", "u", "v", "r"]),
    ("cs2_noisy.yaml", ["u", "v", "r", "sigma_u", "sigma_v", "sigma_r"]),
    ("rov_s1.yaml", ["depth", "yaw"]),
])
def test_error_metrics_and_tables_default_to_the_scenario_kinds_signals(tmp_path, scenario, expected):
    observer = {"kind": "npo"} if scenario.startswith("dp") else {"kind": "liu_eso"}
    variant = {"name": "a", **({"controller": {"kind": "rise"}} if scenario.startswith("rov") else {"observer": observer})}
    doc = {"scenario": str(ROOT / "scenarios" / scenario), "variants": [variant],
           "metrics": [{"kind": "rmse"}, {"kind": "j_tot"}] if scenario.startswith("dp") else [{"kind": "rmse"}],
           "table": {"title": "t", "metrics": ["rmse"]}}
    path = tmp_path / "x.yaml"
    path.write_text(yaml.safe_dump(doc))
    exp, _ = load_experiment(path)
    assert exp.metrics[0].signals == expected and exp.table.signals == expected
    if scenario.startswith("dp"):
        path.write_text(yaml.safe_dump({**doc, "table": {"title": "t", "metrics": ["J_tot"]}}))
        assert load_experiment(path)[0].table.signals == ["z"]


def test_one_step_is_each_runs_own_exact_map_in_a_batch_of_two_design_classes():
    """The fitted harmonic maps of z+ = P z + G_y y + G_u u equal the maps formed directly from A_i(psi) and
    L_i(psi) at any heading, each run with its own design class's (here two Q1s in one batch), inputs included."""
    sc = DpScenario(name="m", horizon=10, waves=None)
    tunings = [ResettingTuning(), ResettingTuning(q=(500.0, 500.0, 100.0)), ResettingTuning()]
    obs = make_observer("resetting_fto", tunings, sc, plant_of(sc))
    assert list(obs.class_of) == [0, 1, 0]
    rng = np.random.default_rng(11)
    state = obs.init().reshape(3, 2, 9, 10)
    scale = np.array([5, 5, 0.3, 1e5, 1e5, 1e6, 1, 1, 0.05])  # typical magnitudes [m, rad, N, N m, m/s, rad/s]
    state[..., 9] = rng.normal(size=(3, 2, 9)) * scale
    y = np.array([[3.0, -2.0, 2.9], [1.0, 4.0, -1.7], [-2.0, 0.5, 0.4]])  # headings far from the design's 0
    tau = np.array([[2e5, -1e5, 3e6], [-4e5, 2e5, -1e6], [1e5, 3e5, 2e6]])
    out = obs.step(state.reshape(3, -1).copy(), y, tau, 0).reshape(3, 2, 9, 10)
    for b, cls in enumerate(obs.class_of):
        P, Gy, Gu = obs.exact_maps(y[b : b + 1, 2], obs.classes[cls]["K"])
        z = P[0] @ state[b, :, :, 9, None] + Gy[0] @ y[b, :, None] + Gu[0] @ tau[b, :, None]
        np.testing.assert_allclose(out[b, :, :, 9] / scale, z[..., 0] / scale, rtol=0, atol=1e-9)
        np.testing.assert_allclose(out[b, :, :, :9], P[0], rtol=1e-12, atol=1e-12)  # Phi_i advanced from I
    assert not np.allclose(out[0, :, :, :9], out[1, :, :, :9])  # the two classes' maps differ


@pytest.mark.parametrize("config, sets, key", [
    ("torben_fig1.yaml", [], "K1_L1"),  # a DP observer's Kalman gains
    ("tijjani_observers.yaml", ["variants[cdo].observer.cdo.theta=20"], "cdo"),  # a variant's own CDO design
])
def test_the_manifest_lists_each_variants_design_up_to_designs_up_to_variants(config, sets, key):
    """runner.design_summary: per-variant designs for at most DESIGNS_UP_TO variants (a sweep's many are skipped)."""
    exp, _ = load_experiment(ROOT / "configs" / config, sets=sets)
    base = exp.variants[0]

    def designs(n: int) -> dict:
        return design_summary(exp.model_copy(update={"variants": [base.model_copy(update={"name": f"v{i}"})
                                                                  for i in range(n)]}))

    assert key in designs(DESIGNS_UP_TO)["v0"]
    assert key not in designs(DESIGNS_UP_TO + 1).get("v0", {})
