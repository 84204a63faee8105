"""Liu, Wang & Peng (2019) extended state observer, epsilon-scaled (reconstruction, baselines.md s.1).

    eta_hat'   = R(psi) nu_hat            - (k1/eps)   phi1(eta_tilde)
    nu_hat'    = M^-1 tau + sigma_hat     - (k2/eps^2) R^T(psi) phi2(eta_tilde)
    sigma_hat' =                          - (k3/eps^3) R^T(psi) phi3(eta_tilde)

with ``eta_tilde = eta_hat - y`` (heading wrapped). ``mode="linear"``: phi_i(x) = x (default, poles
at -1/eps for k = (3, 3, 1)); ``mode="fal"``: Han's fal on the scaled error ``eta_tilde/eps^2`` with
exponents alpha, 2 alpha - 1, 3 alpha - 2 (the homogeneous finite-time form). State ``(B, 9)``:
``[eta_hat(3), nu_hat(3), sigma_hat(3)]``.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, Field

from marinebench.batch import columns
from marinebench.observers.base import wrap_angle
from marinebench.settings import STRICT


class LiuEsoTuning(BaseModel):
    """Tuning of the reconstructed Liu-Wang-Peng ESO ("LIU19-reconstructed")."""

    model_config = STRICT
    kind: Literal["liu_eso"] = "liu_eso"
    eps: float = Field(0.1, gt=0, description="time-scale parameter epsilon [s]")
    k: tuple[float, float, float] = Field((3.0, 3.0, 1.0), description="Hurwitz coefficients k1, k2, k3")
    mode: Literal["linear", "fal"] = Field("linear", description="correction nonlinearity")
    alpha: float = Field(0.95, gt=2 / 3, le=1, description="fal exponent (mode=fal)")
    fal_d: float = Field(0.01, gt=0, description="linear zone of fal in scaled units (mode=fal)")

    def gains(self) -> np.ndarray:
        """The linear gains ``(k1/eps, k2/eps^2, k3/eps^3)``; in numpy, so an extreme eps gives 0 or inf, not an
        OverflowError."""
        with np.errstate(over="ignore", divide="ignore"):
            return np.asarray(self.k) / self.eps ** np.arange(1, 4)


def fal(x: np.ndarray, alpha: float, d: float) -> np.ndarray:
    """Han's fal: linear ``x / d^(1-alpha)`` inside ``|x| <= d``, ``sig^alpha(x)`` outside."""
    ax = np.abs(x)
    return np.where(ax <= d, x / d ** (1 - alpha), np.sign(x) * ax**alpha)


class LiuEsoObserver:
    """Batched Liu ESO; one tuning per run."""

    n_state = 9
    signals = ("u", "v", "r", "sigma_u", "sigma_v", "sigma_r")

    def __init__(self, tunings: list[LiuEsoTuning], Minv: np.ndarray) -> None:
        self.eps = np.array([t.eps for t in tunings])[:, None]
        self.k = np.array([t.k for t in tunings])
        # mode, alpha and fal_d may differ per run: linear and fal tunings share one batch
        self.fal_runs = np.array([t.mode == "fal" for t in tunings])[:, None]
        self.alpha = np.array([t.alpha for t in tunings])[:, None]
        self.fal_d = np.array([t.fal_d for t in tunings])[:, None]
        self.Minv = Minv

    def init(self) -> np.ndarray:
        return np.zeros((self.eps.shape[0], self.n_state))

    def _corrections(self, e: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        eps, k = self.eps, self.k
        if not self.fal_runs.any():
            return self._linear(e)
        a, d, es = self.alpha, self.fal_d, e / eps**2
        fal_terms = (
            eps * k[:, :1] * fal(es, a, d),
            k[:, 1:2] * fal(es, 2 * a - 1, d),
            k[:, 2:3] / eps * fal(es, 3 * a - 2, d),
        )
        if self.fal_runs.all():
            return fal_terms
        return tuple(np.where(self.fal_runs, f, g) for f, g in zip(fal_terms, self._linear(e)))

    def _linear(self, e: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        eps, k = self.eps, self.k
        return k[:, :1] / eps * e, k[:, 1:2] / eps**2 * e, k[:, 2:3] / eps**3 * e

    def derivative(self, xhat: np.ndarray, y: np.ndarray, tau: np.ndarray) -> np.ndarray:
        psi = y[:, 2]
        c, s = np.cos(psi), np.sin(psi)
        e = xhat[:, 0:3] - y
        e[:, 2] = wrap_angle(e[:, 2])
        g1, g2, g3 = self._corrections(e)

        def rot_t(w: np.ndarray) -> np.ndarray:  # R^T(psi) w
            return columns(c * w[:, 0] + s * w[:, 1], -s * w[:, 0] + c * w[:, 1], w[:, 2])

        nu = xhat[:, 3:6]
        d = np.empty_like(xhat)
        d[:, 0] = c * nu[:, 0] - s * nu[:, 1] - g1[:, 0]
        d[:, 1] = s * nu[:, 0] + c * nu[:, 1] - g1[:, 1]
        d[:, 2] = nu[:, 2] - g1[:, 2]
        d[:, 3:6] = tau @ self.Minv.T + xhat[:, 6:9] - rot_t(g2)
        d[:, 6:9] = -rot_t(g3)
        return d

    def outputs(self, xhat: np.ndarray) -> dict[str, np.ndarray]:
        names = ("u", "v", "r", "sigma_u", "sigma_v", "sigma_r")
        return {n: xhat[:, 3 + i] for i, n in enumerate(names)}

    def max_rate(self) -> float:
        """The largest |pole| of the linear error dynamics. Their characteristic polynomial
        ``s^3 + (k1/eps) s^2 + (k2/eps^2) s + k3/eps^3`` is ``eps^-3 p(eps s)`` with ``p(x) = x^3 + k1 x^2 + k2 x + k3``,
        so the poles are p's roots over eps: no gain is formed, and an extreme eps cannot overflow into NaN."""
        return float(max(np.abs(np.roots([1.0, *k])).max() / eps for eps, k in zip(self.eps[:, 0], self.k)))
