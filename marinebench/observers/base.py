"""Observer protocol shared by every estimator (scikit-learn-like lifecycle).

``design`` (pure, cached) turns a tuning into gains; the batched observer is then built from one
tuning per run so gains that differ per run are stacked as ``(B, n, m)`` arrays. ``derivative`` is
the continuous-time right-hand side; the engine integrates it jointly with the plant. A discrete-time
observer (the DP observers) sets ``discrete = True`` and implements ``step(xhat, y, tau, k) -> xhat``
instead, called once per engine step with the world's held sample (``world.sampled``).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from marinebench.batch import columns


class BatchObserver(Protocol):
    """A batch of ``B`` observers of one kind (tunings may differ per run)."""

    n_state: int
    signals: tuple[str, ...]

    def init(self) -> np.ndarray:
        """Initial estimate ``(B, n_state)``."""

    def derivative(self, xhat: np.ndarray, y: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """``d xhat / dt`` given measurement ``y (B, 3)`` and known input ``tau (B, 3)``."""

    def outputs(self, xhat: np.ndarray) -> dict[str, np.ndarray]:
        """Named estimates, each ``(B,)``."""

    def max_rate(self) -> float:
        """Largest |eigenvalue| of the error dynamics over the batch [rad/s] (for the dt check)."""


def chain_response(gains, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Frequency responses of one positional channel of the open-loop ASV observers, linearised at rest.

    At r = 0 both Liu's ESO and Bejarano's positional observer (eq. (14) with (26)) reduce per axis to the chain
    ``x1' = x2 + l1 e, x2' = x3 + l2 e, x3' = l3 e`` with ``e = y - x1``; its velocity and disturbance estimates
    per unit position measurement at ``omega`` [rad/s] are ``(l2 s + l3) s / p(s)`` and ``l3 s^2 / p(s)``,
    ``p(s) = s^3 + l1 s^2 + l2 s + l3``. For a vessel at rest these are (minus) the transfers from position
    noise to the errors e_u and e_sigma_u (Table IV's noise part; ``tests/test_observers.py``)."""
    l1, l2, l3 = gains
    s = 1j * np.asarray(omega, dtype=float)
    p = s**3 + l1 * s**2 + l2 * s + l3
    return (l2 * s + l3) * s / p, l3 * s**2 / p


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Wrap angles to (-pi, pi]."""
    return np.pi - np.mod(np.pi - a, 2 * np.pi)


def rotate2(psi: np.ndarray, xy: np.ndarray, transpose: bool = False) -> np.ndarray:
    """Apply R2(psi) (or its transpose) to ``xy (B, 2)``."""
    c, s = np.cos(psi), np.sin(psi)
    if transpose:
        s = -s
    return columns(c * xy[:, 0] - s * xy[:, 1], s * xy[:, 0] + c * xy[:, 1])
