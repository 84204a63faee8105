"""First-order Gauss-Markov sensor error, Torben et al. eq. (48) (after Beard & McLain 2012).

    v[n+1] = exp(-c Ts) v[n] + rho[n],   rho ~ N(0, sigma^2),  v[0] = 0

``sigma`` is the *driving* standard deviation; the stationary standard deviation is
``sigma / sqrt(1 - exp(-2 c Ts))`` (about 23.5 sigma for 1/c = 1100 s, Ts = 1 s).
"""

from __future__ import annotations

import numpy as np


def stationary_std(sigma: float | np.ndarray, c: float, ts: float) -> float | np.ndarray:
    return sigma / np.sqrt(1.0 - np.exp(-2.0 * c * ts))


def gm_step(v: np.ndarray, sigma: np.ndarray, c: float, ts: float, normal: np.ndarray) -> np.ndarray:
    """One sample of eq. (48) for a batch; ``normal`` are standard normal draws of v's shape."""
    return np.exp(-c * ts) * v + sigma * normal
