import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError

from marinebench.models.cybership2 import CyberShip2, CyberShip2Params, inertia_matrix, rotation


def test_cs2_defaults_are_bejarano_table_ii_with_skjetne_cubic_surge_damping():
    """Every coefficient as published (Bejarano Table II; X_uuu from Skjetne Table 4). The cross terms carry
    Skjetne's labels: Bejarano's table prints Y_|v|r = -0.805 and Y_|r|v = -0.845 (N likewise), the same numbers
    with each pair's subscripts swapped."""
    p = CyberShip2Params()
    published = {
        "L": 1.255, "m": 23.8, "I_z": 1.76, "x_g": 0.046,
        "X_udot": -2.0, "Y_vdot": -10.0, "Y_rdot": 0.0, "N_vdot": 0.0, "N_rdot": -1.0,
        "X_u": -0.72253, "X_uu": -1.32742, "X_uuu": -5.86643,
        "Y_v": -0.88965, "Y_vv": -36.47287, "Y_rv": -0.805, "Y_r": -7.25, "Y_vr": -0.845, "Y_rr": -3.45,
        "N_v": 0.0313, "N_vv": 3.95645, "N_rv": 0.13, "N_r": -1.9, "N_vr": 0.08, "N_rr": -0.75,
    }
    assert {k: getattr(p, k) for k in published} == published
    assert p.include_xuuu


def test_cs2_inertia_matrix_matches_published_values():
    M = inertia_matrix(CyberShip2Params())
    expected = np.array([[25.8, 0, 0], [0, 33.8, 1.0948], [0, 1.0948, 2.76]])
    np.testing.assert_allclose(M, expected, atol=1e-12)


def test_mss_xg_variant_changes_m23():
    assert np.isclose(inertia_matrix(CyberShip2Params(x_g=0.0425))[1, 2], 1.0115)


def test_inertia_matrix_takes_the_cross_added_masses():
    """M of eq. (5) with Y_rdot = N_vdot != 0: m x_g - Y_rdot off the diagonal (Table II has both 0)."""
    M = inertia_matrix(CyberShip2Params(Y_rdot=-0.3, N_vdot=-0.3))
    np.testing.assert_allclose(M[1:, 1:], [[33.8, 23.8 * 0.046 + 0.3], [23.8 * 0.046 + 0.3, 2.76]], atol=1e-12)


@pytest.mark.parametrize("psi", [0.0, 0.7, -2.5, 4.0])
def test_kinematics_are_eta_dot_r_psi_nu(psi):
    """Eq. (3): eta_dot = R(psi) nu, with R(psi) of eq. (4), whatever the forces."""
    plant = CyberShip2(CyberShip2Params())
    nu = np.array([0.6, -0.25, 0.3])
    x = np.array([[1.0, -2.0, psi, *nu]])
    eta_dot = plant.derivative(x, np.array([[2.0, 0.0, 0.5]]), np.array([[0.3, -0.4, 0.1]]))[0, :3]
    np.testing.assert_allclose(eta_dot, rotation(np.array([psi]))[0] @ nu, atol=1e-15)
    c, s = np.cos(psi), np.sin(psi)
    np.testing.assert_allclose(rotation(np.array([psi]))[0], [[c, -s, 0], [s, c, 0], [0, 0, 1]], atol=1e-15)


@given(st.floats(-10, 10))
def test_rotation_is_orthogonal(psi):
    R = rotation(np.array([psi]))[0]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.isclose(np.linalg.det(R), 1.0)


@settings(max_examples=25)
@given(st.lists(st.floats(-1.5, 1.5), min_size=9, max_size=9))
def test_sigma_truth_identity(vals):
    """Eq. (7): nu_dot = M^-1 tau + sigma, with sigma from eq. (6)."""
    plant = CyberShip2(CyberShip2Params())
    x = np.array([[0.0, 0.0, vals[0], vals[1], vals[2], vals[3]]])
    tau = np.array([[vals[4], 0.0, vals[5]]])
    tau_w = np.array([vals[6:9]])
    nu_dot = plant.derivative(x, tau, tau_w)[:, 3:]
    sigma = plant.sigma(x[:, 3:], tau_w)
    np.testing.assert_allclose(nu_dot, tau @ plant.Minv.T + sigma, atol=1e-12)


def test_unforced_vessel_dissipates_kinetic_energy():
    plant = CyberShip2(CyberShip2Params())
    x = np.array([[0, 0, 0.3, 0.8, -0.3, 0.4]], dtype=float)
    zero = np.zeros((1, 3))
    energy = []
    for _ in range(2000):
        nu = x[0, 3:]
        energy.append(0.5 * nu @ plant.M @ nu)
        x = x + 0.005 * plant.derivative(x, zero, zero)
    assert np.all(np.diff(energy) < 0)
    assert energy[-1] < 0.05 * energy[0]


def test_cs2_linear_dp_model_is_the_zero_speed_linearisation():
    """The DP observers' design model of CyberShip II: M of eq. (5) and D = d(C(nu)nu + D(nu)nu)/dnu at nu = 0."""
    from marinebench.design.kalman import kalman_gains
    from marinebench.models.cybership2 import linear_dp_model
    from marinebench.models.supply import SupplyVessel, bis_scale

    p = CyberShip2Params()
    model = SupplyVessel(linear_dp_model(p))
    np.testing.assert_array_equal(model.M, inertia_matrix(p))
    h = 1e-10  # the plant's C(nu)nu + D(nu)nu is quadratic around 0: its Jacobian there is the linear damping
    jac = np.stack([CyberShip2(p).coriolis_damping(h * np.eye(3)[[i]])[0] / h for i in range(3)], axis=1)
    np.testing.assert_allclose(model.D, jac, rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(bis_scale(model.params)[[0, 3]], [1.255, 23.8 * 9.81])
    # Torben's Q1, R1 with the bias in N and N x L (configs/cross_asv_table4.yaml): L1 poles in [-1.19, -0.19] rad/s
    g = kalman_gains(model.M, model.D, np.diag([50.0, 50.0, 10.0]), np.diag([15.0, 15.0, 1.0]), "force", 1.255)
    assert -1.2 < g.poles.real.min() < -1.18 and -0.2 < g.poles.real.max() < -0.18


@pytest.mark.parametrize("p", [
    CyberShip2Params(),
    CyberShip2Params(Y_rdot=-0.3, N_vdot=-0.3, x_g=0.0425, include_xuuu=False),
], ids=["table_ii", "cross_added_mass_no_xuuu"])
@settings(max_examples=25)
@given(nu=st.lists(st.floats(-1.5, 1.5), min_size=3, max_size=3))
def test_coriolis_and_damping_match_the_matrix_form_of_the_model(p, nu):
    """C(nu) nu + D(nu) nu against the matrices of shared/reference/models.md (Skjetne et al. 2004): C_RB + C_A
    written from m, x_g and the added-mass derivatives, and D(nu) entry by entry with each coefficient on its own
    |velocity| (Y_|v|r on |v|, Y_|r|r on |r|, ...); X_uuu u^2 only with ``include_xuuu``."""
    u, v, r = nu
    c_rb = np.array([[0, 0, -p.m * (p.x_g * r + v)], [0, 0, p.m * u], [p.m * (p.x_g * r + v), -p.m * u, 0]])
    a13 = p.Y_vdot * v + 0.5 * (p.N_vdot + p.Y_rdot) * r
    c_a = np.array([[0, 0, a13], [0, 0, -p.X_udot * u], [-a13, p.X_udot * u, 0]])
    D = -np.array([
        [p.X_u + p.X_uu * abs(u) + p.include_xuuu * p.X_uuu * u**2, 0, 0],
        [0, p.Y_v + p.Y_vv * abs(v) + p.Y_rv * abs(r), p.Y_r + p.Y_vr * abs(v) + p.Y_rr * abs(r)],
        [0, p.N_v + p.N_vv * abs(v) + p.N_rv * abs(r), p.N_r + p.N_vr * abs(v) + p.N_rr * abs(r)],
    ])
    expected = (c_rb + c_a + D) @ np.array(nu)
    np.testing.assert_allclose(CyberShip2(p).coriolis_damping(np.array([nu]))[0], expected, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("key", ["L", "m", "I_z"])
def test_size_mass_and_inertia_take_any_positive_value_and_refuse_zero(key):
    """Scale models below 1 m, 1 kg, 1 kg m^2 are valid; zero is refused with the key named."""
    assert getattr(CyberShip2Params(**{key: 0.4}), key) == 0.4
    with pytest.raises(ValidationError, match=key):
        CyberShip2Params(**{key: 0.0})
