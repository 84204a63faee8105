"""JONSWAP spectrum and its harmonic-superposition realisation (models.md section 2c).

    S(w) = (1 - 0.287 ln g) alpha g^2 w^-5 exp(-5/4 (w0/w)^4) gamma^exp(-(w - w0)^2 / (2 s^2 w0^2))
    alpha = (5/16) Hs^2 w0^4 / g^2,  s = 0.07 (w <= w0), 0.09 (w > w0)

(DNV-RP-C205; MSS ``waveSpectrum.m`` type 7). The factor (1 - 0.287 ln gamma) keeps 4 sqrt(m0) ~ Hs.
"""

from __future__ import annotations

import numpy as np

G = 9.81


def jonswap(omega: np.ndarray, hs: float, tp: float, gamma: float = 3.3) -> np.ndarray:
    """Wave elevation spectrum S(omega) [m^2 s] for significant height hs [m] and peak period tp [s]."""
    w = np.asarray(omega, dtype=float)
    w0 = 2 * np.pi / tp
    alpha = 5.0 / 16.0 * hs**2 * w0**4 / G**2
    sigma = np.where(w <= w0, 0.07, 0.09)
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        pm = alpha * G**2 * w**-5.0 * np.exp(-1.25 * (w0 / w) ** 4)
        peak = gamma ** np.exp(-((w - w0) ** 2) / (2 * sigma**2 * w0**2))
        s = (1 - 0.287 * np.log(gamma)) * pm * peak
    return np.where(w > 0, s, 0.0)


def dnv_gamma(hs: float, tp: float) -> float:
    """DNV's peak-enhancement rule, used by MSS when gamma is not given."""
    k = tp / np.sqrt(hs)
    if k <= 3.6:
        return 5.0
    if k <= 5.0:
        return float(np.exp(5.75 - 1.15 * k))
    return 1.0


def component_amplitudes(omega: np.ndarray, d_omega: np.ndarray, hs: float, tp: float, gamma: float) -> np.ndarray:
    """Harmonic amplitudes A_k = sqrt(2 S(w_k) dw_k) of zeta(t) = sum_k A_k cos(w_k t + eps_k)."""
    return np.sqrt(2 * jonswap(omega, hs, tp, gamma) * d_omega)
