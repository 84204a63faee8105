"""Tijjani reproduction: CDO gain design, observers, scenario files, multi-scenario configs, short orderings."""

import numpy as np
import pytest
import yaml

from marinebench.controllers.rise import RISE_PRESETS
from marinebench.controllers.spec import ControllerSpec
from marinebench.design.cdo import (
    BINOMIAL,
    check,
    design_lmi,
    sample_noise_gain,
    sample_noise_gains,
    sampled_flow,
    sampled_radius,
    verify_lmi,
)
from marinebench.errors import ConfigError, DesignError
from marinebench.experiments.runner import _recorders, run, steps
from marinebench.loading import load_experiment, load_scenario
from marinebench.preflight import preflight
from marinebench.rov_scenario import min_jerk
from marinebench.sim.recorders import RecoveryTime

from .conftest import ROOT, md_row


@pytest.mark.parametrize("mu", [0.2, 0.35, 1.0])
def test_cdo_lmi40_solution_is_verified_and_meets_its_decay_rate(mu):
    d = design_lmi(mu)
    assert d.lmi_max_eig <= 1e-6
    assert d.poles_normalised.real.max() <= -mu + 1e-6
    for h in (0.05, 0.04):  # depth and attitude sensor periods (Table I)
        assert check(d.k_star, 24.39, 0.1, h, "dof") < 1
    # the numpy re-check rejects a gain the LMI solution does not certify
    with pytest.raises(DesignError, match="numpy check"):
        verify_lmi(np.array(d.k_star) * 0.2, d.P, d.S, 1e-3, mu)


def test_literal_table_ii_scalar_readings_fail_the_sampled_data_check():
    """baselines.md 9.4: K* = 0.2 [3, 3, 1] for yaw (Table II's scalar) diverges per sample; binomial does not."""
    assert sampled_radius(0.2 * np.array(BINOMIAL), 24.39, 0.1, 0.04) > 1
    with pytest.raises(DesignError, match="spectral radius"):
        check(0.2 * np.array(BINOMIAL), 24.39, 0.1, 0.04, "yaw")
    with pytest.raises(DesignError, match=r"\(39\)"):
        check((0.001, 1.0, 1.0), 24.39, 0.1, 0.04, "yaw")
    assert sampled_radius(BINOMIAL, 24.39, 0.1, 0.05) < 0.75


def simulated_noise_gain(injection, h, k_w, predictor, n_samples=6000, sub=25, seed=3):
    """Std of x_hat_1 of the linear chain fed unit white noise on its samples, truth at rest (direct run)."""
    from scipy.linalg import expm

    F = sampled_flow(injection, k_w, predictor)
    step = expm(F * h / sub)
    z = np.zeros(4)
    out = np.empty((n_samples, sub))
    for k, n in enumerate(np.random.default_rng(seed).standard_normal(n_samples)):
        z[3] = n  # the output channel restarts from the sample
        for i in range(sub):
            z = step @ z
            out[k, i] = z[0]
    return out[n_samples // 10 :].std()


@pytest.mark.parametrize("h", [0.05, 0.04])
def test_sample_noise_gain_matches_a_direct_simulation_and_the_cdo_passes_more_noise_than_the_eo(h):
    """The analytic gain (discrete Lyapunov, period-averaged) agrees with simulating the same chains, and with
    equal gains the CDO's predictor, which keeps integrating the noisy rate estimate between samples, passes more
    sample noise than the EO's held sample (README, CDO vs EO)."""
    theta = 24.39
    eo = np.array([3.0, 3.0, 1.0]) * theta ** np.arange(1, 4)
    cdo = np.array([theta, theta**2, theta**3]) * np.array(design_lmi(0.35).k_star)
    for inj, k_w, pred in ((eo, 0.0, False), (cdo, 0.1, True), (eo, 0.1, True)):
        analytic = sample_noise_gain(inj, h, k_w, pred)
        assert analytic == pytest.approx(simulated_noise_gain(inj, h, k_w, pred), rel=0.04)
    assert sample_noise_gain(eo, h, 0.1, True) > 1.4 * sample_noise_gain(eo, h, predictor=False)


@pytest.mark.filterwarnings("ignore:An ill-conditioned matrix")
def test_sample_noise_gain_stays_exact_for_stiff_gains_a_coarse_quadrature_gets_wrong():
    """The period average is an exact integral (Van Loan, doubled), not a quadrature: for a stiff EO gain (poles
    far faster than 1/h) it agrees with a 1024-point midpoint rule, which a 16-point rule misses by > 10 %; the
    batched call gives each gain the value of the single one (docs/analysis/cdo_noise_frontier.py searches it)."""
    from scipy.linalg import expm, solve_discrete_lyapunov

    def midpoint(inj, h, quad):
        F = sampled_flow(inj, 0.0, False)
        q = np.zeros((4, 4))
        q[3, 3] = 1.0
        P = solve_discrete_lyapunov(np.diag([1.0, 1.0, 1.0, 0.0]) @ expm(F * h), q)
        mids = [expm(F * h * (i + 0.5) / quad) for i in range(quad)]
        return np.sqrt(np.mean([(E @ P @ E.T)[0, 0] for E in mids]))

    stiff, mild = np.array([2.35e3, 4.5e6, 1e10]), np.array([3.0, 3.0, 1.0]) * 24.39 ** np.arange(1, 4)
    radius, gain = sample_noise_gains(np.stack([stiff, mild]), 0.05, predictor=False)
    assert radius[0] < 1 and gain[0] == pytest.approx(midpoint(stiff, 0.05, 1024), rel=1e-4)
    assert abs(midpoint(stiff, 0.05, 16) / gain[0] - 1) > 0.1
    assert gain[1] == pytest.approx(sample_noise_gain(mild, 0.05, predictor=False), rel=1e-12)
    assert sample_noise_gains(np.array([1.0, 1.0, 1.0]) * -1, 0.05, predictor=False)[1][0] == np.inf


def test_sampled_flow_is_the_error_flow_of_eq_38_between_samples():
    """expm(F h) of ``sampled_flow`` against eq. (38) integrated directly (truth at rest, w reset to the sample at
    t = 0): x_hat' = A x_hat + L (w - x_hat_1), w' = x_hat_2 + K_w (w - x_hat_1). A large K_w makes its sign count."""
    from scipy.integrate import solve_ivp
    from scipy.linalg import expm

    theta, h, k_w = 24.39, 0.05, 5.0
    lk = np.array([theta, theta**2, theta**3]) * np.array(BINOMIAL)

    def eq38(_, s):
        x, w = s[:3], s[3]
        return [x[1] + lk[0] * (w - x[0]), x[2] + lk[1] * (w - x[0]), lk[2] * (w - x[0]), x[1] + k_w * (w - x[0])]

    start = np.array([0.02, -0.3, 4.0, 0.0])  # an estimation error; w = y = 0 just after the sample
    direct = solve_ivp(eq38, (0, h), start, rtol=1e-11, atol=1e-13).y[:, -1]
    assert expm(sampled_flow(lk, k_w) * h) @ start == pytest.approx(direct, rel=1e-7, abs=1e-10)


def test_sample_noise_gain_averages_the_variance_over_the_period():
    """The period average of ``sample_noise_gain`` (midpoint rule) against an adaptive quadrature of the same
    variance, E(t) P E(t)^T with P the post-sample covariance of the discrete Lyapunov equation."""
    from scipy.integrate import quad_vec
    from scipy.linalg import expm, solve_discrete_lyapunov

    theta, h, k_w = 24.39, 0.05, 0.1
    cdo = np.array([theta, theta**2, theta**3]) * np.array(design_lmi(0.35).k_star)
    F = sampled_flow(cdo, k_w)
    P = solve_discrete_lyapunov(np.diag([1.0, 1.0, 1.0, 0.0]) @ expm(F * h), np.diag([0.0, 0.0, 0.0, 1.0]))
    mean_var = quad_vec(lambda s: (expm(F * s) @ P @ expm(F * s).T)[0, 0], 0, h, epsrel=1e-10)[0] / h
    assert sample_noise_gain(cdo, h, k_w) == pytest.approx(np.sqrt(mean_var), rel=2e-4)


def test_the_cdo_lmi_design_at_the_default_decay_rate_is_the_documented_one():
    """docs/tijjani.md quotes K* and the poles of the default design (mu = 0.35, theta = 24.39); P >= I fixes the
    scale of (40), so the gain does not depend on the solver's choice of scale."""
    d = design_lmi(0.35)
    assert np.array(d.k_star) == pytest.approx([1.40, 0.94, 0.21], abs=0.006)
    poles = np.sort_complex(d.poles_normalised * 24.39)  # rad/s, printed to one decimal
    assert poles.real == pytest.approx([-12.3, -12.3, -9.7], abs=0.05)
    assert poles.imag == pytest.approx([-13.1, 13.1, 0.0], abs=0.05)


def test_verify_lmi_refuses_a_slightly_violated_lmi_40():
    """The numpy re-check holds (40) to its tolerance: S a thousandth of its size too small fails it."""
    d = design_lmi(0.35)
    verify_lmi(np.array(d.k_star), d.P, d.S, 1e-3, 0.35)  # the solution itself passes
    with pytest.raises(DesignError, match="numpy check"):
        verify_lmi(np.array(d.k_star), d.P, d.S - 1e-3 * np.abs(d.S).max() * np.eye(3), 1e-3, 0.35)


def test_minimal_trace_s_makes_lmi_40_and_the_decay_rate_active():
    """Minimising trace(S) drives the solution onto the boundary of (40) at the lambda it was solved with, and
    S's two directions the injection does not use down to the bound -S <= -lambda I that (40) itself puts on S.
    The decay rate is active too: the slowest normalised pole is no faster than mu needs."""
    d = design_lmi(0.35)
    assert abs(d.lmi_max_eig) < 1e-6
    assert np.linalg.eigvalsh(d.S)[:2] == pytest.approx([1e-3, 1e-3], rel=1e-3)


@pytest.mark.parametrize(("lam", "mu", "holds"), [
    (5e-4, 0.35, True),  # a weaker (40) than solved for
    (1.0e-3 + 1e-5, 0.35, True),  # violated by 1e-5, inside the tolerance 1e-6 x max|P| (P ~ 140)
    (1.5e-3, 0.35, False),  # violated by 5e-4, outside it
    (1e-3, 0.30, True),
    (1e-3, 0.35 + 1e-7, True),  # decay violated by ~3e-5, inside the tolerance
    (1e-3, 0.35 + 1e-6, False),  # by ~3e-4: the solution certifies decay 0.35, not faster
])
def test_verify_lmi_holds_40_and_the_decay_rate_at_the_lambda_and_mu_it_is_given(lam, mu, holds):
    """The re-check is of (40) + lambda I <= 0 and A_cl^T P + P A_cl + 2 mu P <= 0 at the values passed, each
    within a tolerance relative to the size of P and S (the solution is tight at lambda = 1e-3, mu = 0.35)."""
    d = design_lmi(0.35)
    if holds:
        verify_lmi(np.array(d.k_star), d.P, d.S, lam, mu)
    else:
        with pytest.raises(DesignError, match="numpy check"):
            verify_lmi(np.array(d.k_star), d.P, d.S, lam, mu)


def test_check_refuses_equality_in_39_and_a_zero_injection():
    """(39) is strict: K_w = theta K*_1 is refused, the message giving both sides. With no injection the error
    map is exp(A h), whose eigenvalues are all exactly 1: refused as not converging, and its noise gain is inf."""
    with pytest.raises(DesignError, match=r"\(39\) needs K_w < theta K\*_1 \(34.146 >= 34.1\)"):
        check((1.4, 3.0, 1.0), 24.39, 24.39 * 1.4, 0.05, "depth")
    with pytest.raises(DesignError, match=r"CDO yaw: .* spectral radius 1.000 >= 1 at h = 0.04 s"):
        check((0.0, 0.0, 0.0), 24.39, -1.0, 0.04, "yaw")
    radius, gain = sample_noise_gains(np.zeros(3), 0.05, predictor=False)
    assert radius[0] == 1.0 and gain[0] == np.inf


def write(tmp_path, doc, name="x.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def observe_noiseless(tmp_path, **scenario):
    ctrl = {"kind": "rise"}
    doc = {"scenario": {"from": str(ROOT / "scenarios" / "rov_s1.yaml"), "horizon": 6.0, "estimate_offset": [0.05, 10.0],
                        "sensors": {"depth_noise": 0.0, "yaw_noise_deg": 0.0}, **scenario},
           "seeds": 1,
           "variants": [{"name": "cdo", "controller": ctrl, "observer": {"kind": "cdo"}},
                        {"name": "eo", "controller": ctrl, "observer": {"kind": "eo"}}],
           "metrics": [{"kind": "max_abs", "name": "start", "t_start": 0.0, "t_end": 0.01, "signals": ["depth", "yaw"]},
                       {"kind": "max_abs", "name": "late", "t_start": 4.0, "signals": ["depth", "yaw"]}]}
    exp, _ = load_experiment(write(tmp_path, doc))
    return run(exp, traces=False).metrics.set_index(["variant", "signal", "metric"])["value"]


def test_cdo_and_eo_converge_on_a_noiseless_plant(tmp_path):
    m = observe_noiseless(tmp_path, depth_ref=[[0, 0.1]], yaw_ref_deg=[[0, 20.0]])  # holding a pose
    for obs in ("cdo", "eo"):
        assert m[obs, "depth", "start"] > 0.04 and m[obs, "yaw", "start"] > np.deg2rad(9)
        assert m[obs, "depth", "late"] < 1e-4 and m[obs, "yaw", "late"] < 1e-4


def test_cdo_predictor_removes_the_lag_of_held_samples_while_moving(tmp_path):
    """Noiseless samples while diving and turning (S1's first 6 s): the EO, fed the held samples, lags;
    the CDO's inter-sample predictor keeps its error at least 10x smaller."""
    m = observe_noiseless(tmp_path)
    assert m["eo", "depth", "late"] > 1e-3 and m["eo", "yaw", "late"] > np.deg2rad(0.1)
    assert m["cdo", "depth", "late"] < 0.1 * m["eo", "depth", "late"]
    assert m["cdo", "yaw", "late"] < 0.1 * m["eo", "yaw", "late"]


def test_scenario_files_place_the_events_where_the_paper_says():
    s1 = load_scenario(ROOT / "scenarios" / "rov_s1.yaml")
    c1 = load_scenario(ROOT / "scenarios" / "rov_s2_c1.yaml")
    c2 = load_scenario(ROOT / "scenarios" / "rov_s2_c2.yaml")
    s3 = load_scenario(ROOT / "scenarios" / "rov_s3.yaml")
    assert c1.depth_ref == s1.depth_ref and c1.payload.weight_fraction == 0.04 and c1.payload.floor_depth == 0.25
    assert (c2.damping_scale, c2.buoyancy_scale) == (1.9, 2.0) and c2.sensors == s1.sensors
    depth_at = [min_jerk(p.t_start, s3.depth_ref)[0] for p in s3.pushes if p.force[0]]
    yaw_at = [min_jerk(p.t_start, s3.yaw_ref_deg)[0] for p in s3.pushes if p.force[1]]
    assert depth_at == pytest.approx([0.19, 0.30, 0.24, 0.20, 0.20, 0.20, 0.20], abs=0.01)  # (a) (b) (c) (d1-d4)
    assert yaw_at == pytest.approx([60.0, 49.7, -60.0, -60.0], abs=1.0)  # (e) (f) (g1) (g2)
    weight = s3.vessel.mass * 9.81
    assert all(abs(max(p.force, key=abs)) == pytest.approx(0.25 * weight, rel=0.01) for p in s3.pushes if p.force[0])


def test_circular_scenario_reference_is_a_config_error(tmp_path):
    write(tmp_path, {"from": "b.yaml", "name": "a"}, "a.yaml")
    write(tmp_path, {"from": "a.yaml", "name": "b"}, "b.yaml")
    with pytest.raises(ConfigError, match="circular"):
        load_scenario(tmp_path / "a.yaml")


def test_recovery_time_counts_from_the_end_of_each_push():
    """Against the reference: the tracking error, the reference ``depth_ref`` of the world's truth less the depth
    (the estimate a run reports, here an observer's far off, does not count)."""
    far = {"depth": np.array([9.0])}
    rec = RecoveryTime({"depth": [1.0, 3.0]}, {"depth": 0.01}, window=1.5)
    errors = {0.5: 0.0, 1.0: 0.05, 1.5: 0.02, 2.0: 0.005, 3.0: 0.0, 3.5: 0.0}
    for k, (t, e) in enumerate(errors.items()):
        rec.update(k, t, {"depth": np.array([0.0]), "depth_ref": np.array([e])}, far)
    assert rec.value["depth"][0] == pytest.approx(0.5)  # out of the band until 1.5 s after the first push
    # a deviation of exactly tol is in the band; the window [t_e, t_e + window) leaves its end out
    edge = RecoveryTime({"depth": [1.0]}, {"depth": 0.25}, window=1.0)
    for k, (t, e) in enumerate([(0.5, 0.5), (1.0, 0.5), (1.5, 0.25), (2.0, 0.5)]):
        edge.update(k, t, {"depth": np.array([0.0]), "depth_ref": np.array([e])}, far)
    assert edge.value["depth"][0] == 0.0


def test_feedforward_needs_an_observer():
    with pytest.raises(ValueError, match="needs feedback"):
        ControllerSpec(kind="srise", disturbance_feedforward=True)


def test_output_scale_defaults_and_bounds():
    """The unit of tau (spec.DEFAULT_SCALE): RISE's SubjuGator gains in N and N m, S+RISE's Table II gains x40 in
    depth and x9.81 (kgf) in yaw, a custom class's own N and N m; 'inertia' is the nominal inertia; one number
    serves both DOFs; a scale must be positive."""
    inertia = np.array([63.0, 1.82])
    assert ControllerSpec(kind="rise").scale(inertia).tolist() == [1.0, 1.0]
    assert ControllerSpec(kind="srise").scale(inertia).tolist() == [40.0, 9.81]
    custom = ControllerSpec.model_construct(kind="custom")  # its scale needs no class to import
    assert custom.scale(inertia).tolist() == [1.0, 1.0]
    assert ControllerSpec(kind="srise", output_scale="inertia").scale(inertia).tolist() == [63.0, 1.82]
    assert ControllerSpec(kind="rise", output_scale=0.5).scale(inertia).tolist() == [0.5, 0.5]
    for bad in (0.0, -1.0, (1.0, 0.0), (-2.0, 9.81)):
        with pytest.raises(ValueError, match="output_scale must be positive"):
            ControllerSpec(kind="srise", output_scale=bad)


def test_source_and_params_are_for_custom_controllers_only():
    for settings in ({"params": {"kp": 1.0}}, {"source": "pid.py:Pid"}):
        with pytest.raises(ValueError, match="source and params are for custom controllers, not rise"):
            ControllerSpec(kind="rise", **settings)


def test_gain_overrides_are_checked_not_ignored():
    """A misspelt or out-of-range gain override is a config error (it used to be dropped silently)."""
    with pytest.raises(ValueError, match=r"depth: unknown srise gain\(s\) \['bogus'\]"):
        ControllerSpec(kind="srise", depth={"bogus": 1.0})
    with pytest.raises(ValueError, match=r"yaw\.delta1: Input should be less than or equal to 1"):
        ControllerSpec(kind="srise", yaw={"delta1": 2.0})
    with pytest.raises(ValueError, match=r"yaw: unknown rise gain\(s\) \['k0'\]"):
        ControllerSpec(kind="rise", yaw={"k0": 1.0})  # an S+RISE gain on RISE
    depth, yaw = ControllerSpec(kind="rise", preset="table2_equivalent", yaw={"ks": 3.0}).gains()
    assert yaw.ks == 3.0 and depth.ks == RISE_PRESETS["table2_equivalent"][0].ks


def test_multi_scenario_config_runs_each_variant_where_it_is_listed(tmp_path):
    exp, _ = load_experiment(ROOT / "configs" / "tijjani_table3.yaml", profile="quick")
    assert exp.scenario_names == ["S1", "S2-C1", "S2-C2", "S3"]
    assert [v.name for v in exp.part("S3").variants] == ["cdo_srise"]
    assert exp.part("S2-C2").scenario.name == "S2-C2" and exp.part("S2-C2").scenario.damping_scale == 1.9
    assert [f.file for f in exp.part("S3").figures] == ["fig9_s3.png"]
    with pytest.raises(ConfigError, match=r"variants\.0\.scenarios|unknown scenarios"):
        load_experiment(ROOT / "configs" / "tijjani_table3.yaml", ["variants.0.scenarios=[S9]"])
    with pytest.raises(ConfigError) as bad:
        exp2, _origins = load_experiment(ROOT / "configs" / "tijjani_table3.yaml", ["scenarios.S3.cdo.theta=200"])
        preflight(exp2, ROOT / "configs" / "tijjani_table3.yaml")
    assert "scenarios.S3.cdo" in str(bad.value) and "spectral radius" in str(bad.value)


@pytest.fixture(scope="module")
def s1_short():
    """The Table III controllers on S1, 20 s, one seed (the configs' quick horizon)."""
    exp, _ = load_experiment(ROOT / "configs" / "tijjani_table3.yaml", ["seeds=1", "scenarios.S1.horizon=20"])
    return run(exp.part("S1"))


def test_s1_orderings_that_hold_on_the_stand_in(s1_short):
    """Depth: RISE > S+RISE > CDO-S+RISE; yaw: CDO-S+RISE below S+RISE (Table III, S1)."""
    m = s1_short.metrics.set_index(["variant", "signal", "metric"])["value"]
    assert m["rise", "depth", "rmse"] > m["srise", "depth", "rmse"] > m["cdo_srise", "depth", "rmse"]
    assert m["cdo_srise", "yaw", "rmse"] < m["srise", "yaw", "rmse"]


def test_commands_respect_the_thruster_limits(s1_short):
    _, truth, _ = s1_short.traces
    from marinebench.models.rov import LeonardLike, LeonardLikeParams

    limits = LeonardLike(LeonardLikeParams()).limits
    assert np.abs(truth["tau_depth"]).max() <= limits[0] + 1e-9
    assert np.abs(truth["tau_yaw"]).max() <= limits[1] + 1e-9
    assert np.abs(truth["tau_depth"]).max() > 0.5 * limits[0]  # the limit is reached, so the check can bite


def test_table2_equivalent_rise_preset_is_srise_at_its_small_error_constants():
    from marinebench.controllers.rise import RISE_PRESETS, TABLE_II_DEPTH, TABLE_II_YAW

    for srise, rise in zip((TABLE_II_DEPTH, TABLE_II_YAW), RISE_PRESETS["table2_equivalent"]):
        assert rise.alpha1 == srise.alpha
        assert rise.ks == pytest.approx(srise.k0 * srise.eps1 ** (srise.delta1 - 1), rel=5e-3)
        assert rise.alpha2 == pytest.approx(srise.lambda0 * srise.eps3 ** (srise.delta2 - 1), rel=5e-3)


def test_bad_multi_scenario_input_is_one_line_naming_file_and_key(tmp_path):
    from typer.testing import CliRunner

    from marinebench.cli import app

    res = CliRunner().invoke(app, ["run", str(ROOT / "configs" / "tijjani_table3.yaml"), "--out", str(tmp_path / "o"),
                                   "--set", "variants[srise].scenarios=[S7]"])
    assert res.exit_code == 2
    # the cross-field check names its key, so the message names the --set that wrote it
    assert res.output.strip() == "error: --set: variants.1.scenarios: unknown scenarios ['S7'] (have: S1, S2-C1, S2-C2, S3)"
    res = CliRunner().invoke(app, ["validate", str(ROOT / "configs" / "tijjani_table3.yaml"), "--set", "variants=[]"])
    assert res.output.strip() == "error: --set: variants: List should have at least 1 item after validation, not 0"
    assert not (tmp_path / "o").exists()


def test_relative_row_compares_means_beside_the_papers_percentages():
    import pandas as pd

    from marinebench.results.tables import markdown_table

    exp, _ = load_experiment(ROOT / "configs" / "tijjani_observers.yaml")
    rows = [("S1", v, sig, "rmse", mean, np.nan, np.nan, 5, 0)
            for v, mean in (("cdo", 3.0), ("eo", 4.0)) for sig in ("depth", "yaw", "depth_meas", "yaw_meas")]
    summary = pd.DataFrame(rows, columns=["scenario", "variant", "signal", "metric", "mean", "ci_low", "ci_high", "n", "n_diverged"])
    line = next(ln for ln in markdown_table(exp, summary).splitlines() if ln.startswith("| cdo vs eo [%]"))
    assert line.split(" | ")[1:] == ["-25.0", "–", "-25.0", "–", "-25.0", "-45.4", "-25.0", "-24.7 |"]


def test_disturbance_feedforward_acts_on_the_chosen_dof_only(tmp_path):
    ctrl = {"kind": "srise", "output_scale": [40.0, 9.81], "feedback": "cdo"}
    doc = {"scenario": {"from": str(ROOT / "scenarios" / "rov_s1.yaml"), "horizon": 6.0}, "seeds": 1,
           "variants": [{"name": "plain", "controller": ctrl},
                        {"name": "yaw_ff", "controller": {**ctrl, "disturbance_feedforward": [False, True]}}],
           "metrics": [{"kind": "rmse", "t_start": 0.0, "signals": ["depth", "yaw"]}]}
    exp, _ = load_experiment(write(tmp_path, doc))
    m = run(exp, traces=False).metrics.set_index(["variant", "signal"])["value"]
    assert m["yaw_ff", "depth"] == m["plain", "depth"]  # heave and yaw are decoupled in the model
    assert abs(m["yaw_ff", "yaw"] - m["plain", "yaw"]) > 0.05 * m["plain", "yaw"]


def test_recovery_against_the_undisturbed_twin_ignores_the_manoeuvres_own_error():
    """A push during a turn: the tracking error stays large (the turn), the deviation from the same run
    without the push does not."""
    t = np.arange(0.0, 3.0, 0.5)
    truth = np.array([0.0, 0.5, 0.52, 0.53, 0.54, 0.55])  # turning, pushed off by 0.05 right after t = 0.5
    calm = np.array([0.0, 0.45, 0.50, 0.529, 0.54, 0.55])
    reference = truth - 0.1  # a 0.1 tracking error throughout the turn
    for against, expected in (("reference", 2.0), ("undisturbed", 0.5)):
        rec = RecoveryTime({"yaw": [0.5]}, {"yaw": 0.01}, window=2.5,
                           undisturbed={"yaw": calm[:, None]} if against == "undisturbed" else None)
        for k, tk in enumerate(t):
            rec.update(k, tk, {"yaw": truth[k : k + 1], "yaw_ref": reference[k : k + 1]}, {})
        assert rec.value["yaw"][0] == pytest.approx(expected)


def test_random_load_is_a_held_stationary_gauss_markov_sequence():
    from marinebench.rov_scenario import RovScenario, RovWorld

    sc = RovScenario(name="r", depth_ref=[(0, 0.0)], yaw_ref_deg=[(0, 0.0)], horizon=4000.0,
                     random_load={"std": [5.0, 0.5], "time_constant": 2.0, "period": 0.1})
    w = RovWorld(sc, 3, np.zeros(1, dtype=int), [(ControllerSpec(kind="rise"), [0])])
    seq = w.load_sequence[0]
    assert seq[:, 0].std() == pytest.approx(5.0, rel=0.1) and seq[:, 1].std() == pytest.approx(0.5, rel=0.1)
    lag = np.corrcoef(seq[:-20, 0], seq[20:, 0])[0, 1]  # 2 s apart: exp(-1)
    assert lag == pytest.approx(np.exp(-1.0), abs=0.08)
    x = np.zeros((1, 18))
    w.begin_step(0, 0.0, x)
    first = w.loads(0.0, x).copy()
    w.begin_step(49, 0.098, x)  # same 0.1 s period: same load
    assert np.array_equal(w.loads(0.098, x), first)
    w.begin_step(50, 0.1, x)
    assert not np.array_equal(w.loads(0.1, x), first)


def test_table_caption_says_what_each_error_is():
    """Controller-only variants are scored on the tracking error (their 'estimate' is the reference); observed
    variants on the observer's error."""
    from marinebench.results.tables import _window

    tracking, _ = load_experiment(ROOT / "configs" / "tijjani_table3.yaml")
    observed, _ = load_experiment(ROOT / "configs" / "tijjani_observers.yaml")
    assert "rmse of the tracking error (reference − actual)" in _window(tracking.part("S1"), "rmse")
    assert "rmse of est − truth" in _window(observed, "rmse")
    assert "from the first time the tracking error is within 0.01 (depth), 0.0175 (yaw)" in _window(tracking.part("S1"), "int")
    mixed = observed.model_copy(update={"variants": [*observed.variants, tracking.variants[0]]})
    assert "for controllers without an observer: reference − actual" in _window(mixed, "rmse")
    band = "recovery: largest time after a push until the vehicle stays within 0.01 (depth), 0.0175 (yaw) of "
    assert _window(tracking.part("S3"), "recovery") == band + "the same run without the pushes [s]"
    against_ref, _ = load_experiment(ROOT / "configs" / "tijjani_table3.yaml", ["metrics.2.against=reference"])
    assert _window(against_ref.part("S3"), "recovery") == band + "the reference [s]"


def test_a_one_scenario_table_states_the_papers_units_like_a_study_table():
    import pandas as pd

    from marinebench.results.tables import markdown_table

    exp, _ = load_experiment(ROOT / "configs" / "tijjani_observers.yaml",
                             ["table.paper.units={rmse/depth_meas: '% of the EO'}"])
    summary = pd.DataFrame([], columns=["scenario", "variant", "signal", "metric", "mean", "ci_low", "ci_high", "n", "n_diverged"])
    assert "(paper units: rmse/depth_meas: % of the EO)." in markdown_table(exp, summary)


def test_study_table_puts_each_papers_value_in_its_own_row():
    """Table III's paper columns: each cell is the paper's value for that scenario, metric and signal (the yaw rows
    carry the yaw values, not the depth ones); '–' where the paper has none (S3 for RISE and S+RISE)."""
    import pandas as pd

    from marinebench.results.tables import study_table

    exp, _ = load_experiment(ROOT / "configs" / "tijjani_table3.yaml")
    summary = pd.DataFrame([], columns=["scenario", "variant", "signal", "metric", "mean", "ci_low", "ci_high", "n", "n_diverged"])
    table = study_table(exp, summary)
    # columns: index, scenario, then (ours, paper) per variant: rise, srise, cdo_srise
    assert md_row(table, "rmse yaw [1e-2 rad]", "S2-C1")[3::2] == ["2.56", "1.54", "1.47"]
    assert md_row(table, "int depth [N² s]", "S1")[3::2] == ["291", "290", "296"]
    assert md_row(table, "rmse depth [1e-2 m]", "S3")[3::2] == ["–", "–", "1.94"]


def test_recovery_is_timed_per_signal_after_that_signals_own_pushes(tmp_path):
    """A push on depth alone: depth's recovery is timed from its end; yaw, pushed by nothing, has no recovery
    time (it would otherwise be scored after another signal's push)."""
    doc = {"scenario": {"from": str(ROOT / "scenarios" / "rov_s3.yaml"), "horizon": 6.0,
                        "pushes": [{"t_start": 2.0, "duration": 0.1, "force": [68.7, 0.0]}]},
           "seeds": 1, "variants": [{"name": "cdo_srise", "controller": {"kind": "srise", "feedback": "cdo"}}],
           "metrics": [{"kind": "recovery", "name": f"recovery_{against}", "tol": {"depth": 0.01, "yaw": 0.0175},
                        "window": 3.0, "against": against} for against in ("reference", "undisturbed")]}
    exp, _ = load_experiment(write(tmp_path, doc))
    m = run(exp, traces=False).metrics
    for against in ("reference", "undisturbed"):  # undisturbed: against the same run without the push
        rec = m[m["metric"] == f"recovery_{against}"]
        assert rec["signal"].tolist() == ["depth"] and 0 < rec["value"].iloc[0] < 3.0
    one = np.zeros(1, dtype=int)
    for rec in _recorders(exp, one, one, steps(exp)):  # timed from the push's end, 2.0 + 0.1 s
        assert list(rec.events) == ["depth"] and rec.events["depth"] == [pytest.approx(2.1)]


def test_recovery_during_a_turn_is_timed_against_the_twin_only_when_asked(tmp_path):
    """S3's push (f) during the 60 -> -60 deg turn: against the reference the turn's own tracking error (degrees)
    keeps yaw out of the 1 deg band long after the push, against the undisturbed twin it does not."""
    doc = {"scenario": {"from": str(ROOT / "scenarios" / "rov_s3.yaml"), "horizon": 24.0,
                        "pushes": [{"t_start": 18.2, "duration": 0.1, "force": [0.0, -20.6]}]},
           "seeds": 1, "variants": [{"name": "srise", "controller": {"kind": "srise"}}],
           "metrics": [{"kind": "recovery", "name": f"recovery_{against}", "tol": {"yaw": 0.0175}, "window": 5.0,
                        "against": against, "signals": ["yaw"]} for against in ("reference", "undisturbed")]}
    exp, _ = load_experiment(write(tmp_path, doc))
    m = run(exp, traces=False).metrics.set_index("metric")["value"]
    assert m["recovery_undisturbed"] + 1.0 < m["recovery_reference"], m


def test_every_output_names_the_leonard_like_model(tmp_path, monkeypatch):
    """The issue asks for the name ``leonard_like`` in every output: each table.md, claims.md and manifest and
    every figure's title, of runs and of one-at-a-time and grid sweeps (their titles come from the code, not
    from the configs' own wording)."""
    import json

    from matplotlib.figure import Figure
    from typer.testing import CliRunner

    from marinebench.cli import app

    titles = []
    save = Figure.savefig
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: (titles.append(fig._suptitle.get_text()),
                                                                save(fig, *a, **k))[1])
    short = ["--set", "seeds=1"] + [x for s in ("S1", "S2-C1", "S2-C2", "S3") for x in ("--set", f"scenarios.{s}.horizon=4")]
    commands = [
        ["run", str(ROOT / "configs" / "tijjani_table3.yaml"), *short],
        ["run", str(ROOT / "configs" / "tijjani_observers.yaml"), "--set", "seeds=1", "--set", "scenario.horizon=6"],
        ["sweep", "--config", str(ROOT / "configs" / "tijjani_table3.yaml"), "yaw_alpha", "--n", "2", "--horizon", "4",
         "--seeds", "1"],
        ["sweep", "--config", str(ROOT / "configs" / "tijjani_table3.yaml"), "yaw_alpha", "yaw_k0", "--grid", "--n", "2",
         "--horizon", "4", "--seeds", "1"],
    ]
    for i, args in enumerate(commands):
        res = CliRunner().invoke(app, [*args, "--out", str(tmp_path / str(i)), "--quiet"])
        assert res.exit_code == 0, res.output
    dirs = sorted(p.parent for p in tmp_path.rglob("manifest.json"))
    assert len(dirs) == 4 and len(titles) == sum(len(list(d.glob("figures/*.png"))) for d in dirs) >= 4
    for d in dirs:
        assert json.loads((d / "manifest.json").read_text())["model"] == "leonard_like", d
        for md in [d / "table.md", *d.glob("claims.md")]:
            assert "Simulated on the model `leonard_like`." in md.read_text(), md
    assert len(list(tmp_path.rglob("claims.md"))) >= 2  # the two runs' (the configs' sweeps may have no claims)
    assert all("model leonard_like" in t for t in titles), titles


def test_cdo_and_eo_defaults_are_table_ii_and_the_documented_choices():
    """theta = 24.39 and K_w = 0.1 are Table II's; K* from LMI (40) at mu = 0.35 and the EO at eps = 1/theta with
    binomial a = (3, 3, 1) are this package's documented choices (baselines.md 9.4, README)."""
    from marinebench.observers.cdo import CdoParams, EoParams

    cdo, eo = CdoParams(), EoParams()
    assert (cdo.theta, cdo.k_w, cdo.k_star, cdo.lmi_decay) == (24.39, 0.1, "lmi", 0.35)
    assert (eo.eps, eo.a) == (0.041, (3.0, 3.0, 1.0))
    assert eo.eps == pytest.approx(1 / cdo.theta, rel=2e-3)
    assert cdo.gain() == design_lmi(0.35).k_star
    with pytest.raises(ValueError, match="theta"):
        CdoParams(theta=0.0)
    assert CdoParams(theta=0.5).theta == 0.5  # a slow observer is a tuning, not an error
    for params, key in ((CdoParams, "thetaa"), (EoParams, "epsilon")):  # a scenario's cdo:/eo: blocks are strict
        with pytest.raises(ValueError, match=key):
            params(**{key: 1.0})


@pytest.mark.parametrize("k_star", ["binomial", (1.0, 2.0, 0.5)])
def test_cdo_injection_is_delta_theta_times_k_star(k_star):
    """Delta_theta K* = diag(theta, theta^2, theta^3) K* (eq. 38); the EO's gain is [a1/eps, a2/eps^2, a3/eps^3]."""
    from marinebench.observers.cdo import CdoParams, EoParams

    cdo = CdoParams(theta=2.0, k_star=k_star)
    k = np.array(BINOMIAL if k_star == "binomial" else k_star)
    assert cdo.gain() == tuple(k)
    np.testing.assert_allclose(cdo.injection(), [2 * k[0], 4 * k[1], 8 * k[2]], rtol=1e-15)
    np.testing.assert_allclose(EoParams(eps=0.5, a=(1.0, 2.0, 3.0)).gain(), [2.0, 8.0, 24.0], rtol=1e-15)


def test_cdo_and_eo_fastest_poles_are_those_of_their_flows():
    """The step check's rates: the EO's |poles| are those of its companion matrix (computed from a over eps, so an
    extreme eps gives a huge rate, not an overflow); the CDO's the eigenvalues of its flow with the predictor."""
    from marinebench.design.cdo import sampled_flow
    from marinebench.observers.cdo import CdoParams, EoParams

    eo = EoParams(eps=0.05, a=(6.0, 11.0, 6.0))  # poles -1/eps, -2/eps, -3/eps
    assert eo.max_rate() == pytest.approx(60.0, rel=1e-12)
    g = eo.gain()
    companion = np.array([[-g[0], 1, 0], [-g[1], 0, 1], [-g[2], 0, 0]])
    assert eo.max_rate() == pytest.approx(np.abs(np.linalg.eigvals(companion)).max(), rel=1e-9)
    assert EoParams(eps=1e-300).max_rate() == pytest.approx(1e300, rel=1e-4)
    cdo = CdoParams()
    assert cdo.max_rate() == pytest.approx(np.abs(np.linalg.eigvals(sampled_flow(cdo.injection(), cdo.k_w))).max())
    assert CdoParams(theta=1e300).max_rate() == np.inf


@pytest.mark.parametrize("settings,key", [({"cdo": {"thetaa": 30.0}}, "thetaa"), ({"eo": {"epsilon": 0.1}}, "epsilon"),
                                          ({"cdo": {"theta": -1.0}}, "theta"), ({"k_w": 0.2}, "k_w")])
def test_a_variants_observer_settings_are_checked_not_ignored(settings, key):
    """A misspelt or out-of-range CDO/EO setting, or one outside its block, is refused where the variant is read."""
    from marinebench.observers.cdo import RovObserverSpec

    with pytest.raises(ValueError, match=key):
        RovObserverSpec(kind="cdo", **settings)
