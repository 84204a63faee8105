"""Confidence intervals over seeds as small pure functions."""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from functools import lru_cache

import numpy as np
from scipy import stats


@contextmanager
def diverged_runs_quiet() -> Iterator[None]:
    """numpy's nan-reductions (``nanmean``, ``nanmin``, ...) over the runs of a point where every one diverged give
    nan, shown as '–' (and a claim checked on it fails), without their RuntimeWarning on the terminal."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "Mean of empty slice|All-NaN slice encountered", RuntimeWarning)
        yield


@lru_cache(maxsize=256)
def _t_quantile(q: float, dof: int) -> float:
    """Student-t quantile (cached: a sweep's summary asks for the same few thousands of times)."""
    return stats.t.ppf(q, dof)


def mean_ci(values: np.ndarray, level: float = 0.95) -> tuple[float, float, float]:
    """Mean and Student-t confidence interval ``(mean, low, high)`` of finite ``values``.

    With fewer than two finite values the interval is ``(nan, nan)``.
    """
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return float("nan"), float("nan"), float("nan")
    m = float(v.mean())
    if v.size < 2:
        return m, float("nan"), float("nan")
    half = float(_t_quantile(0.5 + level / 2, v.size - 1) * v.std(ddof=1) / np.sqrt(v.size))
    return m, m - half, m + half
