"""Notch filter of Torben et al. eq. (49), discretised with Tustin pre-warped at w0.

    H(s) = (s^2 + w0^2) / (s^2 + wc s + w0^2)

The notch has zero gain at w0 exactly in discrete time thanks to the pre-warping. Implemented as a
batched biquad (direct form II transposed) over ``(B, channels)``.
"""

from __future__ import annotations

import numpy as np


def tustin_notch(w0: float, wc: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Biquad coefficients ``(b, a)`` with ``a[0] = 1``."""
    K = w0 / np.tan(w0 * dt / 2)  # pre-warped bilinear constant
    b = np.array([K**2 + w0**2, 2 * (w0**2 - K**2), K**2 + w0**2])
    a = np.array([K**2 + wc * K + w0**2, 2 * (w0**2 - K**2), K**2 - wc * K + w0**2])
    return b / a[0], a / a[0]


class Biquad:
    """Batched second-order IIR filter; ``state`` has shape ``(B, channels, 2)``."""

    def __init__(self, b: np.ndarray, a: np.ndarray, shape: tuple[int, ...]) -> None:
        self.b, self.a = b, a
        self.state = np.zeros(shape + (2,))

    def reset_to(self, x: np.ndarray) -> None:
        """Start in steady state for a constant input x (DC gain 1): no start-up transient."""
        b, a = self.b, self.a
        self.state[..., 1] = (b[2] - a[2]) * x
        self.state[..., 0] = (b[1] - a[1]) * x + self.state[..., 1]

    def __call__(self, x: np.ndarray) -> np.ndarray:
        b, a, s = self.b, self.a, self.state
        y = b[0] * x + s[..., 0]
        s[..., 0] = b[1] * x - a[1] * y + s[..., 1]
        s[..., 1] = b[2] * x - a[2] * y
        return y
