"""Run one experiment: variants x seeds in a single batch through the one engine.

Run ``b = v * seeds + j`` is variant ``v`` with seed index ``j``; all variants share the world of seed
``j`` (paired comparisons). Observers of the same kind run as one batched group with per-run gains.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from marinebench.config import Experiment
from marinebench.metrics.stats import mean_ci
from marinebench.observers.bejarano import BejaranoObserver
from marinebench.observers.liu_eso import LiuEsoObserver
from marinebench.scenario import OpenLoopASV
from marinebench.sim.engine import ObserverGroup, check_step, simulate
from marinebench.sim.recorders import ErrorMoments, Traces

OBSERVERS = {"bejarano": BejaranoObserver, "liu_eso": LiuEsoObserver}


@dataclass
class RunResult:
    experiment: Experiment
    metrics: pd.DataFrame  # tidy: experiment, scenario, variant, seed, signal, metric, value, status
    summary: pd.DataFrame  # variant, signal, metric, mean, ci_low, ci_high, n, n_diverged
    traces: tuple[np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray]]
    run_variant: np.ndarray
    run_seed: np.ndarray
    wall_time: float
    max_rate: float
    designs: dict[str, dict] = field(default_factory=dict)


def build_groups(exp: Experiment, run_variant: np.ndarray, Minv: np.ndarray) -> list[ObserverGroup]:
    """One batched observer per observer kind, with one tuning per run."""
    groups = []
    for kind, cls in OBSERVERS.items():
        idx = np.array([b for b, v in enumerate(run_variant) if exp.variants[v].observer.kind == kind], dtype=int)
        if idx.size:
            tunings = [exp.variants[run_variant[b]].observer for b in idx]
            groups.append(ObserverGroup(cls(tunings, Minv), idx))
    return groups


def design_summary(exp: Experiment) -> dict[str, dict]:
    """Designed gains and poles per variant, for the manifest."""
    from marinebench.observers import bejarano

    out = {}
    for v in exp.variants:
        if v.observer.kind == "bejarano":
            rot, pos = bejarano.design(v.observer)
            out[v.name] = {
                "L_psi": rot.gain[:, 0].tolist(),
                "L_pz": pos.gain.tolist(),
                "beta_psi": rot.beta,
                "beta_p": pos.beta,
                "slowest_pole_psi": float(rot.poles.real.max()),
                "slowest_pole_p": float(pos.poles.real.max()),
                "fastest_pole_abs": float(max(np.abs(rot.poles).max(), np.abs(pos.poles).max())),
            }
        else:
            eps, k = v.observer.eps, v.observer.k
            out[v.name] = {"gains": [k[0] / eps, k[1] / eps**2, k[2] / eps**3], "mode": v.observer.mode}
    return out


def run(exp: Experiment, progress: Callable[[int], None] | None = None, on_start: Callable[[int], None] | None = None) -> RunResult:
    """Design, check the step, simulate and reduce to tidy metrics."""
    V, S = len(exp.variants), exp.seeds
    run_variant = np.repeat(np.arange(V), S)
    run_seed = np.tile(np.arange(S), V)
    sc = exp.scenario
    world = OpenLoopASV(sc, exp.seed, run_seed)
    groups = build_groups(exp, run_variant, world.plant.Minv)
    rate = check_step(groups, sc.dt, exp.engine.stiffness_limit if exp.engine.check_step else np.inf)
    n_steps = round(sc.horizon / sc.dt)
    moments = [ErrorMoments(m.signals, m.t_start, m.t_end or sc.horizon) for m in exp.metrics]
    trace_signals = sorted({s for g in groups for s in g.observer.signals})
    traces = Traces(trace_signals, round(exp.engine.trace_dt / sc.dt))
    if on_start is not None:
        on_start(n_steps)
    t0 = time.perf_counter()
    diverged = simulate(world, groups, sc.dt, n_steps, moments + [traces], progress)
    wall = time.perf_counter() - t0

    rows = []
    for spec, rec in zip(exp.metrics, moments):
        values = rec.result(spec.kind)
        for signal, per_run in values.items():
            for b in range(V * S):
                ok = not diverged[b] and np.isfinite(per_run[b])
                rows.append(
                    (exp.name, sc.name, exp.variants[run_variant[b]].name, int(run_seed[b]), signal, spec.kind,
                     float(per_run[b]) if ok else float("nan"), "ok" if ok else "diverged")
                )
    metrics = pd.DataFrame(rows, columns=["experiment", "scenario", "variant", "seed", "signal", "metric", "value", "status"])
    summary = summarise(metrics)
    return RunResult(exp, metrics, summary, traces.arrays(), run_variant, run_seed, wall, rate, design_summary(exp))


def summarise(metrics: pd.DataFrame, level: float = 0.95) -> pd.DataFrame:
    """Mean and CI over seeds per (variant, signal, metric), diverged runs excluded and counted."""
    out = []
    for (variant, signal, metric), g in metrics.groupby(["variant", "signal", "metric"], sort=False):
        ok = g[g["status"] == "ok"]["value"].to_numpy()
        m, lo, hi = mean_ci(ok, level)
        out.append((variant, signal, metric, m, lo, hi, int(ok.size), int((g["status"] != "ok").sum())))
    return pd.DataFrame(out, columns=["variant", "signal", "metric", "mean", "ci_low", "ci_high", "n", "n_diverged"])
