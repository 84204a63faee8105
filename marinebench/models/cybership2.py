"""CyberShip II 3-DOF nonlinear manoeuvring model (Skjetne, Smogeli & Fossen 2004).

Parameters are Table II of Bejarano et al. plus the optional cubic surge damping X_uuu of Skjetne
Table 4 (``include_xuuu``). The cross-damping pairs follow the labels of Skjetne et al., MSS and
shared/reference/models.md (Y_|r|v = -0.805, Y_|v|r = -0.845, N_|r|v = 0.13, N_|v|r = 0.08); Bejarano's
Table II prints the same numbers with the subscripts of each pair swapped. Equations (Bejarano eqs. (3)-(7)):

    eta_dot = R(psi) nu
    M nu_dot = -C(nu) nu - D(nu) nu + tau_w + tau
    sigma = M^-1 [-C(nu) nu - D(nu) nu + tau_w]          (eq. 6, g = 0)

State layout of the batched arrays: ``x = [x, y, psi, u, v, r]`` with shape ``(B, 6)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import BaseModel, Field

from marinebench.batch import columns
from marinebench.models.supply import LinearDpParams
from marinebench.settings import STRICT


class CyberShip2Params(BaseModel):
    """Rigid-body, added-mass and damping coefficients (SI units, Skjetne sign convention)."""

    model_config = STRICT
    kind: Literal["cybership2"] = "cybership2"
    L: float = Field(1.255, gt=0, description="length [m] (models.md; the bis length of the DP observers' design)")
    m: float = Field(23.8, gt=0, description="mass [kg]")
    I_z: float = Field(1.76, gt=0, description="yaw moment of inertia [kg m^2]")
    x_g: float = Field(0.046, description="CG position along x_b [m] (MSS initCS2 uses 0.0425)")
    X_udot: float = Field(-2.0, description="added mass X_udot [kg]")
    Y_vdot: float = Field(-10.0, description="added mass Y_vdot [kg]")
    Y_rdot: float = Field(0.0, description="added mass Y_rdot [kg m]")
    N_vdot: float = Field(0.0, description="added mass N_vdot [kg m]")
    N_rdot: float = Field(-1.0, description="added inertia N_rdot [kg m^2]")
    X_u: float = Field(-0.72253, description="linear surge damping X_u [kg/s]")
    X_uu: float = Field(-1.32742, description="X_|u|u")
    X_uuu: float = Field(-5.86643, description="cubic surge damping (Skjetne Table 4; absent from Bejarano Table II)")
    include_xuuu: bool = Field(True, description="include X_uuu u^2 in d11 (Skjetne model)")
    Y_v: float = Field(-0.88965, description="linear sway damping Y_v [kg/s]")
    Y_vv: float = Field(-36.47287, description="Y_|v|v")
    Y_rv: float = Field(-0.805, description="Y_|r|v")
    Y_r: float = Field(-7.25, description="linear sway damping from yaw rate Y_r [kg m/s]")
    Y_vr: float = Field(-0.845, description="Y_|v|r")
    Y_rr: float = Field(-3.45, description="Y_|r|r")
    N_v: float = Field(0.0313, description="linear yaw damping from sway N_v [kg m/s]")
    N_vv: float = Field(3.95645, description="N_|v|v")
    N_rv: float = Field(0.13, description="N_|r|v")
    N_r: float = Field(-1.9, description="linear yaw damping N_r [kg m^2/s]")
    N_vr: float = Field(0.08, description="N_|v|r")
    N_rr: float = Field(-0.75, description="N_|r|r")


def inertia_matrix(p: CyberShip2Params) -> np.ndarray:
    """M of Bejarano eq. (5) (symmetric, Y_rdot = N_vdot)."""
    return np.array(
        [
            [p.m - p.X_udot, 0.0, 0.0],
            [0.0, p.m - p.Y_vdot, p.m * p.x_g - p.Y_rdot],
            [0.0, p.m * p.x_g - p.N_vdot, p.I_z - p.N_rdot],
        ]
    )


def linear_dp_model(p: CyberShip2Params) -> LinearDpParams:
    """The DP observers' design model (Torben eq. (41)) of CyberShip II: M of eq. (5) and the linear damping
    at zero speed, ``D = -[[X_u, 0, 0], [0, Y_v, Y_r], [0, N_v, N_r]]``. Coriolis and the nonlinear damping are
    left out, so the observers' bias absorbs them with the environment forces (as sigma does in eq. (6))."""
    D = ((-p.X_u, 0.0, 0.0), (0.0, -p.Y_v, -p.Y_r), (0.0, -p.N_v, -p.N_r))
    M = tuple(tuple(float(x) for x in row) for row in inertia_matrix(p))
    return LinearDpParams(name="cybership2", L=p.L, m=p.m, M=M, D=D)


def rotation(psi: np.ndarray) -> np.ndarray:
    """R(psi) of eq. (4), batched: ``psi (B,) -> (B, 3, 3)``."""
    c, s = np.cos(psi), np.sin(psi)
    R = np.zeros(psi.shape + (3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 1, 0], R[..., 1, 1] = c, -s, s, c
    R[..., 2, 2] = 1.0
    return R


@dataclass(frozen=True)
class CyberShip2:
    """Batched CyberShip II plant. ``params`` are the true (simulated) coefficients."""

    params: CyberShip2Params

    def __post_init__(self) -> None:
        M = inertia_matrix(self.params)
        object.__setattr__(self, "M", M)
        object.__setattr__(self, "Minv", np.linalg.inv(M))

    def coriolis_damping(self, nu: np.ndarray) -> np.ndarray:
        """``C(nu) nu + D(nu) nu`` for ``nu (B, 3)`` -> ``(B, 3)``."""
        p = self.params
        M = self.M
        u, v, r = nu[:, 0], nu[:, 1], nu[:, 2]
        c13 = -(M[1, 1] * v + M[1, 2] * r)
        c23 = M[0, 0] * u
        Cnu = columns(c13 * r, c23 * r, -c13 * u - c23 * v)
        au, av, ar = np.abs(u), np.abs(v), np.abs(r)
        d11 = -p.X_u - p.X_uu * au - (p.X_uuu * u**2 if p.include_xuuu else 0.0)
        d22 = -p.Y_v - p.Y_vv * av - p.Y_rv * ar
        d23 = -p.Y_r - p.Y_vr * av - p.Y_rr * ar
        d32 = -p.N_v - p.N_vv * av - p.N_rv * ar
        d33 = -p.N_r - p.N_vr * av - p.N_rr * ar
        Dnu = columns(d11 * u, d22 * v + d23 * r, d32 * v + d33 * r)
        return Cnu + Dnu

    def sigma(self, nu: np.ndarray, tau_w: np.ndarray) -> np.ndarray:
        """True lumped disturbance sigma of eq. (6) (acceleration, body frame), ``(B, 3)``."""
        return (tau_w - self.coriolis_damping(nu)) @ self.Minv.T

    def derivative(self, x: np.ndarray, tau: np.ndarray, tau_w: np.ndarray) -> np.ndarray:
        """Eq. (7): ``x_dot`` for state ``(B, 6)``, control ``tau`` and environment ``tau_w`` ``(B, 3)``."""
        psi, nu = x[:, 2], x[:, 3:]
        c, s = np.cos(psi), np.sin(psi)
        eta_dot = columns(c * nu[:, 0] - s * nu[:, 1], s * nu[:, 0] + c * nu[:, 1], nu[:, 2])
        nu_dot = (tau + tau_w - self.coriolis_damping(nu)) @ self.Minv.T
        return np.concatenate([eta_dot, nu_dot], axis=1)
