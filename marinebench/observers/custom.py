"""Observers of your own, run by marinebench like its built-in ones (``observer: {kind: custom, ...}``).

A variant names a class, ``source: my_observer.py:MyObserver`` (a file, relative to the experiment file that
names it) or ``source: mypackage.observers:MyObserver`` (an importable module), and its ``params`` (any
mapping, one per run, so ``sweep`` can vary them: ``key: params.omega``). The class implements the batched
protocol of :mod:`marinebench.observers.base`:

``scenario_kinds``
    the world kinds it applies to: ``open_loop_asv`` (CyberShip II) and/or ``dp_supply`` (Torben's DP world);
``signals``
    the names of the estimates ``outputs`` returns (``u``, ``v``, ``r``, ``sigma_u``, ... ``x``, ``b_x``, ...);
``__init__(self, params: list[dict], plant, dt: float)``
    one ``params`` mapping per run (B runs); ``plant`` is the observers' vessel model (``M``, ``Minv``, ``D``,
    ``params``); ``dt`` the engine step;
``n_state``, ``init() -> (B, n_state)``, ``outputs(xhat) -> {signal: (B,)}``, ``max_rate() -> float``
    as for every observer (``max_rate``: the largest |eigenvalue| of its error dynamics, for the step check);
``derivative(xhat, y, tau) -> (B, n_state)``
    a continuous observer, integrated with the plant by the engine's RK4 (``y``: measured x, y, psi; ``tau``:
    the known thrust, both ``(B, 3)``); or ``discrete = True`` and ``step(xhat, y, tau, k) -> xhat``.

The class is loaded and checked when the config is validated, so a missing file, a class without these
members, a world it does not apply to, or an instance whose ``max_rate``, ``init``, ``outputs``, ``derivative`` or
``step`` returns the wrong thing or raises (:func:`check_built`) is a one-line config error; an exception the class
raises later, while the runs are simulated, is one line naming its file and line. Runs record the source's SHA-256 in the
manifest. With ``sweep --dask``, the file must be at the same path on the workers.
"""

from __future__ import annotations

import math
from numbers import Real
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, Field, field_validator

from marinebench.plugins import split_source, user_class
from marinebench.settings import STRICT

SCENARIO_KINDS = ("open_loop_asv", "dp_supply")  # worlds whose observers take the measured pose and the thrust
MEMBERS = ("signals", "scenario_kinds", "n_state", "init", "outputs", "max_rate")


def observer_class(source: str) -> type:
    """The class ``source`` names, imported and checked against the protocol above; ValueError otherwise."""
    cls = user_class(source, MEMBERS)
    name = split_source(source)[1]
    if getattr(cls, "discrete", False) and not hasattr(cls, "step"):
        raise ValueError(f"{name} is discrete but lacks step: see marinebench/observers/custom.py")
    if not getattr(cls, "discrete", False) and not hasattr(cls, "derivative"):
        raise ValueError(f"{name} lacks derivative (or discrete = True and step): see marinebench/observers/custom.py")
    unknown = set(cls.scenario_kinds) - set(SCENARIO_KINDS)
    if unknown:
        raise ValueError(f"{name}.scenario_kinds: {sorted(unknown)} (custom observers apply to {', '.join(SCENARIO_KINDS)})")
    return cls


def check_built(observer: Any, n_runs: int) -> None:
    """What a built observer returns, checked before anything runs (ValueError naming the member): ``max_rate()``
    a finite number >= 0, ``init()`` of shape (B, n_state), ``outputs(init())`` every declared signal as (B,) and no other,
    ``derivative`` (or ``step``) from ``init()`` at a zero pose and thrust an array of shape (B, n_state).
    Otherwise a mistake in the class would surface as a traceback deep in the engine, or as wrong numbers."""
    name = type(observer).__name__
    rate = observer.max_rate()
    if not isinstance(rate, Real) or not math.isfinite(rate) or rate < 0:
        raise ValueError(f"{name}.max_rate() returned {rate!r}: expected a finite number >= 0 (rad/s)")
    x0 = np.asarray(observer.init())
    if x0.shape != (n_runs, observer.n_state):
        raise ValueError(f"{name}.init() has shape {x0.shape}: expected (B, n_state) = ({n_runs}, {observer.n_state})")
    out = observer.outputs(x0)
    missing = [s for s in observer.signals if s not in out]
    if missing:
        raise ValueError(f"{name}.outputs() lacks {missing}, declared in its signals")
    if undeclared := [s for s in out if s not in observer.signals]:
        raise ValueError(f"{name}.outputs() returns {undeclared}, not declared in its signals {list(observer.signals)}")
    wrong = {s: np.shape(out[s]) for s in observer.signals if np.shape(out[s]) != (n_runs,)}
    if wrong:
        s, shape = next(iter(wrong.items()))
        raise ValueError(f"{name}.outputs()['{s}'] has shape {shape}: expected (B,) = ({n_runs},)")
    y, tau = np.zeros((n_runs, 3)), np.zeros((n_runs, 3))  # a measured pose and a thrust, at the initial estimate
    member = "step" if getattr(observer, "discrete", False) else "derivative"
    moved = observer.step(x0.copy(), y, tau, 0) if member == "step" else observer.derivative(x0.copy(), y, tau)
    if not isinstance(moved, np.ndarray) or moved.shape != x0.shape:
        raise ValueError(f"{name}.{member}() returned {type(moved).__name__} of shape {np.shape(moved)}: expected an "
                         f"array (B, n_state) = ({n_runs}, {observer.n_state})")


class CustomTuning(BaseModel):
    """An observer class of your own (source: file.py:Class or module:Class; params: one mapping per run)."""

    model_config = STRICT
    kind: Literal["custom"] = "custom"
    source: str = Field(..., description="file.py:ClassName (relative to the experiment file) or package.module:ClassName")
    params: dict[str, Any] = Field(default_factory=dict, description="passed to the class, one mapping per run")

    @field_validator("source")
    @classmethod
    def _loadable(cls, source: str) -> str:
        observer_class(source)
        return source

    def estimated_signals(self) -> tuple[str, ...]:
        return tuple(observer_class(self.source).signals)
