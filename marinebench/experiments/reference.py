"""Plain per-run reference of the DP observers and the KPI, for equivalence tests and ``marinebench bench``.

One run at a time, written as directly as the equations read: 9-vectors and 9 x 9 matrices, the
one-step maps (``observers.dp.one_step_maps``) formed from A_i(psi) at every step (no harmonic fit), the
window logic with scalars, the jump with ``numpy.linalg.solve`` and ``cond``. The world (plant and sensors) is the same code as the
batched engine with a batch of one, so both see identical measurements.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np
import pandas as pd

from marinebench.config import Experiment
from marinebench.design.kalman import dp_system
from marinebench.experiments.runner import make_world, plant_of
from marinebench.models.supply import bis_scale
from marinebench.observers.base import wrap_angle
from marinebench.observers.dp import gain_pair, jump_scale, one_step_maps

SIGNALS = ("x", "y", "psi", "b_x", "b_y", "b_n", "u", "v", "r")


def reference_run(exp: Experiment, variant: int, seed: int = 0) -> dict[str, float]:
    """Simulate one (variant, seed) of a DP experiment; returns its J metrics and jump count."""
    v = exp.variants[variant]
    t_obs = v.observer
    sc = exp.scenario
    world = make_world(exp.model_copy(update={"variants": [v]}), np.array([0]), np.array([seed]))
    model = plant_of(sc)  # the observers' design model (the plant's unless design_vessel is set)
    M, D, Minv = model.M, model.D, model.Minv
    g = gain_pair(t_obs.design_key(sc.model.L), M, D)
    k = getattr(t_obs, "k", 0.0)
    n_window = max(1, round(getattr(t_obs, "delta", 2.5) / sc.dt))
    eps = np.multiply(getattr(t_obs, "eps", (np.inf,) * 3), getattr(t_obs, "eps_scale", 1.0))
    c_max, check = getattr(t_obs, "c_max", 1e10), getattr(t_obs, "check_cond", True)
    S, S_obs = bis_scale(sc.vessel), jump_scale(t_obs, bis_scale(sc.model))  # the KPI's units, the jump's coordinates
    z = [np.zeros(9), np.zeros(9)]
    phi = [np.eye(9), np.eye(9)]
    windows = [(m.label, *m.window(sc.horizon)) for m in exp.metrics if m.kind == "j_tot"]
    J = {name: 0.0 for name, *_ in windows}
    x = world.x0.copy()
    counter = jumps = 0
    dt, n_steps = sc.dt, round(sc.horizon / sc.dt)
    for step in range(n_steps + 1):
        t = step * dt
        world.begin_step(step, t, x)
        truth = world.truth(t, x)
        e = np.array([z[0][i] - truth[s][0] for i, s in enumerate(SIGNALS)])
        e[2] = wrap_angle(e[2])
        norm = float(np.sqrt(np.sum((e / S) ** 2)))
        for name, a, b in windows:
            if a - 1e-9 <= t < b - 1e-9:
                J[name] += norm * dt
        if step == n_steps:
            break
        y, tau = world.y[0].copy(), world.tau[0].copy()
        # plant: RK4
        f = lambda tt, xx: world.derivative(tt, xx)[0]
        k1 = f(t, x)
        k2 = f(t + dt / 2, x + dt / 2 * k1)
        k3 = f(t + dt / 2, x + dt / 2 * k2)
        k4 = f(t + dt, x + dt * k3)
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        # observers: z_i+ = P_i z_i + G_y y + G_u tau, Phi_i+ = P_i Phi_i
        A = dp_system(M, D, y[2])  # eq. (43) at the measured heading
        R = A[0:3, 6:9]
        for i in range(2):
            L = np.vstack([g[i].K1, g[i].K2, Minv @ R.T @ g[i].K3])
            Acl = A.copy()
            Acl[:, 0:3] -= L
            P, Gy, Gu = one_step_maps(Acl, L, Minv, dt, t_obs.discretization)
            z[i] = P @ z[i] + Gy @ y + Gu @ tau
            phi[i] = P @ phi[i]
        counter += 1
        if counter >= n_window:
            innov = y - z[0][0:3]
            innov[2] = wrap_angle(innov[2])
            # Psi in the coordinates z_s = S_obs^-1 z (bis-scaled: the same equation, better conditioned)
            p1, p2 = (p * S_obs[None, :] / S_obs[:, None] for p in phi)
            Ys = np.linalg.solve(p1.T, p2.T).T
            Xs = np.eye(9) - Ys
            cond = np.linalg.cond(Xs)
            if np.any(np.abs(innov) >= eps) and (not check or cond <= c_max) and np.isfinite(cond):
                z_star = S_obs * np.linalg.solve(Xs, z[1] / S_obs - Ys @ (z[0] / S_obs))
                z[0] = k * z_star + (1 - k) * z[0]
                jumps += int(k > 0)
            z[1] = z[0].copy()
            phi = [np.eye(9), np.eye(9)]
            counter = 0
    return {**J, "n_jumps": float(jumps)}


def against_reference(exp: Experiment, metrics: pd.DataFrame, picks: Sequence[int]) -> tuple[float, float]:
    """The per-run reference on the variants ``picks`` of a DP experiment whose batched ``metrics`` are given:
    returns the reference's seconds per run and the largest relative J_tot difference from the batch (what
    ``marinebench bench`` and the pytest-benchmark suite report)."""
    t0 = time.perf_counter()
    refs = [reference_run(exp, int(i)) for i in picks]
    per_run = (time.perf_counter() - t0) / len(picks)
    values = metrics.set_index(["variant", "metric"])["value"]
    worst = max(abs(values[exp.variants[int(i)].name, "J_tot"] / r["J_tot"] - 1) for i, r in zip(picks, refs))
    return per_run, float(worst)
