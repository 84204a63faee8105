"""Batch arrays: runs along axis 0, a vector's components along axis 1 (``(B, n)``)."""

from __future__ import annotations

import numpy as np


def columns(*cols: np.ndarray) -> np.ndarray:
    """The ``(B, n)`` array whose columns are the ``(B,)`` arrays ``cols``: ``np.stack(cols, axis=1)``, the same
    C-ordered float array and values, at a third of np.stack's per-call cost (which dominates the plant and
    observer derivatives at the batch sizes of a run: 2 µs against 7 µs for three columns of 10 runs)."""
    out = np.empty((cols[0].shape[0], len(cols)))
    for j, col in enumerate(cols):
        out[:, j] = col
    return out
