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


def spearman_rows(x: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Spearman's rank correlation of ``x`` ``(k,)`` with each row of ``ys`` ``(B, k)``, ``(B,)``: the Pearson
    correlation of their average ranks, as ``scipy.stats.spearmanr`` gives it for one row (to rounding), for every
    row at once (a trend claim's bootstrap asks for thousands). nan where a row holds a nan or is constant."""
    ys = np.asarray(ys, dtype=float)
    missing = np.isnan(ys).any(axis=1)
    rx = stats.rankdata(x)
    ry = stats.rankdata(np.where(missing[:, None], 0.0, ys), axis=1)
    dx, dy = rx - rx.mean(), ry - ry.mean(axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = np.clip((dy @ dx) / np.sqrt((dx @ dx) * np.einsum("ij,ij->i", dy, dy)), -1.0, 1.0)
    return np.where(missing, np.nan, rho)


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
