"""Leonard-like ROV, heave and yaw (Tijjani et al.; ``shared/reference/models.md`` section 2f).

The Leonard ROV's identified model is not public. This stand-in takes the paper's public facts (28 kg,
+9 N net buoyancy, 6 thrusters of 2.2 kgf) and BlueROV2 hydrodynamics (Wu 2018) scaled heuristically to
Leonard's size: added mass with volume (x2.4), damping with area (x2.7-2.85), inertia with m L^2 (x6.5).
Every value is an ASSUMPTION and every output that uses it says ``leonard_like``.

Heave (z down) and yaw, roll and pitch passively stable and ignored, Coriolis neglected (paper A2):

    (m + m_a) w_dot = tau_z - (d_zl + d_zq |w|) w - b_net + f_z          z_dot = w
    (I_z + I_a) r_dot = tau_psi - (d_rl + d_rq |r|) r + f_psi             psi_dot = r

``b_net = B - W > 0`` pushes the vehicle up (towards negative z). Thrust allocation: two vertical
thrusters share tau_z, four horizontal ones at lever ``yaw_lever`` share tau_psi; each saturates at
``thrust_max``; with ``thrust_time_constant`` T > 0 the thrust follows the allocated command through a
first-order lag, T dtau/dt = tau_cmd - tau (applied by the closed-loop world: once per step, its exact solution
for the held command, held over the step). State ``(B, 4) = [z, psi, w, r]``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import BaseModel, Field

from marinebench.batch import columns
from marinebench.settings import STRICT


class LeonardLikeParams(BaseModel):
    """Heave/yaw stand-in for the Leonard ROV: 28 kg, +9 N buoyancy, BlueROV2-derived hydrodynamics (assumed)."""

    model_config = STRICT
    kind: Literal["leonard_like"] = "leonard_like"
    mass: float = Field(28.0, gt=0, description="[kg] Tijjani Table I")
    net_buoyancy: float = Field(9.0, description="B - W [N] ('floatability 9 N', Tijjani Table I)")
    added_mass_heave: float = Field(35.0, ge=0, description="[kg] BlueROV2 |Z_wdot| 14.57 x 2.4")
    inertia_yaw: float = Field(1.04, gt=0, description="[kg m^2] BlueROV2 I_z 0.16 x 6.5")
    added_inertia_yaw: float = Field(0.78, ge=0, description="[kg m^2] BlueROV2 |N_rdot| 0.12 x 6.5")
    d_heave_lin: float = Field(14.0, ge=0, description="[N s/m] BlueROV2 |Z_w| 5.18 x 2.7")
    d_heave_quad: float = Field(105.0, ge=0, description="[N s^2/m^2] BlueROV2 |Z_ww| 36.99 x 2.85")
    d_yaw_lin: float = Field(0.20, ge=0, description="[N m s] BlueROV2 |N_r| 0.07 x 2.85")
    d_yaw_quad: float = Field(4.4, ge=0, description="[N m s^2] BlueROV2 |N_rr| 1.55 x 2.85")
    thrust_max: float = Field(21.6, gt=0, description="[N] per thruster, 2.2 kgf (Seabotix BTD150)")
    n_vertical: int = Field(2, ge=1, description="vertical thrusters (of 6)")
    n_horizontal: int = Field(4, ge=1, description="horizontal thrusters (of 6) producing yaw")
    yaw_lever: float = Field(0.25, gt=0, description="[m] moment arm of the horizontal thrusters (assumed)")
    thrust_time_constant: float = Field(
        0.0, ge=0, description="[s] first-order lag of each thruster's thrust behind its (saturated) command; 0: "
        "instantaneous (default; the paper gives no thruster dynamics). The observers take the command; tau_* and "
        "INT are the thrust")


@dataclass(frozen=True)
class LeonardLike:
    """Batched heave/yaw plant with thrust allocation and saturation."""

    p: LeonardLikeParams

    @property
    def inertia(self) -> np.ndarray:
        return np.array([self.p.mass + self.p.added_mass_heave, self.p.inertia_yaw + self.p.added_inertia_yaw])

    @property
    def limits(self) -> np.ndarray:
        """Largest |tau_z| [N] and |tau_psi| [N m] the thrusters can produce."""
        return np.array([self.p.n_vertical * self.p.thrust_max, self.p.n_horizontal * self.p.yaw_lever * self.p.thrust_max])

    def allocate(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Thrusts of the vertical and horizontal groups (each saturated) and the achieved ``tau (B, 2)``."""
        p = self.p
        f_v = np.clip(tau[:, 0] / p.n_vertical, -p.thrust_max, p.thrust_max)
        f_h = np.clip(tau[:, 1] / (p.n_horizontal * p.yaw_lever), -p.thrust_max, p.thrust_max)
        achieved = columns(p.n_vertical * f_v, p.n_horizontal * p.yaw_lever * f_h)
        return columns(f_v, f_h), achieved

    def derivative(self, x: np.ndarray, tau: np.ndarray, f_ext: np.ndarray, scale_damping: float | np.ndarray = 1.0,
                   net_buoyancy: float | np.ndarray | None = None) -> np.ndarray:
        """``x_dot`` for state ``(B, 4)``, achieved thrust ``tau (B, 2)`` and external loads ``f_ext (B, 2)``.

        ``scale_damping`` and ``net_buoyancy`` (scalars, or one value per run) change the *plant* only (Tijjani
        scenario S2-C2).
        """
        p = self.p
        w, r = x[:, 2], x[:, 3]
        b = p.net_buoyancy if net_buoyancy is None else net_buoyancy
        dz = scale_damping * (p.d_heave_lin + p.d_heave_quad * np.abs(w)) * w
        dr = scale_damping * (p.d_yaw_lin + p.d_yaw_quad * np.abs(r)) * r
        m_z, i_r = self.inertia
        w_dot = (tau[:, 0] - dz - b + f_ext[:, 0]) / m_z
        r_dot = (tau[:, 1] - dr + f_ext[:, 1]) / i_r
        return columns(w, r, w_dot, r_dot)
