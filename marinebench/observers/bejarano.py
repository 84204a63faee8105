"""Bejarano, N-Yo & Orihuela robust nonlinear velocity and lumped-disturbance estimator.

Rotational observer, eq. (13):  chi_psi_hat' = A_psi chi_psi_hat + B_psi tau + L_psi (psi - C_psi chi_psi_hat)
Positional observer, eq. (14):  chi_p_hat'   = A_p(psi) chi_p_hat + B_p tau + L_p(psi) (y_p - C_p chi_p_hat)
with the heading-scheduled gain of eq. (26)
    L_p(psi) = -T_p^-1 P_p^-1 W_p R2^T(psi) = -blkdiag(R2, I, I) L_pz R2^T(psi).

State layout ``(B, 9)``: ``[psi, r, sigma_r, x, y, u, v, sigma_u, sigma_v]``.
Tuning symbols: delta_{psi,1} -> ``delta_psi1``, delta_{p,1} -> ``delta_p1``, k_{omega,p} ->
``k_omega``, k_{n,p} -> ``k_n``; r_min/r_max are the yaw-rate vertices of Assumption 2.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, Field, model_validator

from marinebench.design.lmi import A0_P, A_PSI, C_P, C_PSI, positional_design, rotational_design, verify
from marinebench.errors import DesignError
from marinebench.observers.base import rotate2, wrap_angle
from marinebench.settings import STRICT


class BejaranoTuning(BaseModel):
    """Tuning of the proposed estimator (paper Table I)."""

    model_config = STRICT
    kind: Literal["bejarano"] = "bejarano"
    delta_psi1: float = Field(0.05, ge=0, description="rotational convergence rate delta_psi,1 [1/s]")
    delta_p1: float = Field(0.05, ge=0, description="positional convergence rate delta_p,1 [1/s]")
    k_omega: float = Field(1.0, ge=0, description="disturbance-robustness weight k_omega,p")
    k_n: float = Field(0.0, ge=0, description="noise-rejection weight k_n,p")
    r_max: float = Field(0.8727, gt=0, description="yaw-rate bound r_max = -r_min [rad/s]")
    rho: float | None = Field(
        None,
        gt=0,
        description="disk-region radius |lambda| <= rho [rad/s] (deviation that makes the LMIs well posed); "
        "default max(50, 5 delta)",
    )
    scale_above: float = Field(50.0, gt=0, description="solve time-scaled LMIs when delta >= this")
    trace_weight: float = Field(
        1e-3,
        ge=0,
        description="mu in the LMI objective beta + mu tr(P) (deviation: with mu = 0 the rotational problem, and the "
        "positional one with k_n = 0, have no attained optimum and the gains depend on where the solver stops)",
    )

    @model_validator(mode="after")
    def _rho_large_enough(self) -> BejaranoTuning:
        for d in (self.delta_psi1, self.delta_p1):
            if self.rho is not None and self.rho <= d:
                raise ValueError(f"rho={self.rho} must exceed delta={d}")
        return self

    def rho_for(self, delta: float) -> float:
        return self.rho if self.rho is not None else max(50.0, 5.0 * delta)


def design(t: BejaranoTuning):
    """Solve both LMI problems and re-verify them in numpy; raises DesignError when infeasible."""
    rho_psi, rho_p = t.rho_for(t.delta_psi1), t.rho_for(t.delta_p1)
    rot = rotational_design(t.delta_psi1, rho_psi, t.scale_above, t.trace_weight)
    pos = positional_design(t.delta_p1, t.k_omega, t.k_n, -t.r_max, t.r_max, rho_p, t.scale_above, t.trace_weight)
    for name, sol, d, rho in (("rotational", rot, t.delta_psi1, rho_psi), ("positional", pos, t.delta_p1, rho_p)):
        problems = verify(sol, d, rho)
        if problems:
            raise DesignError(f"{name} design failed verification: {'; '.join(problems)}")
    return rot, pos


class BejaranoObserver:
    """Batched Bejarano estimator; one tuning per run."""

    n_state = 9
    signals = ("u", "v", "r", "sigma_u", "sigma_v", "sigma_r")

    def __init__(self, tunings: list[BejaranoTuning], Minv: np.ndarray) -> None:
        designs = [design(t) for t in tunings]
        self.L_psi = np.stack([rot.gain[:, 0] for rot, _ in designs])  # (B, 3)
        self.L_pz = np.stack([pos.gain for _, pos in designs])  # (B, 6, 2)
        self.Minv = Minv
        self.designs = designs

    def init(self) -> np.ndarray:
        return np.zeros((self.L_psi.shape[0], self.n_state))

    def derivative(self, xhat: np.ndarray, y: np.ndarray, tau: np.ndarray) -> np.ndarray:
        psi = y[:, 2]  # noiseless heading (Assumption 3)
        acc = tau @ self.Minv.T  # M^-1 tau, (B, 3)
        d = np.empty_like(xhat)
        # rotational, eq. (13)
        inn_psi = wrap_angle(psi - xhat[:, 0])
        d[:, 0] = xhat[:, 1] + self.L_psi[:, 0] * inn_psi
        d[:, 1] = xhat[:, 2] + acc[:, 2] + self.L_psi[:, 1] * inn_psi
        d[:, 2] = self.L_psi[:, 2] * inn_psi
        # positional, eq. (14) with eq. (26)
        inn_b = rotate2(psi, y[:, :2] - xhat[:, 3:5], transpose=True)  # R2^T (y_p - C_p chi_hat)
        g = -np.einsum("bij,bj->bi", self.L_pz, inn_b)  # -L_pz R2^T (.)
        d[:, 3:5] = rotate2(psi, xhat[:, 5:7] + g[:, 0:2])
        d[:, 5:7] = xhat[:, 7:9] + acc[:, :2] + g[:, 2:4]
        d[:, 7:9] = g[:, 4:6]
        return d

    def outputs(self, xhat: np.ndarray) -> dict[str, np.ndarray]:
        return {
            "u": xhat[:, 5],
            "v": xhat[:, 6],
            "r": xhat[:, 1],
            "sigma_u": xhat[:, 7],
            "sigma_v": xhat[:, 8],
            "sigma_r": xhat[:, 2],
        }

    def max_rate(self) -> float:
        rates = [np.abs(np.linalg.eigvals(A_PSI - rot.gain @ C_PSI)).max() for rot, _ in self.designs]
        rates += [np.abs(pos.poles).max() for _, pos in self.designs]
        return float(max(rates))


__all__ = ["A0_P", "C_P", "BejaranoObserver", "BejaranoTuning", "design"]
