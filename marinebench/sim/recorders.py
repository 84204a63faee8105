"""Streaming recorders: error moments over a time window and decimated traces for figures."""

from __future__ import annotations

import numpy as np


class ErrorMoments:
    """Welford running mean/variance of ``est - truth`` per signal over ``t >= t_start``.

    Also accumulates the mean square (for RMSE) and the maximum absolute error. Memory is O(B) per
    signal, independent of the horizon.
    """

    def __init__(self, signals: list[str], t_start: float, t_end: float = np.inf) -> None:
        self.signals, self.t_start, self.t_end = list(signals), t_start, t_end
        self.n = 0
        self.mean: dict[str, np.ndarray] = {}
        self.m2: dict[str, np.ndarray] = {}
        self.msq: dict[str, np.ndarray] = {}
        self.maxabs: dict[str, np.ndarray] = {}

    def update(self, k: int, t: float, truth: dict[str, np.ndarray], est: dict[str, np.ndarray]) -> None:
        if t < self.t_start - 1e-12 or t > self.t_end + 1e-12:
            return
        self.n += 1
        for name in self.signals:
            e = est[name] - truth[name]
            if self.n == 1:
                self.mean[name] = e.copy()
                self.m2[name] = np.zeros_like(e)
                self.msq[name] = e**2
                self.maxabs[name] = np.abs(e)
                continue
            delta = e - self.mean[name]
            self.mean[name] += delta / self.n
            self.m2[name] += delta * (e - self.mean[name])
            self.msq[name] += (e**2 - self.msq[name]) / self.n
            self.maxabs[name] = np.fmax(self.maxabs[name], np.abs(e))

    def result(self, metric: str) -> dict[str, np.ndarray]:
        """Per-run values of ``std`` (population), ``rmse``, ``mean`` or ``max_abs`` for each signal."""
        if self.n == 0:
            raise ValueError(f"no samples in the metric window t in [{self.t_start}, {self.t_end}]")
        out = {}
        for name in self.signals:
            if metric == "std":
                out[name] = np.sqrt(self.m2[name] / self.n)
            elif metric == "rmse":
                out[name] = np.sqrt(self.msq[name])
            elif metric == "mean":
                out[name] = self.mean[name].copy()
            elif metric == "max_abs":
                out[name] = self.maxabs[name].copy()
            else:
                raise KeyError(metric)
        return out


class Traces:
    """Truth and estimates every ``every`` steps, for figures, of the runs ``columns`` (batch indices; all runs
    when None). Arrays are ``(T, len(columns))``: the figures draw seed 0 of each variant, so the runner keeps
    only those runs and the traces' memory does not grow with the number of seeds."""

    def __init__(self, signals: list[str], every: int, columns: np.ndarray | None = None) -> None:
        self.signals, self.every = list(signals), max(1, every)
        self.columns = slice(None) if columns is None else np.asarray(columns)
        self.t: list[float] = []
        self.truth: dict[str, list[np.ndarray]] = {s: [] for s in signals}
        self.est: dict[str, list[np.ndarray]] = {s: [] for s in signals}

    def update(self, k: int, t: float, truth: dict[str, np.ndarray], est: dict[str, np.ndarray]) -> None:
        if k % self.every:
            return
        self.t.append(t)
        for s in self.signals:
            self.truth[s].append(truth[s][self.columns].copy())
            if s in est:
                self.est[s].append(est[s][self.columns].copy())

    def arrays(self) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray]]:
        return (
            np.asarray(self.t),
            {s: np.asarray(v) for s, v in self.truth.items()},
            {s: np.asarray(v) for s, v in self.est.items() if v},
        )


class NormIntegral:
    """Streaming ``integral of ||S^-1 (est - truth)|| dt`` over ``[t_start, t_end)`` (Torben eq. (50)).

    ``scale`` are the per-signal denominators S (bis units); signals in ``wrap`` are angles whose
    error is wrapped to (-pi, pi]. Left Riemann sum at the engine step ``dt``.
    """

    def __init__(self, signals: list[str], scale: np.ndarray, wrap: set[str], t_start: float, t_end: float, dt: float):
        self.signals, self.scale, self.wrap = list(signals), np.asarray(scale, dtype=float), wrap
        self.t_start, self.t_end, self.dt = t_start, t_end, dt
        self.value: np.ndarray | None = None

    def update(self, k: int, t: float, truth: dict[str, np.ndarray], est: dict[str, np.ndarray]) -> None:
        if t < self.t_start - 1e-9 or t >= self.t_end - 1e-9:
            if self.value is None:
                self.value = np.zeros_like(next(iter(truth.values())))
            return
        sq = 0.0
        for name, s in zip(self.signals, self.scale):
            e = est[name] - truth[name]
            if name in self.wrap:
                e = np.pi - np.mod(np.pi - e, 2 * np.pi)
            sq = sq + (e / s) ** 2
        inc = np.sqrt(sq) * self.dt
        self.value = inc if self.value is None else self.value + inc


class ControlEnergy:
    """Tijjani's INT: integral of tau^2 dt per DOF from the first time the tracking error of that DOF (its
    reference ``<signal>_ref`` less its truth, both from the world's truth, so also in runs that report an
    observer's estimate) is within ``tol`` (the robot "reaches the reference") to the end."""

    def __init__(self, signals: list[str], controls: list[str], tol: list[float], dt: float) -> None:
        self.signals, self.controls, self.tol, self.dt = signals, controls, tol, dt
        self.value: dict[str, np.ndarray] = {}
        self.started: dict[str, np.ndarray] = {}

    def update(self, k: int, t: float, truth: dict[str, np.ndarray], est: dict[str, np.ndarray]) -> None:
        for s, c, tol in zip(self.signals, self.controls, self.tol):
            if s not in self.value:
                self.value[s] = np.zeros_like(truth[s])
                self.started[s] = np.zeros(truth[s].shape, dtype=bool)
            self.started[s] |= np.abs(truth[f"{s}_ref"] - truth[s]) <= tol
            self.value[s] += np.where(self.started[s], truth[c] ** 2 * self.dt, 0.0)


class TruthLog:
    """Every step's truth of some signals, ``(n_steps + 1, B)`` arrays (e.g. an undisturbed twin run)."""

    def __init__(self, signals: list[str], n_steps: int) -> None:
        self.signals, self.n = list(signals), n_steps + 1
        self.values: dict[str, np.ndarray] = {}

    def update(self, k: int, t: float, truth: dict[str, np.ndarray], est: dict[str, np.ndarray]) -> None:
        for s in self.signals:
            if s not in self.values:
                self.values[s] = np.full((self.n, truth[s].shape[0]), np.nan)
            self.values[s][k] = truth[s]


class RecoveryTime:
    """Time to recover from each disturbance event, per signal: for an event ending at ``t_e``, the last time
    in ``[t_e, t_e + window)`` at which the deviation exceeds ``tol``, minus ``t_e`` (0 if it never does).
    The deviation is ``|<signal>_ref - truth|`` (the tracking error, the reference from the world's truth, whichever
    estimate a run reports), or, with ``undisturbed`` (per-step truth of the same runs without the events),
    ``|truth - undisturbed|``: how far the events have moved the vehicle.
    Per run, the largest over the signal's events; ``window`` if it has not recovered by then."""

    def __init__(self, events: dict[str, list[float]], tol: dict[str, float], window: float,
                 undisturbed: dict[str, np.ndarray] | None = None) -> None:
        self.events, self.tol, self.window, self.undisturbed = events, tol, window, undisturbed
        self.last_out: dict[str, list[np.ndarray]] = {}

    def update(self, k: int, t: float, truth: dict[str, np.ndarray], est: dict[str, np.ndarray]) -> None:
        for s, ends in self.events.items():
            if s not in self.last_out:
                self.last_out[s] = [np.full(truth[s].shape, np.nan) for _ in ends]
            other = truth[f"{s}_ref"] if self.undisturbed is None else self.undisturbed[s][k]
            out = np.abs(other - truth[s]) > self.tol[s]
            for i, t_e in enumerate(ends):
                if t_e <= t < t_e + self.window:
                    self.last_out[s][i] = np.where(out, t, self.last_out[s][i])

    @property
    def value(self) -> dict[str, np.ndarray]:
        out = {}
        for s, ends in self.events.items():
            times = [np.nan_to_num(last - t_e, nan=0.0) for last, t_e in zip(self.last_out.get(s, []), ends)]
            out[s] = np.max(times, axis=0) if times else np.zeros(0)
        return out
