"""Batched fixed-step engine: one Python loop over time, numpy over runs.

The plant and every continuous observer group are integrated jointly by classic RK4 with the same
step, so those observers see the measurement at the RK4 stage times (no zero-order-hold lag).
*Discrete* observer groups (``observer.discrete = True``, e.g. the DP observers fed by sampled,
held sensors) are advanced once per step by ``observer.step(state, y_k, tau_k, k)`` with the
measurement at the start of the step (the world's ``sampled(t, x)`` if it has one, e.g. a held sample
while continuous observers see it interpolated). A world may have a ``begin_step(k, t, x)`` hook, called at the
start of every step, to sample and filter its sensors. Stiff observer gains are handled by a step
check (see :func:`check_step`): RK4 is accurate when ``dt * |lambda|_max`` is well below its stability
limit 2.78; the default limit is 0.5.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from marinebench.errors import StiffnessError
from marinebench.observers.base import BatchObserver


class World(Protocol):
    """A batch of simulated worlds (plant, inputs, environment, sensors). Optional hooks: ``begin_step(k, t, x)``,
    ``sampled(t, x)`` (see the module's docstring) and ``observer_rates() -> (B,)``, the fastest pole of observers
    the world integrates in its own state (the ROV's CDO and EO), which :func:`check_step` counts."""

    x0: np.ndarray

    def derivative(self, t: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return ``(x_dot, y, tau)``: state derivative, measurement and known input at time t."""

    def truth(self, t: float, x: np.ndarray) -> dict[str, np.ndarray]:
        """True values of the named signals, each ``(B,)``."""


@dataclass
class ObserverGroup:
    """One observer kind running on the runs ``index`` of the batch."""

    observer: BatchObserver
    index: np.ndarray


class Recorder(Protocol):
    def update(self, k: int, t: float, truth: dict[str, np.ndarray], est: dict[str, np.ndarray]) -> None: ...


RATE_RTOL = 1e-4
"""Relative error allowed in a computed |lambda|max: a pole of multiplicity m comes out of the polynomial roots or
eigenvalues to about machine epsilon^(1/m) (Liu's ESO at eps = 0.1 has a triple pole at 10 rad/s, computed as
10.0000248), so a step exactly at the limit for such a pole (0.05 s there) is not refused for that error."""


def check_step(groups: list[ObserverGroup], dt: float, limit: float, world: World | None = None) -> float:
    """Refuse a step that RK4 cannot integrate accurately for the designed observer poles: the groups' and those of
    observers a world integrates itself (its ``observer_rates()``, per run, if it has one: the ROV's CDO and EO).
    The refusal suggests the largest step that passes, rounded down to 3 significant digits."""
    rate = max((g.observer.max_rate() for g in groups), default=0.0)
    if hasattr(world, "observer_rates"):
        rate = max(rate, float(np.max(world.observer_rates(), initial=0.0)))
    if dt * rate > limit * (1 + RATE_RTOL):
        raise StiffnessError(
            f"dt={dt:g} s is too large for observer poles up to |lambda|={rate:.4g} rad/s "
            f"(dt*|lambda| = {dt * rate:.3g} > {limit:g}); use dt <= {rounded_down(limit * (1 + RATE_RTOL) / rate):.3g}"
        )
    return rate


def rounded_down(x: float, digits: int = 3) -> float:
    """``x`` > 0 rounded down to ``digits`` significant digits (0.0104999 -> 0.0104), so that it stays below ``x``."""
    scale = 10.0 ** (math.floor(math.log10(x)) - digits + 1)
    return math.floor(x / scale) * scale


def rk4_step(rhs: Callable[[float, list[np.ndarray]], list[np.ndarray]], t: float, dt: float,
             s: list[np.ndarray]) -> list[np.ndarray]:
    """One classic Runge-Kutta step of the jointly integrated states ``s`` (plant first, then the continuous
    observers), ``rhs(t, s)`` giving their derivatives."""

    def axpy(a: float, ds: list[np.ndarray]) -> list[np.ndarray]:
        return [si + a * di for si, di in zip(s, ds)]

    k1 = rhs(t, s)
    k2 = rhs(t + dt / 2, axpy(dt / 2, k1))
    k3 = rhs(t + dt / 2, axpy(dt / 2, k2))
    k4 = rhs(t + dt, axpy(dt, k3))
    return [si + dt / 6 * (a + 2 * b + 2 * c + d) for si, a, b, c, d in zip(s, k1, k2, k3, k4)]


def simulate(
    world: World,
    groups: list[ObserverGroup],
    dt: float,
    n_steps: int,
    recorders: list[Recorder],
    progress: Callable[[int], None] | None = None,
    progress_every: int = 1000,
) -> np.ndarray:
    """Integrate plant and observers for ``n_steps`` steps; returns the per-run ``diverged`` mask.

    Recorders are updated at every step ``k = 0..n_steps`` with the truth and the gathered estimates.
    ``progress`` hears of every ``progress_every`` steps done and of the remainder at the end, ``n_steps`` in all.
    """
    B = world.x0.shape[0]
    continuous = [g for g in groups if not getattr(g.observer, "discrete", False)]
    discrete = [g for g in groups if getattr(g.observer, "discrete", False)]
    groups = continuous + discrete
    nc = len(continuous)
    state = [world.x0.copy()] + [g.observer.init() for g in groups]
    begin_step = getattr(world, "begin_step", None)
    sampled = getattr(world, "sampled", None) or (lambda t, x: world.derivative(t, x)[1:])  # discrete observers' input
    world_estimates = getattr(world, "estimates", None)  # e.g. a reference, so est - truth is a tracking error

    def rhs(t: float, s: list[np.ndarray]) -> list[np.ndarray]:
        x_dot, y, tau = world.derivative(t, s[0])
        return [x_dot] + [g.observer.derivative(xh, y[g.index], tau[g.index]) for g, xh in zip(continuous, s[1:])]

    signals = sorted({name for g in groups for name in g.observer.signals})
    est = {name: np.full(B, np.nan) for name in signals}
    with np.errstate(all="ignore"):
        for k in range(n_steps + 1):
            t = k * dt
            if begin_step is not None:
                begin_step(k, t, state[0])
            _gather(groups, state[1:], est)
            if world_estimates is not None:
                est.update(world_estimates(t, state[0]))
            truth = world.truth(t, state[0])
            for rec in recorders:
                rec.update(k, t, truth, est)
            if k == n_steps:
                break
            new = rk4_step(rhs, t, dt, state[: nc + 1])
            if discrete:
                y, tau = sampled(t, state[0])
                new += [g.observer.step(xh, y[g.index], tau[g.index], k) for g, xh in zip(discrete, state[nc + 1 :])]
            state = new
            if progress is not None and ((k + 1) % progress_every == 0 or k + 1 == n_steps):
                progress((k + 1) % progress_every or progress_every)  # a block, or the rest at the end
    diverged = ~np.isfinite(state[0]).all(axis=1)
    for g, xh in zip(groups, state[1:]):
        diverged[g.index] |= ~np.isfinite(xh).all(axis=1)
    return diverged


def _gather(groups: list[ObserverGroup], states: list[np.ndarray], est: dict[str, np.ndarray]) -> None:
    """Write each group's outputs (named signals, one value per run) into the batch-wide ``est`` at its runs."""
    for g, xh in zip(groups, states):
        for name, value in g.observer.outputs(xh).items():
            est[name][g.index] = value
