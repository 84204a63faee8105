"""Observers of your own, run by marinebench like its built-in ones (``observer: {kind: custom, ...}``).

A variant names a class, ``source: my_observer.py:MyObserver`` (a file, relative to the experiment file that
names it) or ``source: mypackage.observers:MyObserver`` (an importable module), and its ``params`` (any
mapping, one per run, so ``sweep`` can vary them: ``key: params.omega``). The class implements the batched
protocol of :mod:`marinebench.observers.base`:

``scenario_kinds``
    the world kinds it applies to: ``open_loop_asv`` (CyberShip II) and/or ``dp_supply`` (Torben's DP world), or
    ``rov_tracking`` (the closed-loop ROV world, two DOF: its own members, :mod:`marinebench.observers.custom_rov`);
``signals``
    a tuple of the names of the estimates ``outputs`` returns (``u``, ``v``, ``r``, ``sigma_u``, ... ``x``, ``b_x``, ...);
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
``step`` returns the wrong thing or raises (:func:`check_built`) is a one-line config error. While the runs are
simulated every answer is checked again (:class:`CheckedObserver`), and an exception the class raises is one line
naming its file and line. Runs record the source's SHA-256 in the manifest. With ``sweep --dask``, the file must be
at the same path on the workers.
"""

from __future__ import annotations

import math
from numbers import Integral, Real
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, Field, field_validator

from marinebench.errors import ProtocolError
from marinebench.plugins import split_source, user_class
from marinebench.settings import STRICT

SCENARIO_KINDS = ("open_loop_asv", "dp_supply", "rov_tracking")  # worlds whose observers take a measured pose and the thrust
MEMBERS = ("signals", "scenario_kinds", "n_state", "init", "outputs", "max_rate")


def observer_class(source: str) -> type:
    """The class ``source`` names, imported and checked against the protocol above; ValueError otherwise."""
    cls = user_class(source, MEMBERS)
    name = split_source(source)[1]
    if getattr(cls, "discrete", False) and not hasattr(cls, "step"):
        raise ValueError(f"{name} is discrete but lacks step: see marinebench/observers/custom.py")
    if not getattr(cls, "discrete", False) and not hasattr(cls, "derivative"):
        raise ValueError(f"{name} lacks derivative (or discrete = True and step): see marinebench/observers/custom.py")
    names(f"{name}.scenario_kinds", cls.scenario_kinds, "('open_loop_asv',)")
    names(f"{name}.signals", cls.signals)
    whole_number(f"{name}.n_state", cls.n_state)
    unknown = set(cls.scenario_kinds) - set(SCENARIO_KINDS)
    if unknown:
        raise ValueError(f"{name}.scenario_kinds: {sorted(unknown)} (custom observers apply to {', '.join(SCENARIO_KINDS)})")
    return cls


def names(what: str, value: Any, example: str = "('u', 'v')") -> tuple[str, ...]:
    """``value`` as a tuple of distinct names (``signals``, ``scenario_kinds``); a ProtocolError for a single string
    (which would be read as its letters), an empty or repeated entry, or anything else."""
    if isinstance(value, str) or not isinstance(value, tuple | list) or not all(isinstance(v, str) for v in value):
        raise ProtocolError(f"{what} is {value!r}: expected a tuple of names, e.g. {example}")
    if not value:
        raise ProtocolError(f"{what} is empty: expected a tuple of names, e.g. {example}")
    if repeated := sorted({v for v in value if value.count(v) > 1}):
        raise ProtocolError(f"{what} names {repeated} more than once")
    return tuple(value)


def whole_number(what: str, value: Any) -> int:
    """``value`` as an int if it is a whole number >= 1 (``n_state``; numpy's integers too); a ProtocolError otherwise."""
    if not isinstance(value, Integral) or isinstance(value, bool) or value < 1:
        raise ProtocolError(f"{what} is {value!r}: expected a whole number >= 1")
    return int(value)


def check_built(observer: Any, n_runs: int, dof: int = 3) -> None:
    """What a built observer returns, checked before anything runs (a :class:`ProtocolError` naming the member):
    ``max_rate()`` a finite number >= 0, ``init()`` of shape (B, n_state), ``outputs(init())`` every declared signal as
    (B,) and no other, ``derivative`` (or ``step``) from ``init()`` at a zero pose and thrust (``dof`` columns each: 3,
    or 2 on the ROV world) an array of shape (B, n_state). Otherwise a mistake in the class would surface as a
    traceback deep in the engine, or as wrong numbers."""
    checked = observer if isinstance(observer, CheckedObserver) else CheckedObserver(observer, n_runs)
    checked.max_rate()
    x0 = checked.init()
    checked.outputs(x0)
    y, tau = np.zeros((n_runs, dof)), np.zeros((n_runs, dof))  # a measured pose and a thrust, at the initial estimate
    if checked.discrete:
        checked.step(x0.copy(), y, tau, 0)
    else:
        checked.derivative(x0.copy(), y, tau)


class CheckedObserver:
    """A built custom observer whose every answer is checked against the protocol, at validation
    (:func:`check_built`) and at every step of the runs: a class that later drops a signal, changes a shape or
    returns a list would otherwise leave a stale or broadcast estimate in the results (wrong numbers, no error) or
    fail deep in the engine. A wrong answer is a :class:`ProtocolError` naming the member."""

    def __init__(self, inner: Any, n_runs: int) -> None:
        self.inner, self.name = inner, type(inner).__name__
        self.signals = names(f"{self.name}.signals", inner.signals)
        self.n_state = whole_number(f"{self.name}.n_state", inner.n_state)
        self.discrete = bool(getattr(inner, "discrete", False))
        self.shape = (n_runs, self.n_state)

    def max_rate(self) -> float:
        rate = self.inner.max_rate()
        if not isinstance(rate, Real) or not math.isfinite(rate) or rate < 0:
            raise ProtocolError(f"{self.name}.max_rate() returned {rate!r}: expected a finite number >= 0 (rad/s)")
        return rate

    def init(self) -> np.ndarray:
        x0 = np.asarray(self.inner.init())
        if x0.shape != self.shape:
            raise ProtocolError(f"{self.name}.init() has shape {x0.shape}: expected (B, n_state) = {self.shape}")
        return x0

    def outputs(self, xhat: np.ndarray) -> dict[str, np.ndarray]:
        out = self.inner.outputs(xhat)
        if not isinstance(out, dict):
            raise ProtocolError(f"{self.name}.outputs() returned {type(out).__name__}: expected a dict of its signals")
        if missing := [s for s in self.signals if s not in out]:
            raise ProtocolError(f"{self.name}.outputs() lacks {missing}, declared in its signals")
        if undeclared := [s for s in out if s not in self.signals]:
            raise ProtocolError(f"{self.name}.outputs() returns {undeclared}, not declared in its signals {list(self.signals)}")
        for s in self.signals:
            if np.shape(out[s]) != self.shape[:1]:
                raise ProtocolError(f"{self.name}.outputs()['{s}'] has shape {np.shape(out[s])}: expected (B,) = "
                                    f"({self.shape[0]},)")
        return out

    def derivative(self, xhat: np.ndarray, y: np.ndarray, tau: np.ndarray) -> np.ndarray:
        return self._state("derivative", self.inner.derivative(xhat, y, tau))

    def step(self, xhat: np.ndarray, y: np.ndarray, tau: np.ndarray, k: int) -> np.ndarray:
        return self._state("step", self.inner.step(xhat, y, tau, k))

    def _state(self, member: str, value: Any) -> np.ndarray:
        if not isinstance(value, np.ndarray) or value.shape != self.shape:
            raise ProtocolError(f"{self.name}.{member}() returned {type(value).__name__} of shape {np.shape(value)}: "
                                f"expected an array (B, n_state) = {self.shape}")
        return value


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
