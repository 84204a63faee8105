"""RISE (Fischer et al. 2014) and S+RISE (Tijjani et al. eqs. (13)-(17)), batched over runs and DOFs.

Both are discrete-time implementations at the controller period ``h`` (forward-Euler integrals, as
on the vehicle), acting on arrays ``(B, n_dof)`` of tracking errors ``e1 = eta_d - eta`` and their rates.

RISE:   e2 = e1_dot + alpha1 e1,  tau = (ks + 1)(e2 - e2(t0)) + nu,  nu_dot = (ks + 1) alpha2 e2 + beta sgn(e2)

S+RISE: e2 = e1_dot + alpha tanh(e1)                                                        (14)
        tau = (K(e2) + 1) e2 - (K(e2(t0)) + 1) e2(t0) + Sigma,   Sigma_dot = phi + phi*          (15)
        phi = (K + 1) Lambda(I) tanh(e2),   I = integral of e2
        phi* = B(e2) [mu1^2/2 tanh(e2) + mu2^2 e2 + 3 mu1 mu2 / 2 |e2|^(1/2) tanh(e2)]        (16)
        K = k0 |e2|^(delta1 - 1) (|e2| > eps1, else k0 eps1^(delta1 - 1)); B = beta |e2| tanh|e2|
        (above eps2, else beta eps2); Lambda = lambda0 |I|^(delta2 - 1) (|I| > eps3, else at eps3)   (17)

Symbols -> fields: k_0 -> k0, beta, lambda_bar_0 -> lambda0, epsilon_1..3 -> eps1..eps3,
delta_1, delta_2 -> delta1, delta2, mu_1, mu_2 -> mu1, mu2, alpha.
"""

from __future__ import annotations

import numpy as np
from pydantic import BaseModel, Field

from marinebench.settings import STRICT


class SRiseGains(BaseModel):
    """S+RISE gains of one DOF (Tijjani Table II)."""

    model_config = STRICT
    k0: float = Field(..., gt=0)
    beta: float = Field(..., gt=0)
    lambda0: float = Field(..., gt=0)
    eps1: float = Field(..., gt=0)
    eps2: float = Field(..., gt=0)
    eps3: float = Field(..., gt=0)
    delta1: float = Field(..., gt=0, le=1)
    delta2: float = Field(..., gt=0, le=1)
    mu1: float = Field(..., gt=0)
    mu2: float = Field(..., gt=0)
    alpha: float = Field(..., gt=0)


TABLE_II_DEPTH = SRiseGains(k0=2.45, beta=3.75, lambda0=0.45, eps1=0.01, eps2=1e-5, eps3=0.24, delta1=0.85,
                            delta2=0.5, mu1=0.95, mu2=1.0, alpha=16.5)
TABLE_II_YAW = SRiseGains(k0=0.72, beta=0.05, lambda0=0.06, eps1=0.014, eps2=1e-5, eps3=0.06, delta1=0.6,
                          delta2=0.7, mu1=0.6, mu2=0.7, alpha=1.1)


class RiseGains(BaseModel):
    """RISE gains of one DOF (defaults: SubjuGator z entries, baselines.md s.5.2)."""

    model_config = STRICT
    alpha1: float = Field(5.0, gt=0)
    ks: float = Field(125.0, gt=0)
    alpha2: float = Field(0.3, gt=0)
    beta: float = Field(0.45, ge=0)


RISE_PRESETS = {
    # SubjuGator z and yaw entries of Fischer et al.'s vehicle code (baselines.md 5.2), tau in N / N m.
    "subjugator": (RiseGains(alpha1=5.0, ks=125.0, alpha2=0.3, beta=0.45), RiseGains(alpha1=4.0, ks=20.0, alpha2=0.05, beta=1.0)),
    # Table II's S+RISE evaluated at its small-error constants: alpha1 = alpha, ks = k0 eps1^(delta1-1),
    # alpha2 = lambda0 eps3^(delta2-1) (baselines.md 5.2), in Table II's units (use the S+RISE output_scale).
    "table2_equivalent": (RiseGains(alpha1=16.5, ks=4.89, alpha2=0.919, beta=0.5), RiseGains(alpha1=1.1, ks=3.97, alpha2=0.140, beta=0.05)),
}


def _stack(gains: list[BaseModel], field: str) -> np.ndarray:
    return np.array([getattr(g, field) for g in gains])


class SRise:
    """Batched S+RISE; ``gains`` has one entry per DOF (shared by the batch)."""

    def __init__(self, gains: list[SRiseGains], batch: int) -> None:
        self.g = {f: _stack(gains, f) for f in SRiseGains.model_fields}
        n = len(gains)
        self.I = np.zeros((batch, n))
        self.Sigma = np.zeros((batch, n))
        self.e2_0: np.ndarray | None = None
        self.k_0: np.ndarray | None = None

    def K(self, e2: np.ndarray) -> np.ndarray:
        g = self.g
        a = np.maximum(np.abs(e2), g["eps1"])
        return g["k0"] * a ** (g["delta1"] - 1)

    def Bgain(self, e2: np.ndarray) -> np.ndarray:
        g = self.g
        s = np.abs(e2) * np.tanh(np.abs(e2))
        return g["beta"] * np.maximum(s, g["eps2"])

    def Lambda(self, integral: np.ndarray) -> np.ndarray:
        g = self.g
        a = np.maximum(np.abs(integral), g["eps3"])
        return g["lambda0"] * a ** (g["delta2"] - 1)

    def e2(self, e1: np.ndarray, e1_dot: np.ndarray) -> np.ndarray:
        return e1_dot + self.g["alpha"] * np.tanh(e1)  # (14)

    def command(self, e1: np.ndarray, e1_dot: np.ndarray, h: float) -> np.ndarray:
        """tau of eq. (15) at this sample, then advance the integrals by h."""
        g = self.g
        e2 = self.e2(e1, e1_dot)
        if self.e2_0 is None:
            self.e2_0, self.k_0 = e2.copy(), self.K(e2)
        K = self.K(e2)
        tau = (K + 1) * e2 - (self.k_0 + 1) * self.e2_0 + self.Sigma
        th = np.tanh(e2)
        phi = (K + 1) * self.Lambda(self.I) * th
        phi_star = self.Bgain(e2) * (g["mu1"] ** 2 / 2 * th + g["mu2"] ** 2 * e2
                                     + 1.5 * g["mu1"] * g["mu2"] * np.sqrt(np.abs(e2)) * th)
        self.Sigma = self.Sigma + h * (phi + phi_star)
        self.I = self.I + h * e2
        return tau


class Rise:
    """Batched RISE (Fischer et al. 2014 form without feedforward)."""

    def __init__(self, gains: list[RiseGains], batch: int) -> None:
        self.g = {f: _stack(gains, f) for f in RiseGains.model_fields}
        self.nu = np.zeros((batch, len(gains)))
        self.e2_0: np.ndarray | None = None

    def command(self, e1: np.ndarray, e1_dot: np.ndarray, h: float) -> np.ndarray:
        g = self.g
        e2 = e1_dot + g["alpha1"] * e1
        if self.e2_0 is None:
            self.e2_0 = e2.copy()
        tau = (g["ks"] + 1) * (e2 - self.e2_0) + self.nu
        self.nu = self.nu + h * ((g["ks"] + 1) * g["alpha2"] * e2 + g["beta"] * np.sign(e2))
        return tau
