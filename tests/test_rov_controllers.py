"""Leonard-like ROV model and the RISE / S+RISE controllers (Tijjani et al.), without the engine yet."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError

from marinebench.controllers.rise import TABLE_II_DEPTH, TABLE_II_YAW, Rise, RiseGains, SRise
from marinebench.models.rov import LeonardLike, LeonardLikeParams

ROV = LeonardLike(LeonardLikeParams())
ZERO = np.zeros((1, 2))


def test_buoyancy_equilibrium():
    x = np.zeros((1, 4))
    hold = np.array([[9.0, 0.0]])  # 9 N of down-thrust cancels the +9 N net buoyancy
    assert np.allclose(ROV.derivative(x, hold, ZERO), 0.0)
    rise = ROV.derivative(x, ZERO, ZERO)
    assert rise[0, 2] < 0  # unforced, the vehicle accelerates upwards (z down)


def test_terminal_rise_velocity_and_damping_decay():
    x = np.array([[0.3, 0.0, 0.0, 0.5]])
    rates = []
    for _ in range(4000):
        x = x + 0.005 * ROV.derivative(x, ZERO, ZERO)
        rates.append(x[0, 3])
    assert np.all(np.diff(np.abs(rates)) <= 0) and abs(rates[-1]) < 0.01  # yaw rate decays (tau ~ 9 s)
    w = x[0, 2]  # terminal heave velocity: (d_l + d_q |w|) |w| = 9 N
    assert (ROV.p.d_heave_lin + ROV.p.d_heave_quad * abs(w)) * abs(w) == pytest.approx(9.0, rel=1e-3)


def test_damping_scale_multiplies_heave_and_yaw_damping():
    """S2-C2's +90 % damping acts on both DOFs: with no thrust, load or buoyancy, the damping force is the scale
    times the nominal (d_l + d_q |v|) v in heave and in yaw."""
    x = np.array([[0.2, 0.4, 0.3, -0.5]])  # [z, psi, w, r]
    p = ROV.p
    nominal = np.array([(p.d_heave_lin + p.d_heave_quad * 0.3) * 0.3, (p.d_yaw_lin + p.d_yaw_quad * 0.5) * -0.5])
    for scale in (1.0, 1.9):
        damping = -ROV.derivative(x, ZERO, ZERO, scale_damping=scale, net_buoyancy=0.0)[0, 2:] * ROV.inertia
        np.testing.assert_allclose(damping, scale * nominal, rtol=1e-12)


def test_leonard_like_defaults_are_bluerov2_scaled_as_documented():
    """models.md 2f: BlueROV2 (Wu 2018) magnitudes scaled to Leonard's size, added mass x2.4, damping x2.7 (linear
    heave) and x2.85, inertia x6.5; Tijjani Table I's mass, +9 N floatability and 2.2 kgf thrusters."""
    p = LeonardLikeParams()
    scaled = {"added_mass_heave": 14.57 * 2.4, "inertia_yaw": 0.16 * 6.5, "added_inertia_yaw": 0.12 * 6.5,
              "d_heave_lin": 5.18 * 2.7, "d_heave_quad": 36.99 * 2.85, "d_yaw_lin": 0.07 * 2.85, "d_yaw_quad": 1.55 * 2.85}
    for key, value in scaled.items():
        assert getattr(p, key) == pytest.approx(value, rel=0.01), key
    assert (p.mass, p.net_buoyancy, p.n_vertical, p.n_horizontal, p.yaw_lever) == (28.0, 9.0, 2, 4, 0.25)
    assert p.thrust_max == pytest.approx(2.2 * 9.81, rel=0.001)


def test_rov_derivative_written_out_with_loads_off_unit_values():
    """The module's equations at a state moving down and turning negative, with an external load, a changed
    buoyancy and damping scale, on a vehicle with 3 horizontal thrusters at 0.3 m: z_dot = w, psi_dot = r,
    (m + m_a) w_dot = tau_z - s (d_zl + d_zq |w|) w - b + f_z, (I + I_a) r_dot = tau_psi - s (d_rl + d_rq |r|) r + f_psi."""
    p = LeonardLikeParams(n_horizontal=3, yaw_lever=0.3, d_heave_lin=12.0, d_heave_quad=90.0, d_yaw_lin=0.3,
                          d_yaw_quad=3.0)
    rov = LeonardLike(p)
    w, r, tau, f, s, b = -0.2, -0.4, (5.0, -1.5), (-3.0, 0.8), 1.9, 18.0
    x = np.array([[0.3, 1.2, w, r]])
    xdot = rov.derivative(x, np.array([tau]), np.array([f]), scale_damping=s, net_buoyancy=b)[0]
    w_dot = (tau[0] - s * (12.0 + 90.0 * abs(w)) * w - b + f[0]) / (28.0 + 35.0)
    r_dot = (tau[1] - s * (0.3 + 3.0 * abs(r)) * r + f[1]) / (1.04 + 0.78)
    np.testing.assert_allclose(xdot, [w, r, w_dot, r_dot], rtol=1e-12)


def test_allocation_splits_each_dof_over_its_thrusters_and_saturates_each_group():
    """Two vertical thrusters share tau_z; three horizontal ones at 0.3 m share tau_psi (not a unit lever arm);
    each group clips at thrust_max, so the achieved tau is the command up to the group's limit."""
    rov = LeonardLike(LeonardLikeParams(n_horizontal=3, yaw_lever=0.3))
    np.testing.assert_allclose(rov.limits, [2 * 21.6, 3 * 0.3 * 21.6])
    tau = np.array([[30.0, -9.0], [-60.0, 25.0]])  # first row inside both limits, second outside both
    thrust, achieved = rov.allocate(tau)
    np.testing.assert_allclose(thrust, [[15.0, -9.0 / 0.9], [-21.6, 21.6]], rtol=1e-12)
    np.testing.assert_allclose(achieved, [[30.0, -9.0], [-43.2, 3 * 0.3 * 21.6]], rtol=1e-12)


def test_srise_integral_terms_follow_eqs_16_17():
    """One controller period from rest, written out from eqs. (15)-(17) for one DOF: Sigma grows by
    h (phi + phi*) with I = 0 (so Lambda at eps3), and the next command carries it."""
    import math

    g, h, e1, e1_dot = TABLE_II_YAW, 0.04, 0.5, 0.3
    c = SRise([g], batch=1)
    c.command(np.array([[0.0]]), np.array([[0.0]]), h)  # t0 at rest: e2(t0) = 0, I stays 0
    c.command(np.array([[e1]]), np.array([[e1_dot]]), h)
    e2 = e1_dot + g.alpha * math.tanh(e1)  # (14)
    K = g.k0 * abs(e2) ** (g.delta1 - 1)  # |e2| > eps1
    B = g.beta * abs(e2) * math.tanh(abs(e2))  # above eps2
    Lam = g.lambda0 * g.eps3 ** (g.delta2 - 1)  # I = 0 before this step
    phi = (K + 1) * Lam * math.tanh(e2)
    phi_star = B * (g.mu1**2 / 2 * math.tanh(e2) + g.mu2**2 * e2 + 3 * g.mu1 * g.mu2 / 2 * abs(e2) ** 0.5 * math.tanh(e2))
    assert c.Sigma[0, 0] == pytest.approx(h * (phi + phi_star), rel=1e-12)
    assert c.I[0, 0] == pytest.approx(h * e2, rel=1e-12)
    tau = c.command(np.array([[e1]]), np.array([[e1_dot]]), h)[0, 0]
    assert tau == pytest.approx((K + 1) * e2 + h * (phi + phi_star), rel=1e-12)  # e2(t0) = 0


def test_rise_law_written_out_for_three_periods():
    """baselines.md 5.1: mu = (ks + 1)(e2 - e2(t0)) + nu, nu' = (ks + 1) alpha2 e2 + beta sgn(e2) (sgn(0) = 0),
    e2 = e1' + alpha1 e1; nu integrated over each period h from its start (explicit Euler). Two DOFs with
    their own gains."""
    gains = [RiseGains(alpha1=2.0, ks=10.0, alpha2=0.5, beta=0.3), RiseGains(alpha1=1.0, ks=4.0, alpha2=2.0, beta=0.7)]
    c, h = Rise(gains, batch=1), 0.04
    e1s = [np.array([[0.1, -0.2]]), np.array([[-0.3, 0.4]]), np.array([[0.0, 0.0]])]
    e1_dots = [np.array([[0.2, 0.1]]), np.array([[0.1, -0.1]]), np.array([[0.0, 0.0]])]
    taus = [c.command(e1, e1_dot, h)[0] for e1, e1_dot in zip(e1s, e1_dots)]
    for j, g in enumerate(gains):
        e2 = [e1_dot[0, j] + g.alpha1 * e1[0, j] for e1, e1_dot in zip(e1s, e1_dots)]
        nu = [0.0]
        for e in e2:
            nu.append(nu[-1] + h * ((g.ks + 1) * g.alpha2 * e + g.beta * np.sign(e)))
        expected = [(g.ks + 1) * (e - e2[0]) + n for e, n in zip(e2, nu)]
        np.testing.assert_allclose([tau[j] for tau in taus], expected, rtol=1e-12, atol=1e-15)
        assert taus[0][j] == 0.0  # mu(t0) = 0
        assert c.nu[0, j] == pytest.approx(nu[2], rel=1e-12)  # the last period, at e2 = 0, added nothing


@given(st.floats(-500, 500), st.floats(-200, 200))
def test_allocation_respects_thruster_limits(tz, tp):
    f, achieved = ROV.allocate(np.array([[tz, tp]]))
    assert np.all(np.abs(f) <= ROV.p.thrust_max + 1e-12)
    assert np.all(np.abs(achieved) <= ROV.limits + 1e-9)
    inside = np.abs([tz, tp]) <= ROV.limits
    assert np.allclose(achieved[0, inside], np.array([tz, tp])[inside])


def test_srise_starts_at_zero_and_gains_stay_in_their_bounds():
    c = SRise([TABLE_II_DEPTH, TABLE_II_YAW], batch=3)
    e1 = np.array([[0.3, 1.0], [-2.0, 0.0], [0.0, -1.0]])
    assert np.allclose(c.command(e1, np.zeros_like(e1), 0.01), 0.0)  # tau(t0) = 0 by design of (15)
    e2 = np.linspace(-5, 5, 1001)[:, None].repeat(2, axis=1)
    K = c.K(e2)
    k_max = c.g["k0"] * c.g["eps1"] ** (c.g["delta1"] - 1)
    assert np.all(K <= k_max + 1e-12) and np.all(K > 0)
    assert np.all(c.Bgain(e2) >= c.g["beta"] * c.g["eps2"] - 1e-15)
    assert np.all(c.Lambda(e2) <= c.g["lambda0"] * c.g["eps3"] ** (c.g["delta2"] - 1) + 1e-12)


@settings(max_examples=50)
@given(st.floats(-1e3, 1e3))
def test_srise_proportional_action_is_bounded_by_the_saturated_error(e1):
    """e2 = e1_dot + alpha tanh(e1): at rest, the state feedback (K+1) e2 cannot exceed
    k0 alpha^delta1 + alpha (or k0 eps1^(delta1-1) alpha when alpha < eps1), whatever the error."""
    c = SRise([TABLE_II_DEPTH, TABLE_II_YAW], batch=1)
    e = np.array([[e1, e1]])
    e2 = c.e2(e, np.zeros_like(e))
    p = (c.K(e2) + 1) * e2
    g = c.g
    bound = g["k0"] * np.maximum(g["alpha"], g["eps1"]) ** g["delta1"] + g["alpha"]
    assert np.all(np.abs(p) <= bound + 1e-9)
    # RISE's proportional action is unbounded in e1
    r = Rise([RiseGains(), RiseGains()], batch=1)
    r.command(np.zeros((1, 2)), np.zeros((1, 2)), 0.01)
    if abs(e1) > 1:
        assert np.all(np.abs(r.command(e, np.zeros_like(e), 0.01)) > np.abs(p))


def smooth_step(t, t0, t1, a, b):
    s = np.clip((t - t0) / (t1 - t0), 0, 1)
    blend = s**3 * (10 - 15 * s + 6 * s**2)  # C2 minimum-jerk blend
    return a + (b - a) * blend


def test_rise_closed_loop_tracks_depth_and_yaw_on_the_nominal_model():
    """State feedback on the plant: depth 0 -> 0.3 m and yaw 0 -> 60 deg in 5 s, then hold.
    (S+RISE with the Table II gains winds up against the thruster limits on this stand-in model; its
    closed loop is part of the open Tijjani issue.)"""
    ctrl, dt = Rise([RiseGains(), RiseGains(alpha1=4, ks=20, alpha2=0.05, beta=1.0)], 1), 0.005
    x = np.zeros((1, 4))
    worst = 0.0
    for k in range(int(25 / dt)):
        t = k * dt
        ref = np.array([[smooth_step(t, 0, 5, 0, 0.3), smooth_step(t, 0, 5, 0, np.deg2rad(60))]])
        ref_dot = (np.array([[smooth_step(t + 1e-4, 0, 5, 0, 0.3), smooth_step(t + 1e-4, 0, 5, 0, np.deg2rad(60))]]) - ref) / 1e-4
        tau = ctrl.command(ref - x[:, :2], ref_dot - x[:, 2:], dt)
        _, achieved = ROV.allocate(tau)
        x = x + dt * ROV.derivative(x, achieved, ZERO)
        if t > 15:
            worst = max(worst, abs(ref[0, 0] - x[0, 0]))
    assert worst < 0.01 and abs(np.rad2deg(x[0, 1]) - 60) < 1.0


@pytest.mark.parametrize(("key", "ok", "bad"), [
    *[(k, 0.5, 0.0) for k in ("mass", "inertia_yaw", "thrust_max", "yaw_lever")],  # any positive size, not zero
    *[(k, 0.0, -0.1) for k in ("added_mass_heave", "added_inertia_yaw", "d_heave_lin", "d_heave_quad", "d_yaw_lin",
                               "d_yaw_quad")],  # added mass and damping may be zero, not negative
    *[(k, 1, 0) for k in ("n_vertical", "n_horizontal")],  # a thruster group needs one thruster
])
def test_rov_parameter_bounds(key, ok, bad):
    assert getattr(LeonardLikeParams(**{key: ok}), key) == ok
    with pytest.raises(ValidationError, match=key):
        LeonardLikeParams(**{key: bad})
