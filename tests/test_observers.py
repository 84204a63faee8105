"""Open-loop ASV observers: named outputs, mixed tunings in one batch, and the noise transfer behind Table IV
(their convergence is in the registry-wide conformance suite, tests/test_conformance.py)."""

import numpy as np
import pytest

from marinebench.design.lmi import A_PSI, C_PSI
from marinebench.experiments.runner import noise_parts
from marinebench.observers.base import chain_response, wrap_angle
from marinebench.observers.bejarano import BejaranoObserver, BejaranoTuning
from marinebench.observers.liu_eso import LiuEsoObserver, LiuEsoTuning, fal
from marinebench.scenario import OpenLoopASV, Scenario, stream_rngs
from marinebench.sensors.noise import BandLimitedUniform
from marinebench.sim.engine import ObserverGroup, simulate
from marinebench.sim.recorders import ErrorMoments

SIGNALS = ["u", "v", "r", "sigma_u", "sigma_v", "sigma_r"]
CONSTANT = {"kind": "constant"}


def steady_world(seeds: int = 1) -> OpenLoopASV:
    """Constant thrust, torque and environment: the vessel settles in a steady turn, so sigma is constant."""
    sc = Scenario(
        name="steady",
        horizon=40.0,
        dt=0.005,
        inputs={"F_u": {**CONSTANT, "value": 3.0}, "tau_r": {**CONSTANT, "value": 0.1}},
        disturbances={"F_wu": {**CONSTANT, "value": 0.3}, "F_wv": {**CONSTANT, "value": -0.2},
                      "tau_wr": {**CONSTANT, "value": 0.02}},
    )
    return OpenLoopASV(sc, 0, np.zeros(seeds, dtype=int))


@pytest.mark.parametrize("observer, tuning, columns", [
    (LiuEsoObserver, LiuEsoTuning, [3, 4, 5, 6, 7, 8]),  # [eta_hat, nu_hat, sigma_hat]
    (BejaranoObserver, BejaranoTuning, [5, 6, 1, 7, 8, 2]),  # [psi, r, sigma_r, x, y, u, v, sigma_u, sigma_v]
])
def test_observer_starts_at_zero_and_outputs_its_named_state_columns(observer, tuning, columns):
    """Estimates start at 0 (Bejarano s.V), one 9-state row per run; u, v, r, sigma_u, sigma_v, sigma_r are read
    from the columns of each observer's state layout."""
    obs = observer([tuning(), tuning()], steady_world().plant.Minv)
    x0 = obs.init()
    assert obs.n_state == 9
    np.testing.assert_array_equal(x0, np.zeros((2, 9)))
    xhat = np.arange(18.0).reshape(2, 9)
    out = obs.outputs(xhat)
    assert list(out) == SIGNALS == list(obs.signals)
    for name, col in zip(SIGNALS, columns):
        np.testing.assert_array_equal(out[name], xhat[:, col])


def test_bejarano_derivative_is_eqs_13_14_with_eq_26_per_run():
    """One evaluation of the right-hand side, written out with matrices for two tunings in one batch: eq. (13)
    with chi_psi = [psi, r, sigma_r], eq. (14) with chi_p = [x, y, u, v, sigma_u, sigma_v] and the scheduled
    gain L_p(psi) = -blkdiag(R2, I, I) L_pz R2^T(psi) of eq. (26); headings far from 0, innovations wrapped."""
    Minv = steady_world().plant.Minv
    obs = BejaranoObserver([BejaranoTuning(delta_psi1=1.2, delta_p1=1.2, k_n=1), BejaranoTuning(delta_psi1=2.0)], Minv)
    rng = np.random.default_rng(4)
    xhat = obs.init() + rng.normal(size=(2, 9))
    assert xhat.shape == (2, 9)
    xhat[:, 0] = [3.0, -2.9]  # psi_hat: psi - psi_hat wraps past pi in both runs
    y = np.column_stack([rng.normal(size=(2, 2)), [-2.9, 3.0]])  # [x, y, psi]
    tau = rng.normal(size=(2, 3))
    got = obs.derivative(xhat, y, tau)
    for b in range(2):
        psi, acc = y[b, 2], Minv @ tau[b]
        inn = wrap_angle(np.array(psi - xhat[b, 0]))
        assert abs(inn) < 1.0
        rot = A_PSI @ xhat[b, :3] + np.array([0, acc[2], 0]) + obs.L_psi[b] * inn
        c, s = np.cos(psi), np.sin(psi)
        R2 = np.array([[c, -s], [s, c]])
        A_p = np.zeros((6, 6)); A_p[0:2, 2:4] = R2; A_p[2:4, 4:6] = np.eye(2)
        T_inv = np.eye(6); T_inv[0:2, 0:2] = R2
        L_p = -T_inv @ obs.L_pz[b] @ R2.T
        pos = A_p @ xhat[b, 3:] + np.r_[0, 0, acc[:2], 0, 0] + L_p @ (y[b, :2] - xhat[b, 3:5])
        np.testing.assert_allclose(got[b], np.r_[rot, pos], rtol=1e-12, atol=1e-12)


def test_bejarano_max_rate_is_its_fastest_pole_of_either_subsystem():
    """The engine's step-size check sees the fastest pole, whichever subsystem has it (Table III's delta = 300/400)."""
    Minv = steady_world().plant.Minv
    fast_p = BejaranoObserver([BejaranoTuning(), BejaranoTuning(delta_p1=400)], Minv)
    fast_psi = BejaranoObserver([BejaranoTuning(delta_psi1=300)], Minv)
    assert fast_p.max_rate() == pytest.approx(np.abs(fast_p.designs[1][1].poles).max())
    assert fast_p.max_rate() > 400
    rot = fast_psi.designs[0][0]
    assert fast_psi.max_rate() == pytest.approx(np.abs(np.linalg.eigvals(A_PSI - rot.gain @ C_PSI)).max())
    assert fast_psi.max_rate() > 300


def test_liu_tunings_of_different_modes_share_a_batch():
    """Linear and fal Liu ESOs (with different alpha) in one batch: each run's derivative is its own."""
    tunings = [LiuEsoTuning(eps=0.1), LiuEsoTuning(eps=0.2, mode="fal"), LiuEsoTuning(eps=0.1, mode="fal", alpha=0.8)]
    Minv = steady_world().plant.Minv
    g = np.random.default_rng(3)
    xhat, y, tau = g.normal(size=(3, 9)), g.normal(size=(3, 3)), g.normal(size=(3, 3))
    together = LiuEsoObserver(tunings, Minv).derivative(xhat, y, tau)
    for b, t in enumerate(tunings):
        alone = LiuEsoObserver([t], Minv).derivative(xhat[b : b + 1], y[b : b + 1], tau[b : b + 1])
        np.testing.assert_array_equal(together[b], alone[0])
    assert not np.allclose(together[1], LiuEsoObserver([tunings[1].model_copy(update={"mode": "linear"})], Minv)
                           .derivative(xhat[1:2], y[1:2], tau[1:2])[0])


def test_liu_fal_corrections_are_homogeneous_of_degrees_alpha_2alpha_minus_1_3alpha_minus_2():
    """Outside fal's linear zone the three corrections scale with the output error as |e|^alpha, |e|^(2 alpha - 1)
    and |e|^(3 alpha - 2), the weights of the homogeneous finite-time form (baselines.md s.1). Read off the
    derivative at psi = 0 with nu_hat = sigma_hat = 0 and tau = 0: it is (-g1, -g2, -g3)."""
    alpha = 0.8
    obs = LiuEsoObserver([LiuEsoTuning(eps=1.0, mode="fal", alpha=alpha, fal_d=0.01)], steady_world().plant.Minv)
    y, tau = np.zeros((1, 3)), np.zeros((1, 3))

    def corrections(e_x: float) -> np.ndarray:
        xhat = np.zeros((1, 9))
        xhat[0, 0] = e_x  # eta_hat - y along x only
        d = obs.derivative(xhat, y, tau)[0]
        return -d[[0, 3, 6]]

    small, large = corrections(0.5), corrections(5.0)
    assert np.all(small > 0)
    np.testing.assert_allclose(np.log10(large / small), [alpha, 2 * alpha - 1, 3 * alpha - 2], rtol=1e-12)


def test_liu_linear_derivative_is_the_eps_scaled_eso_written_out():
    """baselines.md s.1.2, linear mode, for two tunings in one batch: eta_hat' = R(psi) nu_hat - k1/eps eta_tilde,
    nu_hat' = M^-1 tau + sigma_hat - k2/eps^2 R^T(psi) eta_tilde, sigma_hat' = -k3/eps^3 R^T(psi) eta_tilde, with
    eta_tilde = eta_hat - y and its heading wrapped (headings near +-pi)."""
    Minv = steady_world().plant.Minv
    tunings = [LiuEsoTuning(eps=0.2), LiuEsoTuning(eps=0.5, k=(4.0, 5.0, 2.0))]
    obs = LiuEsoObserver(tunings, Minv)
    rng = np.random.default_rng(5)
    xhat, tau = rng.normal(size=(2, 9)), rng.normal(size=(2, 3))
    xhat[:, 2] = [3.0, -2.9]
    y = np.column_stack([rng.normal(size=(2, 2)), [-2.9, 3.0]])
    got = obs.derivative(xhat, y, tau)
    for b, t in enumerate(tunings):
        c, s = np.cos(y[b, 2]), np.sin(y[b, 2])
        R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        e = xhat[b, :3] - y[b]
        e[2] = wrap_angle(np.array(e[2]))
        assert abs(e[2]) < 1.0
        k1, k2, k3 = t.k
        want = np.r_[R @ xhat[b, 3:6] - k1 / t.eps * e,
                     Minv @ tau[b] + xhat[b, 6:9] - k2 / t.eps**2 * R.T @ e,
                     -k3 / t.eps**3 * R.T @ e]
        np.testing.assert_allclose(got[b], want, rtol=1e-12, atol=1e-12)


def test_liu_fal_with_alpha_one_is_the_linear_mode():
    """baselines.md s.1.2: with alpha = 1 the homogeneous form reduces exactly to the linear mode (eps k1 e/eps^2 =
    k1 e/eps, ...), inside and outside fal's linear zone."""
    Minv = steady_world().plant.Minv
    rng = np.random.default_rng(6)
    xhat, y, tau = rng.normal(size=(2, 9)), rng.normal(size=(2, 3)), rng.normal(size=(2, 3))
    xhat[0, :3] = y[0] + 1e-5  # scaled error 1e-5/eps^2 = 2.5e-4 inside |e_s| <= fal_d = 0.01
    linear = LiuEsoObserver([LiuEsoTuning(eps=0.2)] * 2, Minv).derivative(xhat, y, tau)
    fal1 = LiuEsoObserver([LiuEsoTuning(eps=0.2, mode="fal", alpha=1.0)] * 2, Minv).derivative(xhat, y, tau)
    np.testing.assert_allclose(fal1, linear, rtol=1e-12, atol=1e-12)


def test_fal_is_linear_with_slope_d_to_alpha_minus_one_inside_its_zone_and_continuous_at_its_edge():
    alpha, d = 0.8, 0.01
    x = np.array([0.004, -0.009, 0.0])
    np.testing.assert_allclose(fal(x, alpha, d), x * d ** (alpha - 1), rtol=1e-14)
    edge = np.array([d, -d])
    np.testing.assert_allclose(fal(edge * (1 + 1e-12), alpha, d), np.sign(edge) * d**alpha, rtol=1e-10)
    np.testing.assert_allclose(fal(edge * (1 - 1e-12), alpha, d), np.sign(edge) * d**alpha, rtol=1e-10)
    np.testing.assert_allclose(fal(np.array([-0.5]), alpha, d), [-(0.5**alpha)], rtol=1e-14)


def test_liu_max_rate_is_the_fastest_pole_over_the_batch():
    """The poles of s^3 + k1/eps s^2 + k2/eps^2 s + k3/eps^3 are the roots of k's polynomial over eps: a triple
    pole at -1/eps for k = (3, 3, 1) (Table III's eps = 0.006 gives 167 1/s), -1, -2, -3 over eps for (6, 11, 6)."""
    Minv = steady_world().plant.Minv
    triple = LiuEsoObserver([LiuEsoTuning(eps=0.1), LiuEsoTuning(eps=0.006)], Minv)
    assert triple.max_rate() == pytest.approx(1 / 0.006, rel=1e-4)
    distinct = LiuEsoObserver([LiuEsoTuning(eps=0.5, k=(6.0, 11.0, 6.0)), LiuEsoTuning(eps=1.0)], Minv)
    assert distinct.max_rate() == pytest.approx(3 / 0.5, rel=1e-9)


def test_liu_tuning_defaults_and_bounds():
    """baselines.md s.1.2: eps = 0.1 (Table III's slower row), k = (3, 3, 1), linear mode, alpha = 0.95 in
    (2/3, 1], fal's linear zone d = 0.01; eps and d positive; unknown keys refused."""
    t = LiuEsoTuning()
    assert (t.eps, t.k, t.mode, t.alpha, t.fal_d) == (0.1, (3.0, 3.0, 1.0), "linear", 0.95, 0.01)
    LiuEsoTuning(alpha=1.0)
    LiuEsoTuning(alpha=0.67)
    for bad in ({"eps": 0.0}, {"alpha": 2 / 3}, {"alpha": 1.01}, {"fal_d": 0.0}, {"epsilon": 0.1}):
        with pytest.raises(ValueError):
            LiuEsoTuning(**bad)


def test_wrap_angle():
    a = np.array([0.0, np.pi, -np.pi, 3 * np.pi / 2, -7.0])
    w = wrap_angle(a)
    assert np.all(w <= np.pi) and np.all(w > -np.pi)
    np.testing.assert_allclose(np.cos(w), np.cos(a), atol=1e-12)


NOISE = {"kind": "bandlimited_uniform", "bound": 0.2, "f_low": 0.1, "f_high": 0.5, "n_components": 40, "rms": 0.0327}


def at_rest(noise=None) -> Scenario:
    """A vessel at rest at the origin, no input, no environment; position noise ``noise`` (or none)."""
    zero = {**CONSTANT, "value": 0.0}
    return Scenario(name="rest", horizon=40.0, dt=0.005, initial={"eta": (0.0, 0.0, 0.0)},
                    sensors={"position_noise": noise} if noise else {}, inputs={"F_u": zero, "tau_r": zero},
                    disturbances={"F_wu": zero, "F_wv": zero, "tau_wr": zero})


def test_noisy_errors_are_the_observers_noise_transfer_sampled_by_the_multisine():
    """Table IV's mechanism, end to end: on a vessel at rest (psi = 0, no input) the u and sigma_u errors are
    the position noise through each observer's linear chain, so their simulated std equals the steady-state
    response of that chain to the seed's multisine components, computed on the same time grid. This checks the
    noise generator, both observers' positional channels with their designed gains, the engine and the std
    recorder against closed-form linear theory (README, Table IV)."""
    sc = at_rest(NOISE)
    seeds = np.array([0, 1])
    liu = [LiuEsoTuning(eps=0.2), LiuEsoTuning(eps=0.1)]
    prop = [BejaranoTuning(delta_psi1=d, delta_p1=d, k_omega=1, k_n=1) for d in (1.2, 2.2)]
    world = OpenLoopASV(sc, 11, np.tile(seeds, 4))
    runs = np.arange(8)
    observers = [LiuEsoObserver(liu[:1] * 2 + liu[1:] * 2, world.plant.Minv),
                 BejaranoObserver(prop[:1] * 2 + prop[1:] * 2, world.plant.Minv)]
    window = ErrorMoments(["u", "sigma_u"], t_start=20.0)
    simulate(world, [ObserverGroup(observers[0], runs[:4]), ObserverGroup(observers[1], runs[4:])], sc.dt, 8000, [window])
    std = window.result("std")

    gains = [(3 / t.eps, 3 / t.eps**2, 1 / t.eps**3) for t in liu]
    gains += [tuple(-observers[1].L_pz[2 * i, [0, 2, 4], 0]) for i in range(2)]  # x-channel of -L_pz
    noise = sc.sensors.position_noise.sample(stream_rngs(11, list(seeds), "position_noise"), 2)
    t = np.arange(4000, 8001) * sc.dt
    for run in runs:
        omega, phase = noise.omega[seeds[run % 2], 0], noise.phase[seeds[run % 2], 0]  # channel 0: the x (north) noise, which is e_u's at psi = 0
        for name, H in zip(("u", "sigma_u"), chain_response(gains[run // 2], omega)):
            e = (noise.amplitude * np.abs(H) * np.sin(np.outer(t, omega) + phase + np.angle(H))).sum(axis=1)
            assert std[name][run] == pytest.approx(e.std(), rel=1e-5), (run, name)


@pytest.mark.parametrize("spacing", ["uniform", "log"])
def test_response_std_is_the_expected_std_over_the_noise_draws(spacing):
    """A multisine's steady-state response has variance rms^2 mean_k |H(omega_k)|^2; its mean over many draws of
    the component frequencies is what ``response_std`` integrates."""
    noise = BandLimitedUniform(**{**NOISE, "spacing": spacing})
    gains = (3 / 0.2, 3 / 0.2**2, 1 / 0.2**3)
    batch = noise.sample([np.random.default_rng(s) for s in range(400)], 1)
    for i in range(2):
        H = chain_response(gains, batch.omega)[i]  # (draws, 1, K)
        simulated = np.sqrt(np.mean(np.sum((noise.std * np.sqrt(2 / noise.n_components) * np.abs(H)) ** 2 / 2, axis=-1)))
        assert noise.response_std(lambda w, i=i: chain_response(gains, w)[i]) == pytest.approx(simulated, rel=0.01)


def test_noise_part_of_a_very_fast_observer_is_the_noise_derivative():
    """Closed form: an observer far faster than the band passes the noise's derivative into its velocity
    estimate, whose std is rms sqrt(E omega^2) with omega uniform over the band."""
    eps = 1e-3
    parts = noise_parts(at_rest(NOISE), {"u": (3 / eps, 3 / eps**2, 1 / eps**3)})
    w1, w2 = 2 * np.pi * NOISE["f_low"], 2 * np.pi * NOISE["f_high"]
    assert parts["noise_part_std_u"] == pytest.approx(NOISE["rms"] * np.sqrt((w2**3 - w1**3) / (3 * (w2 - w1))), rel=1e-3)
    assert noise_parts(at_rest(), {"u": (1.0, 1.0, 1.0)}) == {}


def test_manifest_designs_carry_each_observers_noise_part(tmp_path):
    """``design_summary`` (the manifest's ``designs``) predicts, per variant and axis, the noise part of the velocity and
    disturbance errors from the designed gains: Liu's from (3/eps, 3/eps^2, 1/eps^3), Bejarano's from -L_pz."""
    import marinebench as mb
    from marinebench.experiments.runner import design_summary

    from .conftest import write_tiny

    exp = mb.load(write_tiny(tmp_path))
    designs = design_summary(exp)
    noise = exp.scenario.sensors.position_noise
    liu = designs["liu_eps0.2"]
    assert liu["noise_part_std_u"] == liu["noise_part_std_v"] == noise.response_std(lambda w: chain_response(liu["gains"], w)[0])
    prop = designs["proposed_d1.2"]
    L = -np.asarray(prop["L_pz"])
    for axis, rows, col in (("u", [0, 2, 4], 0), ("v", [1, 3, 5], 1)):
        for i, name in enumerate((axis, f"sigma_{axis}")):
            assert prop[f"noise_part_std_{name}"] == noise.response_std(lambda w, i=i, g=L[rows, col]: chain_response(g, w)[i])
    assert prop["noise_part_std_sigma_u"] < liu["noise_part_std_sigma_u"]  # delta = 1.2 filters sigma more than eps = 0.2
