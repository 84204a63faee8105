"""MSS supply vessels for dynamic positioning, models (A) and (B) of ``shared/reference/models.md`` section 2b.

(A) ``supply_dp_linear``: Fossen, Sagatun & Sorensen (1996), MSS ``supply.m`` / PythonVehicleSimulator
``supply.py``, a 3-DOF linear low-frequency model given in the bis system; the observers' design model
(its M and D are fully published) and the default plant of a scenario that names no vessel.
(B) ``supply_shipx_lf``: the low-frequency 3-DOF part of the MSS ShipX 6-DOF "Supply vessel" (the
simulator Torben et al. most likely used): M = (M_RB + M_A)[1,2,6] and the viscous damping at low
frequency, as read from ``supply.mat`` in models.md; the frequency-dependent added mass and damping
(fluid memory) and the 6-DOF coupling are not available here. Used as a *plant* with observers designed
on (A), it stands in for the paper's mismatch between its "high-fidelity" simulator and the "highly
simplified control design model" (41); the committed Torben scenarios do this (``DpScenario.design_vessel``).

Low-frequency dynamics with a bias load b (NED, force units), Torben et al. eq. (41):

    eta_dot = R(psi) nu,   M nu_dot + D nu = tau + R(psi)^T b + tau_d

``tau_d`` are body-frame disturbance events (e.g. the sway impulse). Dimensionalisation with
``T_L = diag(1, 1, L)``: ``M = m T_L M'' T_L`` and ``D = m sqrt(g/L) T_L D'' T_L``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, Field, field_validator

from marinebench.batch import columns
from marinebench.settings import STRICT

M_BIS = ((1.1274, 0.0, 0.0), (0.0, 1.8902, -0.0744), (0.0, -0.0744, 0.1278))
D_BIS = ((0.0358, 0.0, 0.0), (0.0, 0.1183, -0.0124), (0.0, -0.0041, 0.0308))


class SupplyVesselParams(BaseModel):
    """Linear DP model of the MSS supply vessel (bis matrices, length, mass)."""

    model_config = STRICT
    kind: Literal["supply_dp_linear"] = "supply_dp_linear"
    L: float = Field(76.2, gt=0, description="length between perpendiculars [m]")
    m: float = Field(6.0e6, gt=0, description="mass [kg] (bis mass unit)")
    g: float = Field(9.81, gt=0, description="gravity [m/s^2]")
    M_bis: tuple[tuple[float, float, float], ...] = Field(M_BIS, description="M'' (bis)")
    D_bis: tuple[tuple[float, float, float], ...] = Field(D_BIS, description="D'' (bis)")


Mat3 = tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]]
# models.md 2b (B): 3-DOF M from supply.mat, sway-yaw entries (-4.468e7, -4.503e7) symmetrised; viscous Bv
M_SHIPX = ((7.018e6, 0.0, 0.0), (0.0, 8.546e6, -4.4855e7), (0.0, -4.4855e7, 4.050e9))
D_SHIPX = ((1.30e5, 0.0, 0.0), (0.0, 8.27e4, 0.0), (0.0, 0.0, 1.83e8))


class ShipxSupplyLfParams(BaseModel):
    """Low-frequency 3-DOF part of the MSS ShipX supply vessel (model B; M, D in SI)."""

    model_config = STRICT
    kind: Literal["supply_shipx_lf"] = "supply_shipx_lf"
    L: float = Field(82.8, gt=0, description="length between perpendiculars [m]")
    m: float = Field(6362208.5, gt=0, description="mass rho*volume [kg] (bis mass unit)")
    g: float = Field(9.81, gt=0, description="gravity [m/s^2]")
    M: Mat3 = Field(M_SHIPX, description="3-DOF mass matrix incl. infinite-frequency added mass [kg, kg m, kg m^2]")
    D: Mat3 = Field(D_SHIPX, description="linear (viscous, low-frequency) damping [N s/m, N s, N m s]")

    @field_validator("M")
    @classmethod
    def _positive_definite(cls, M: Mat3) -> Mat3:
        sym = np.array(M, dtype=float)
        if not np.all(np.linalg.eigvalsh((sym + sym.T) / 2) > 0):
            raise ValueError("M must be positive definite")
        return M


class LinearDpParams(BaseModel):
    """A linear low-frequency model (41) of any vessel in SI, e.g. the DP observers' design model of CyberShip II."""

    model_config = STRICT
    kind: Literal["linear_dp"] = "linear_dp"
    name: str = Field("", description="the vessel it was derived from")
    L: float = Field(..., gt=0, description="length [m] (bis length unit)")
    m: float = Field(..., gt=0, description="mass [kg] (bis mass unit)")
    g: float = Field(9.81, gt=0, description="gravity [m/s^2]")
    M: Mat3 = Field(..., description="mass matrix incl. added mass [kg, kg m, kg m^2]")
    D: Mat3 = Field(..., description="linear damping [N s/m, N s, N m s]")


SupplyParams = Annotated[SupplyVesselParams | ShipxSupplyLfParams, Field(discriminator="kind")]
DpModelParams = SupplyVesselParams | ShipxSupplyLfParams | LinearDpParams


def dimensional_matrices(p: DpModelParams) -> tuple[np.ndarray, np.ndarray]:
    """(M, D) in SI units."""
    if p.kind != "supply_dp_linear":  # given in SI
        return np.array(p.M, dtype=float), np.array(p.D, dtype=float)
    T = np.diag([1.0, 1.0, p.L])
    M = p.m * T @ np.array(p.M_bis) @ T
    D = p.m * np.sqrt(p.g / p.L) * T @ np.array(p.D_bis) @ T
    return M, D


def bis_scale(p: DpModelParams) -> np.ndarray:
    """Denominators that make z = [eta, b, nu] dimensionless (Norrbin's bis system, models.md 2d)."""
    L, m, g = p.L, p.m, p.g
    return np.array([L, L, 1.0, m * g, m * g, m * g * L, np.sqrt(g * L), np.sqrt(g * L), np.sqrt(g / L)])


@dataclass(frozen=True)
class SupplyVessel:
    """Batched low-frequency plant; state ``x = [eta(3), nu(3), b(3)]`` with shape ``(B, 9)``."""

    params: DpModelParams
    M: np.ndarray = field(init=False)
    D: np.ndarray = field(init=False)
    Minv: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        M, D = dimensional_matrices(self.params)
        object.__setattr__(self, "M", M)
        object.__setattr__(self, "D", D)
        object.__setattr__(self, "Minv", np.linalg.inv(M))

    def derivative(self, x: np.ndarray, tau: np.ndarray, tau_d: np.ndarray, b_dot: np.ndarray) -> np.ndarray:
        psi, nu, b = x[:, 2], x[:, 3:6], x[:, 6:9]
        c, s = np.cos(psi), np.sin(psi)
        eta_dot = columns(c * nu[:, 0] - s * nu[:, 1], s * nu[:, 0] + c * nu[:, 1], nu[:, 2])
        b_body = columns(c * b[:, 0] + s * b[:, 1], -s * b[:, 0] + c * b[:, 1], b[:, 2])
        nu_dot = (tau + b_body + tau_d - nu @ self.D.T) @ self.Minv.T
        return np.concatenate([eta_dot, nu_dot, b_dot], axis=1)
