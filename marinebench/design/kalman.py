"""Kalman-Bucy injection gains for the DP observer about zero heading (Torben et al. Sec. IV-A).

The LTV model z = [eta, b, nu] of eq. (42)-(44) is frozen at psi = 0 and, with ``bias_units =
"acceleration"`` (default), written with the bias as an acceleration ``b_a = M^-1 b`` so the process
noise enters where the disturbance acts:

    eta_dot = nu,  b_a_dot = w,  nu_dot = -M^-1 D nu + b_a,   y = eta + v,   E[w w^T] = Q, E[v v^T] = R

``L0 = P C^T R^-1`` from the continuous algebraic Riccati equation; then ``K1 = L0_eta``, ``K2 = M L0_b``
(force units, as the plant's bias) and ``K3 = M L0_nu``, so that eq. (47) ``L(psi) = [K1; K2;
M^-1 R^T(psi) K3]`` equals L0 at psi = 0. Units: Q in (m/s^2)^2/s for surge/sway and (rad/s^2)^2/s for
yaw; R in m^2 and rad^2 (``shared/reference/baselines.md`` section 3.3).

``bias_units = "force"`` (N), ``"kN"``, ``"10kN"``, ``"100kN"`` or ``"MN"`` design on the model with the bias in that force unit
(``nu_dot = ... + unit M^-1 b_unit``). The paper does not state its units; the gain's speed depends on
them by orders of magnitude (force: slowest pole ~6e-5 rad/s; kN: ~2e-3; acceleration: ~0.6). The
moment's unit is the force unit times ``moment_arm``: with 1 m (kN m with kN) the yaw channel of the
supply vessel is ~30x slower than surge/sway (I_z/m ~ 400 m^2); a length of the order of the hull
(bis-like: moment per F L) balances the three DOFs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.linalg import solve_continuous_are

from marinebench.models.cybership2 import rotation

C_DP = np.hstack([np.eye(3), np.zeros((3, 6))])


@dataclass(frozen=True)
class DpGains:
    K1: np.ndarray  # (3, 3) eta injection
    K2: np.ndarray  # (3, 3) bias injection (force units)
    K3: np.ndarray  # (3, 3) velocity injection (force units), enters as M^-1 R^T K3
    riccati_residual: float
    poles: np.ndarray  # of A(0) - L0 C in the force-unit model


def dp_system(M: np.ndarray, D: np.ndarray, psi: float = 0.0) -> np.ndarray:
    """A(psi) of eq. (43) in force units, z = [eta, b, nu]."""
    R = rotation(np.asarray(psi, dtype=float))
    Minv = np.linalg.inv(M)
    A = np.zeros((9, 9))
    A[0:3, 6:9] = R
    A[6:9, 3:6] = Minv @ R.T
    A[6:9, 6:9] = -Minv @ D
    return A


def gain_at(g: DpGains, M: np.ndarray, psi: float = 0.0) -> np.ndarray:
    """L(psi) of eq. (47), (9, 3)."""
    R = rotation(np.asarray(psi, dtype=float))
    return np.vstack([g.K1, g.K2, np.linalg.solve(M, R.T @ g.K3)])


BiasUnits = Literal["acceleration", "force", "kN", "10kN", "100kN", "MN"]
FORCE_UNIT = {"force": 1.0, "kN": 1e3, "10kN": 1e4, "100kN": 1e5, "MN": 1e6}


def kalman_gains(
    M: np.ndarray, D: np.ndarray, Q: np.ndarray, R: np.ndarray, bias_units: BiasUnits = "acceleration",
    moment_arm: float = 1.0,
) -> DpGains:
    """Steady-state Kalman gains; with a force unit F (``bias_units``) the yaw bias is designed in units of
    ``F * moment_arm`` (1 m: F m, as N m goes with N)."""
    Minv = np.linalg.inv(M)
    A = np.zeros((9, 9))
    A[0:3, 6:9] = np.eye(3)
    A[6:9, 6:9] = -Minv @ D
    unit = FORCE_UNIT.get(bias_units, 1.0) * np.array([1.0, 1.0, moment_arm])
    A[6:9, 3:6] = np.eye(3) if bias_units == "acceleration" else Minv * unit
    G = np.vstack([np.zeros((3, 3)), np.eye(3), np.zeros((3, 3))])
    P = solve_continuous_are(A.T, C_DP.T, G @ Q @ G.T, R)
    residual = A @ P + P @ A.T - P @ C_DP.T @ np.linalg.solve(R, C_DP @ P) + G @ Q @ G.T
    L0 = P @ C_DP.T @ np.linalg.inv(R)
    K1 = L0[0:3]
    K2 = M @ L0[3:6] if bias_units == "acceleration" else unit[:, None] * L0[3:6]
    K3 = M @ L0[6:9]
    gains = DpGains(K1, K2, K3, float(np.abs(residual).max() / max(1.0, np.abs(P).max())), np.empty(0))
    poles = np.linalg.eigvals(dp_system(M, D) - gain_at(gains, M) @ C_DP)
    return DpGains(K1, K2, K3, gains.riccati_residual, poles)
