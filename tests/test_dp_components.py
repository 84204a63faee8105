"""Torben DP building blocks: supply vessel, bis units, JONSWAP, Gauss-Markov, notch, Kalman gains, FTO."""

import numpy as np
import pytest
from scipy.integrate import trapezoid  # numpy has it only from 2.0
from scipy.linalg import expm
from scipy.signal import freqz, lfilter

from marinebench.design.kalman import C_DP, DpGains, dp_system, gain_at, kalman_gains
from marinebench.environment.waves import dnv_gamma, jonswap
from marinebench.models.supply import SupplyVessel, SupplyVesselParams, bis_scale
from marinebench.observers.dp import SIGNALS, DpObserver, ResettingTuning
from marinebench.observers.fto import fto_jump, rk4_maps
from marinebench.sensors.gauss_markov import gm_step, stationary_std
from marinebench.sensors.notch import Biquad, tustin_notch

from .conftest import accepts_and_refuses

VESSEL = SupplyVessel(SupplyVesselParams())
Q1, R1 = np.diag([50.0, 50.0, 10.0]), np.diag([15.0, 15.0, 1.0])


def test_supply_vessel_matrices_match_published_values():
    np.testing.assert_allclose(VESSEL.M, [[6.7644e6, 0, 0], [0, 1.13412e7, -3.40157e7], [0, -3.40157e7, 4.45238e9]], rtol=1e-4)
    np.testing.assert_allclose(VESSEL.D, [[7.7071e4, 0, 0], [0, 2.54679e5, -2.03416e6], [0, -6.72585e5, 3.85007e8]], rtol=1e-4)
    tc = np.sort(-1 / np.linalg.eigvals(-np.linalg.solve(VESSEL.M, VESSEL.D)).real)
    np.testing.assert_allclose(tc, [11.5, 44, 88], rtol=0.05)


def test_bis_units():
    s = bis_scale(SupplyVesselParams())
    np.testing.assert_allclose(s[[0, 3, 5, 6, 8]], [76.2, 5.886e7, 4.485e9, 27.34, 0.3588], rtol=1e-3)


def test_jonswap_hs_recovered():
    w = np.linspace(0.05, 6.0, 20000)
    for gamma in (1.0, 3.3, dnv_gamma(2.0, 6.3)):
        m0 = trapezoid(jonswap(w, 2.0, 6.3, gamma), w)
        assert abs(4 * np.sqrt(m0) - 2.0) < 0.03
    assert abs(dnv_gamma(2.0, 6.3) - 1.87) < 0.01
    assert abs(jonswap(np.array([2 * np.pi / 6.3]), 2.0, 6.3, 3.3)[0] - 0.779) < 0.01


def test_dnv_gamma_in_each_band_of_tp_over_sqrt_hs():
    """DNV-RP-C205: gamma = 5 up to and at Tp/sqrt(Hs) = 3.6, exp(5.75 - 1.15 Tp/sqrt(Hs)) up to 5, 1 beyond."""
    assert dnv_gamma(4.0, 6.0) == dnv_gamma(1.0, 3.6) == 5.0  # Tp/sqrt(Hs) = 3 and exactly 3.6
    assert dnv_gamma(1.0, 4.0) == pytest.approx(np.exp(5.75 - 4.6))
    assert dnv_gamma(1.0, 5.0) == pytest.approx(1.0) and dnv_gamma(1.0, 8.0) == 1.0
    assert dnv_gamma(1.0, 3.6 + 1e-9) == pytest.approx(5.0, rel=1e-2)  # continuous at the bands' edges


def test_jonswap_peak_is_narrower_below_the_peak_frequency():
    """DNV's peak enhancement gamma^exp(-(w - w0)^2 / (2 s^2 w0^2)), s = 0.07 below w0 and 0.09 above, over the
    Pierson-Moskowitz shape (gamma = 1) and the normalisation 1 - 0.287 ln gamma: one width from the peak on either
    side the enhancement is gamma^exp(-1/2)."""
    gamma, tp = 3.3, 6.3
    w0 = 2 * np.pi / tp
    w = np.array([w0 * (1 - 0.07), w0, w0 * (1 + 0.09)])
    enhancement = jonswap(w, 2.0, tp, gamma) / jonswap(w, 2.0, tp, 1.0) / (1 - 0.287 * np.log(gamma))
    np.testing.assert_allclose(enhancement, [gamma ** np.exp(-0.5), gamma, gamma ** np.exp(-0.5)], rtol=1e-12)


def test_jonswap_written_out_off_the_unit_values():
    """The module docstring's S(w) at Hs = 3.5 m, Tp = 9 s (w0 = 0.698 rad/s), gamma = 2.5, on both sides of the
    peak: (1 - 0.287 ln gamma) (5/16) Hs^2 w0^4 w^-5 exp(-5/4 (w0/w)^4) gamma^exp(-(w - w0)^2 / (2 s^2 w0^2))."""
    hs, tp, gamma = 3.5, 9.0, 2.5
    w0, w = 2 * np.pi / tp, np.array([0.45, 0.65, 0.75, 1.3])
    sig = np.where(w <= w0, 0.07, 0.09)
    want = ((1 - 0.287 * np.log(gamma)) * 5 / 16 * hs**2 * w0**4 * w**-5 * np.exp(-1.25 * (w0 / w) ** 4)
            * gamma ** np.exp(-((w - w0) ** 2) / (2 * sig**2 * w0**2)))
    np.testing.assert_allclose(jonswap(w, hs, tp, gamma), want, rtol=1e-12)
    np.testing.assert_allclose(jonswap(w, hs, tp), jonswap(w, hs, tp, 3.3), rtol=0)  # gamma defaults to 3.3


def test_dnv_gamma_in_its_three_regimes_and_no_energy_at_zero_frequency():
    """DNV-RP-C205's gamma from k = Tp / sqrt(Hs): 5 for k <= 3.6, exp(5.75 - 1.15 k) up to k = 5, 1 above; the
    spectrum is 0 at w = 0 (and below), not the 0 x inf of w^-5 exp(-w0^4 / w^4)."""
    assert dnv_gamma(4.0, 7.0) == 5.0  # k = 3.5
    assert dnv_gamma(4.0, 8.0) == pytest.approx(np.exp(5.75 - 1.15 * 4.0), rel=1e-12)  # k = 4
    assert dnv_gamma(1.0, 6.0) == 1.0  # k = 6
    assert dnv_gamma(1.0, 5.0) == pytest.approx(1.0, rel=1e-12)  # continuous at k = 5
    s = jonswap(np.array([-1.0, 0.0, 1e-3]), 2.0, 6.3)
    assert s.tolist() == [0.0, 0.0, 0.0] and np.isfinite(s).all()


def test_gauss_markov_stationary_std():
    rng = np.random.default_rng(0)
    c, ts, sigma = 1 / 20.0, 1.0, 0.5  # short time constant so the test reaches stationarity quickly
    v = np.zeros(4000)
    for _ in range(600):
        v = gm_step(v, sigma, c, ts, rng.standard_normal(v.shape))
    assert abs(v.std() / stationary_std(sigma, c, ts) - 1) < 0.05
    assert abs(stationary_std(1.0, 1 / 1100, 1.0) - 23.46) < 0.05
    # eq. (48) written out at a sample time other than 1 s: v+ = exp(-c Ts) v + sigma rho, per run's own sigma
    v, rho, sig = np.array([0.4, -1.0]), np.array([0.3, 0.7]), np.array([0.5, 2.0])
    np.testing.assert_allclose(gm_step(v, sig, 0.05, 0.5, rho), np.exp(-0.025) * v + sig * rho, rtol=1e-15)
    assert stationary_std(0.3, 0.05, 0.5) == pytest.approx(0.3 / np.sqrt(1 - np.exp(-0.05)), rel=1e-14)


def test_notch_gain():
    b, a = tustin_notch(1.0, 0.5, 1.0)
    _w, h = freqz(b, a, worN=np.array([0.1, 0.5, 1.0, 1.5]), fs=2 * np.pi)  # w in rad/s for dt = 1 s
    gain = np.abs(h)
    assert gain[2] < 1e-12  # zero at w0 thanks to pre-warping
    assert gain[0] > 0.99 and 0.85 < gain[1] < 0.97 and 0.6 < gain[3] < 0.95
    f = Biquad(b, a, (1, 1))
    f.reset_to(np.array([[3.0]]))
    assert abs(f(np.array([[3.0]]))[0, 0] - 3.0) < 1e-12  # DC gain 1, no start-up transient


def test_notch_is_eq_49_at_the_prewarped_frequencies():
    """Tustin with pre-warping maps the discrete frequency w to the analogue K tan(w dt / 2), K = w0 / tan(w0 dt / 2):
    the biquad's response there is H(s) = (s^2 + w0^2) / (s^2 + wc s + w0^2) of eq. (49) exactly, for a w0 and a
    step other than 1 (so no power of w0 or of K is hidden by a unit value)."""
    w0, wc, dt = 0.8, 0.3, 0.2
    b, a = tustin_notch(w0, wc, dt)
    assert a[0] == 1.0
    w = np.array([0.05, 0.4, 0.8, 1.3, 4.0])
    _w, h = freqz(b, a, worN=w * dt)  # worN in rad/sample
    s = 1j * w0 / np.tan(w0 * dt / 2) * np.tan(w * dt / 2)
    np.testing.assert_allclose(h, (s**2 + w0**2) / (s**2 + wc * s + w0**2), rtol=1e-12, atol=1e-13)
    f = Biquad(b, a, (2, 3))  # batched: each run and channel is its own direct-form filter
    x = np.random.default_rng(0).standard_normal((300, 2, 3)) + np.sin(w0 * dt * np.arange(300))[:, None, None]
    y = np.array([f(xk) for xk in x])
    np.testing.assert_allclose(y, lfilter(b, a, x, axis=0), rtol=0, atol=1e-12)


def _rot(psi: float) -> np.ndarray:
    c, s = np.cos(psi), np.sin(psi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize(("units", "arm", "scale"), [
    ("acceleration", None, None), ("force", None, [1.0, 1.0, 1.0]), ("kN", 76.2, [1e3, 1e3, 76.2e3]),
    ("10kN", 2.0, [1e4, 1e4, 2e4]), ("100kN", None, [1e5, 1e5, 1e5]), ("MN", 1.0, [1e6, 1e6, 1e6])])
def test_kalman_gains_written_out(units, arm, scale):
    """The design model of design/kalman.py's docstring written out: eta' = nu, nu' = -M^-1 D nu + B b, b' = w
    (B = I for the bias as an acceleration, M^-1 diag(unit) for a force unit with the moment in unit x arm),
    y = eta + v; L0 = P C^T R^-1 from the CARE, K1 = L0_eta, K2 = M L0_b (acceleration) or diag(unit) L0_b,
    K3 = M L0_nu; poles of A(0) - L(0) C in the force-unit model of eq. (43)."""
    M, D = VESSEL.M, VESSEL.D
    Q, R = np.diag([50.0, 40.0, 10.0]), np.diag([15.0, 12.0, 1.0])
    Minv, Z, I3 = np.linalg.inv(M), np.zeros((3, 3)), np.eye(3)
    B = I3 if scale is None else Minv @ np.diag(scale)
    A = np.block([[Z, Z, I3], [Z, Z, Z], [Z, B, -Minv @ D]])
    C, G = np.hstack([I3, Z, Z]), np.vstack([Z, I3, Z])
    from scipy.linalg import solve_continuous_are

    P = solve_continuous_are(A.T, C.T, G @ Q @ G.T, R)
    L0 = P @ C.T @ np.linalg.inv(R)
    g = kalman_gains(M, D, Q, R, bias_units=units, **({} if arm is None else {"moment_arm": arm}))  # default arm: 1
    np.testing.assert_allclose(g.K1, L0[0:3], rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(g.K2, (M if scale is None else np.diag(scale)) @ L0[3:6], rtol=1e-8, atol=1e-9)
    np.testing.assert_allclose(g.K3, M @ L0[6:9], rtol=1e-8, atol=1e-6)
    assert g.riccati_residual < 1e-9
    A43 = np.block([[Z, Z, I3], [Z, Z, Z], [Z, Minv, -Minv @ D]])  # eq. (43) at psi = 0, bias in N
    want = np.linalg.eigvals(A43 - gain_at(g, M) @ C)
    np.testing.assert_allclose(np.sort_complex(g.poles), np.sort_complex(want), rtol=1e-9, atol=1e-12)
    if scale is None:  # the acceleration model is eq. (43) with b_a = M^-1 b: the same poles
        np.testing.assert_allclose(np.sort_complex(g.poles), np.sort_complex(np.linalg.eigvals(A - L0 @ C)), rtol=1e-7)


def test_dp_system_and_gain_at_written_out():
    """Eq. (43) A(psi) = [[0, 0, R], [0, 0, 0], [0, M^-1 R^T, -M^-1 D]] and eq. (47) L(psi) = [K1; K2; M^-1 R^T K3]
    at a heading far from 0, with K's that are not symmetric."""
    M, D, psi = VESSEL.M, VESSEL.D, 2.1
    Rp, Minv, Z = _rot(psi), np.linalg.inv(VESSEL.M), np.zeros((3, 3))
    np.testing.assert_allclose(dp_system(M, D, psi), np.block([[Z, Z, Rp], [Z, Z, Z], [Z, Minv @ Rp.T, -Minv @ D]]),
                               rtol=1e-12, atol=1e-20)
    K1, K2, K3 = (np.arange(9.0).reshape(3, 3) + k for k in (1, 10, 1e5))
    g = DpGains(K1, K2, K3, 0.0, np.empty(0))
    np.testing.assert_allclose(gain_at(g, M, psi), np.vstack([K1, K2, Minv @ Rp.T @ K3]), rtol=1e-12, atol=1e-20)


def test_resetting_observer_defaults_are_torben_table_i_and_the_documented_choices():
    """Table I: delta = 2.5 s, k = 0.7, eps = [0.5 m, 0.5 m, 0.05 rad], Q1 = diag(50, 50, 10), R1 = diag(15, 15, 1);
    our readings (docs/torben.md, README): Q2 = 1e8 Q1, bias in 10 kN with the yaw bias per vessel length, the
    predictor discretisation, the condition check on in bis coordinates with c_max = 1e10. The NPO shares Q1, R1."""
    from marinebench.observers.dp import NpoTuning, ResettingTuning

    t = ResettingTuning()
    assert (t.delta, t.k, t.eps, t.eps_scale) == (2.5, 0.7, (0.5, 0.5, 0.05), 1.0)
    assert (t.q, t.r, t.q2_scale) == ((50.0, 50.0, 10.0), (15.0, 15.0, 1.0), 1e8)
    assert (t.bias_units, t.moment_arm, t.discretization) == ("10kN", "L", "predictor")
    assert (t.check_cond, t.c_max, t.jump_coordinates) == (True, 1e10, "bis")
    npo = NpoTuning()
    assert (npo.q, npo.r, npo.bias_units, npo.moment_arm) == (t.q, t.r, t.bias_units, t.moment_arm)
    assert npo.design_key(76.2) == ((50.0, 50.0, 10.0), (15.0, 15.0, 1.0), 1.0, "10kN", 76.2, "predictor")
    assert ResettingTuning(moment_arm=1.0).design_key(76.2)[2:5] == (1e8, "10kN", 1.0)
    # k in [0, 1] (k = 0 is the NPO, 1 jumps to z*), c_max >= 1 (cond >= 1 always), positive delta and eps scale,
    # any positive q2_scale (the paper's literal 1e-7 included)
    accepts_and_refuses(ResettingTuning, {}, [{"k": 0.0}, {"k": 1.0}, {"c_max": 1.0}, {"delta": 0.01}, {"q2_scale": 1e-7}],
                        [{"k": -0.1}, {"k": 1.01}, {"c_max": 0.99}, {"delta": 0.0}, {"eps_scale": 0.0}, {"q2_scale": 0.0}])


def test_kalman_l1_l2():
    g1 = kalman_gains(VESSEL.M, VESSEL.D, Q1, R1)
    g2 = kalman_gains(VESSEL.M, VESSEL.D, 1e7 * Q1, R1)
    assert g1.riccati_residual < 1e-10 and g2.riccati_residual < 1e-10
    assert -1.6 < g1.poles.real.min() and g1.poles.real.max() < -0.5
    assert g2.poles.real.max() < g1.poles.real.min()  # L2 faster than L1 (the q2 inversion)
    for psi in np.linspace(-np.pi, np.pi, 13):  # stable for every frozen heading
        for g in (g1, g2):
            assert np.linalg.eigvals(dp_system(VESSEL.M, VESSEL.D, psi) - gain_at(g, VESSEL.M, psi) @ C_DP).real.max() < 0


def test_phi_propagation_matches_expm_for_frozen_heading():
    g1 = kalman_gains(VESSEL.M, VESSEL.D, Q1, R1)
    A1 = dp_system(VESSEL.M, VESSEL.D, 0.4) - gain_at(g1, VESSEL.M, 0.4) @ C_DP
    P, _ = rk4_maps(A1[None], 0.05)
    phi = np.linalg.matrix_power(P[0], 50)
    s = bis_scale(SupplyVesselParams())
    scaled = lambda m: m * s[None, :] / s[:, None]
    np.testing.assert_allclose(scaled(phi), scaled(expm(A1 * 2.5)), atol=1e-5)  # RK4 at dt = 0.05 s


def test_fto_recovers_true_state_of_noiseless_lti_after_one_window():
    """Exact continuous-time flows over one window: Psi [z1; z2] equals the true z(t_k + delta)."""
    g1 = kalman_gains(VESSEL.M, VESSEL.D, Q1, R1)
    g2 = kalman_gains(VESSEL.M, VESSEL.D, 1e3 * Q1, R1)
    A = dp_system(VESSEL.M, VESSEL.D, 0.3)
    L1, L2 = gain_at(g1, VESSEL.M, 0.3), gain_at(g2, VESSEL.M, 0.3)
    # augmented LTI system [z, z1, z2] (u = 0, b constant): z_i' = (A - L_i C) z_i + L_i C z
    Z = np.zeros((9, 9))
    big = np.block([[A, Z, Z], [L1 @ C_DP, A - L1 @ C_DP, Z], [L2 @ C_DP, Z, A - L2 @ C_DP]])
    z0 = np.array([3.0, -2.0, 0.1, 2e5, -1e5, 3e6, 0.2, -0.1, 0.01])
    zhat0 = np.zeros(9)
    delta = 2.5
    out = expm(big * delta) @ np.concatenate([z0, zhat0, zhat0])
    z, z1, z2 = out[:9], out[9:18], out[18:]
    phi1, phi2 = expm((A - L1 @ C_DP) * delta), expm((A - L2 @ C_DP) * delta)
    s = bis_scale(SupplyVesselParams())
    zp, jumped, _cond = fto_jump(z1[None], z2[None], phi1[None], phi2[None], np.array([[1.0, 1.0, 1.0]]),
                                np.array([1.0]), np.array([[0.5, 0.5, 0.05]]), 1e10, s)
    assert jumped[0]
    np.testing.assert_allclose(zp[0] / s, z / s, atol=1e-7)


def twice(a: np.ndarray) -> np.ndarray:
    """A batch of two runs from one (the same window end, for per-run settings)."""
    return np.concatenate([a, a])


def test_jump_rule_and_condition_check():
    n = 9
    rng = np.random.default_rng(2)
    phi1 = np.eye(n)[None] * 0.5
    phi2 = np.eye(n)[None] * 0.1
    z1, z2 = rng.normal(size=(1, n)), rng.normal(size=(1, n))
    ones, k = np.ones(n), np.array([0.7])
    small = np.array([[0.1, 0.1, 0.01]])
    eps = np.array([[0.5, 0.5, 0.05]])
    zp, jumped, _ = fto_jump(z1, z2, phi1, phi2, small, k, eps, 1e10, ones)
    assert not jumped[0] and np.array_equal(zp, z1)  # no output error above the bounds: no jump
    big = np.array([[0.1, 0.6, 0.0]])
    zp, jumped, cond = fto_jump(z1, z2, phi1, phi2, big, k, eps, 1e10, ones)
    z_star = (z2 - 0.2 * z1) / 0.8  # X = I - 0.2 I
    assert jumped[0] and np.allclose(zp, 0.7 * z_star + 0.3 * z1) and np.isclose(cond[0], 1.0)
    phi2_bad = phi2.copy()
    phi2_bad[0, 0, 0] = 0.5 * (1 - 1e-13)  # Y[0, 0] ~ 1: X nearly singular
    _, jumped, cond = fto_jump(z1, z2, phi1, phi2_bad, big, k, eps, 1e10, ones)
    assert cond[0] > 1e10 and not jumped[0]
    _, jumped_unchecked, _ = fto_jump(z1, z2, phi1, phi2_bad, big, k, eps, 1e10, ones, check=False)
    assert jumped_unchecked[0]
    # per-run c_max and check (a sweep's runs differ): the same window end, refused only where checked
    zp, jumped, _ = fto_jump(twice(z1), twice(z2), twice(phi1), twice(phi2_bad), twice(big), twice(k), twice(eps),
                             np.array([1e10, 1e10]), ones, check=np.array([True, False]))
    assert list(jumped) == [False, True] and np.array_equal(zp[0], z1[0]) and not np.array_equal(zp[1], z1[0])


def test_jump_rule_boundaries_and_an_exactly_singular_window():
    """|y - C z1|_i >= eps_i and cond <= c_max both hold at equality; with the check off, a window whose
    I - Phi2 Phi1^-1 is exactly singular does not jump (no z* exists) while the others in the batch do."""
    n = 9
    rng = np.random.default_rng(5)
    phi1, phi2 = np.eye(n)[None] * 0.5, np.eye(n)[None] * 0.1  # X = 0.8 I: cond 1 exactly
    z1, z2 = rng.normal(size=(1, n)), rng.normal(size=(1, n))
    ones, k = np.ones(n), np.array([1.0])
    eps = np.array([[0.5, 0.5, 0.05]])
    at_bound = np.array([[0.0, 0.5, 0.0]])
    zp, jumped, cond = fto_jump(z1, z2, phi1, phi2, at_bound, k, eps, 1.0, ones)
    assert cond[0] == 1.0 and jumped[0] and np.allclose(zp, (z2 - 0.2 * z1) / 0.8)
    singular = phi2.copy()
    singular[0, 0, 0] = 0.5  # Phi2 = Phi1 in the first state: X[0, 0] = 0
    zp, jumped, cond = fto_jump(twice(z1), twice(z2), twice(phi1), np.concatenate([singular, phi2]), twice(at_bound),
                                twice(k), twice(eps), 1.0, ones, check=False)
    assert list(jumped) == [False, True] and cond[0] > 1e15
    np.testing.assert_array_equal(zp[0], z1[0])
    assert np.allclose(zp[1], (z2[0] - 0.2 * z1[0]) / 0.8)


def test_a_diverged_run_at_a_window_end_does_not_stop_the_batch():
    """A run gone non-finite (here an absurd sea state, waves.gamma = 1e300) has NaN transition maps: before, the
    condition number's SVD raised for the whole batch; now that run neither jumps nor fails, and the engine flags it
    diverged, while the others jump as before."""
    n = 9
    rng = np.random.default_rng(3)
    phi1, phi2 = np.eye(n)[None] * 0.5, np.eye(n)[None] * 0.1
    z1, z2 = rng.normal(size=(1, n)), rng.normal(size=(1, n))
    gone = phi1.copy()
    gone[0, 2, 2] = np.nan
    big, eps = np.array([[0.1, 0.6, 0.0]]), np.array([[0.5, 0.5, 0.05]])
    zp, jumped, cond = fto_jump(twice(z1), twice(z2), np.concatenate([gone, phi1]), twice(phi2), twice(big),
                                np.array([0.7, 0.7]), twice(eps), 1e10, np.ones(n))
    assert list(jumped) == [False, True] and cond[0] == np.inf and np.isclose(cond[1], 1.0)
    np.testing.assert_array_equal(zp[0], z1[0])
    assert np.allclose(zp[1], 0.7 * (z2[0] - 0.2 * z1[0]) / 0.8 + 0.3 * z1[0])
    _, jumped, cond = fto_jump(z1, z2, gone, phi2, big, np.array([0.7]), eps, 1e10, np.ones(n))  # all of them
    assert not jumped[0] and cond[0] == np.inf


@pytest.mark.parametrize("dt", [0.05, 0.01])
def test_rk4_maps_match_taylor(dt):
    A = np.array([[[-1.0, 2.0], [0.0, -3.0]]])
    P, H = rk4_maps(A, dt)
    X = A[0] * dt
    I2 = np.eye(2)
    np.testing.assert_allclose(P[0], I2 + X + X @ X / 2 + X @ X @ X / 6 + X @ X @ X @ X / 24, rtol=1e-14)
    np.testing.assert_allclose(H[0], dt * (I2 + X / 2 + X @ X / 6 + X @ X @ X / 24), rtol=1e-14)


def test_shipx_low_frequency_vessel():
    """Model B of models.md 2b: M symmetric positive definite; M/D time constants ~54 s, 103 s, 22 s."""
    from marinebench.models.supply import ShipxSupplyLfParams

    v = SupplyVessel(ShipxSupplyLfParams())
    np.testing.assert_array_equal(v.M, v.M.T)
    assert np.all(np.linalg.eigvalsh(v.M) > 0)
    np.testing.assert_allclose(np.diag(v.M) / np.diag(v.D), [54, 103, 22], rtol=0.02)
    np.testing.assert_allclose(bis_scale(ShipxSupplyLfParams())[[0, 3]], [82.8, 6362208.5 * 9.81])


def test_shipx_matrices_are_models_md_2b_and_m_needs_a_positive_definite_symmetric_part():
    """Model B's 3-DOF M from supply.mat with its sway-yaw pair (-4.468e7, -4.503e7) symmetrised, and the viscous
    damping diag(1.30e5, 8.27e4, 1.83e8) (models.md 2b); M is refused when its symmetric part is singular, accepted
    when only its skew part is large."""
    from pydantic import ValidationError

    from marinebench.models.supply import ShipxSupplyLfParams

    v = SupplyVessel(ShipxSupplyLfParams())
    m26 = (-4.468e7 - 4.503e7) / 2
    np.testing.assert_array_equal(v.M, [[7.018e6, 0, 0], [0, 8.546e6, m26], [0, m26, 4.050e9]])
    np.testing.assert_array_equal(v.D, np.diag([1.30e5, 8.27e4, 1.83e8]))
    assert (v.params.L, v.params.m, v.params.g) == (82.8, 6362208.5, 9.81)
    with pytest.raises(ValidationError, match="M must be positive definite"):
        ShipxSupplyLfParams(M=((1.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)))
    ShipxSupplyLfParams(M=((1.0, 5.0, 0.0), (-5.0, 1.0, 0.0), (0.0, 0.0, 1.0)))


def test_supply_plant_is_eq_41_written_out():
    """eta' = R(psi) nu, M nu' + D nu = tau + R(psi)^T b + tau_d, and b' as given, per run (two headings far from 0)."""
    rng = np.random.default_rng(4)
    x = rng.standard_normal((2, 9)) * [10, 10, 1, 1, 1, 0.1, 1e5, 1e5, 1e6]
    x[:, 2] = [2.2, -1.0]
    tau, tau_d, b_dot = (rng.standard_normal((2, 3)) * [1e5, 1e5, 1e6] for _ in range(3))
    got = VESSEL.derivative(x, tau, tau_d, b_dot)
    for i in range(2):
        Rp, nu, b = _rot(x[i, 2]), x[i, 3:6], x[i, 6:9]
        np.testing.assert_allclose(got[i, 0:3], Rp @ nu, rtol=1e-13)
        np.testing.assert_allclose(got[i, 3:6], np.linalg.solve(VESSEL.M, tau[i] + Rp.T @ b + tau_d[i] - VESSEL.D @ nu),
                                   rtol=1e-10)
        np.testing.assert_array_equal(got[i, 6:9], b_dot[i])


def test_shipx_mass_matrix_must_be_positive_definite(tmp_path):
    from typer.testing import CliRunner

    from marinebench.cli import app

    from .conftest import ROOT

    res = CliRunner().invoke(app, ["run", str(ROOT / "configs" / "torben_fig1.yaml"), "--out", str(tmp_path / "o"),
                                   "--set", "scenario.vessel.M=[[1, 0, 0], [0, -1, 0], [0, 0, 1]]"])
    assert res.exit_code == 2 and res.output.strip() == "error: --set: scenario.vessel.M: M must be positive definite"
    assert not (tmp_path / "o").exists()


def test_wave_components_carry_the_spectrums_variance():
    """zeta = sum A_k cos(w_k t + eps_k) with random phases has variance sum A_k^2 / 2, which must be the spectrum's
    m0 (so 4 sqrt(m0) = Hs on a fine grid)."""
    from marinebench.environment.waves import component_amplitudes

    w = np.linspace(0.05, 6.0, 20000)
    dw = np.full_like(w, w[1] - w[0])
    A = component_amplitudes(w, dw, 2.0, 6.3, 3.3)
    m0 = trapezoid(jonswap(w, 2.0, 6.3, 3.3), w)
    assert np.sum(A**2) / 2 == pytest.approx(m0, rel=1e-3)


def test_a_window_end_with_a_singular_jump_matrix_counts_as_a_reset_and_adds_nothing_to_the_log_cond_sum():
    """``DpObserver._reset`` with Phi2 = diag(0.5, 0.875, ...) Phi1 (cond(I - Phi2 Phi1^-1) = 4), then Phi2 = Phi1
    (the matrix is 0, cond inf), then Phi2 = 0.5 Phi1 (cond 1): three resets, no jump (zero innovation), cond_max
    inf, and the log10 cond mean over all resets, log10 4 after the first and (log10 4 + 0 + 0) / 3 at the end."""
    vessel = SupplyVessel(SupplyVesselParams())
    obs = DpObserver([ResettingTuning(k=0.5)], vessel, 0.05, bis_scale(vessel.params))
    assert obs.signals == SIGNALS  # without lumped: z = [eta, b, nu] only
    y = np.zeros((1, 3))
    S = obs.init().reshape(1, 2, 9, 10)
    S[0, 1, :, :9] = np.diag([0.5] + [0.875] * 8)
    obs._reset(S, np.array([0]), y)
    diag = obs.diagnostics()
    assert diag["n_resets"][0] == 1 and diag["cond_max"][0] == pytest.approx(4.0)
    assert diag["log10_cond_mean"][0] == pytest.approx(np.log10(4))
    obs._reset(S, np.array([0]), y)  # the reset set Phi1 = Phi2 = I
    assert (obs.n_resets[0], obs.cond_max[0]) == (2, np.inf) and obs.log_cond_sum[0] == pytest.approx(np.log10(4))
    S[0, 1, :, :9] *= 0.5
    obs._reset(S, np.array([0]), y)
    diag = obs.diagnostics()
    assert diag["n_resets"][0] == 3 and diag["n_jumps"][0] == 0 and diag["cond_max"][0] == np.inf
    assert diag["log10_cond_mean"][0] == pytest.approx(np.log10(4) / 3)


def test_dp_vessel_length_mass_and_gravity_take_any_positive_value_and_refuse_zero():
    """The three DP vessel models: a model-scale 0.5 m, 0.5 kg (or another planet's 0.5 m/s^2) is valid; zero is not."""
    from marinebench.models.supply import LinearDpParams, ShipxSupplyLfParams

    linear = {"L": 1.0, "m": 1.0, "M": np.eye(3).tolist(), "D": np.eye(3).tolist()}
    for model, base in ((SupplyVesselParams, {}), (ShipxSupplyLfParams, {}), (LinearDpParams, linear)):
        accepts_and_refuses(model, base, [{"L": 0.5}, {"m": 0.5}, {"g": 0.5}], [{"L": 0.0}, {"m": 0.0}, {"g": 0.0}])
