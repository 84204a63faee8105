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
members or a world it does not apply to is a one-line config error. Runs record the source's SHA-256 in the
manifest. With ``sweep --dask``, the file must be at the same path on the workers.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import sys
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

SCENARIO_KINDS = ("open_loop_asv", "dp_supply")  # worlds whose observers take the measured pose and the thrust
MEMBERS = ("signals", "scenario_kinds", "n_state", "init", "outputs", "max_rate")
_LOADED: dict[str, tuple[float, type]] = {}


def _split(source: str) -> tuple[str, str]:
    where, _, name = source.rpartition(":")
    if not where or not name.isidentifier():
        raise ValueError(f"source '{source}': expected file.py:ClassName or package.module:ClassName")
    return where, name


def observer_class(source: str) -> type:
    """The class ``source`` names, imported (a ``.py`` file is re-read when it changes) and checked against
    the protocol; ValueError with a one-line reason otherwise."""
    where, name = _split(source)
    if where.endswith(".py"):
        path = Path(where)
        if not path.is_file():
            raise ValueError(f"source file not found: {where}")
        mtime = path.stat().st_mtime
        if source in _LOADED and _LOADED[source][0] == mtime:
            return _LOADED[source][1]
        module_name = "marinebench_custom_" + hashlib.sha1(str(path.resolve()).encode()).hexdigest()[:12]
        spec = importlib.util.spec_from_file_location(module_name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[module_name] = module  # dataclasses and pickling look the module up by name
        try:
            spec.loader.exec_module(module)
        except Exception as exc:  # noqa: BLE001 - the user's module: any error is a config error naming it
            del sys.modules[module_name]
            raise ValueError(f"{where}: cannot import ({type(exc).__name__}: {exc})") from None
    else:
        mtime = 0.0
        try:
            module = importlib.import_module(where)
        except Exception as exc:  # noqa: BLE001 - as above
            raise ValueError(f"cannot import module '{where}' ({type(exc).__name__}: {exc})") from None
    cls = getattr(module, name, None)
    if not isinstance(cls, type):
        raise ValueError(f"{where} has no class '{name}'")  # noqa: TRY004 - pydantic reports ValueErrors
    missing = [m for m in MEMBERS if not hasattr(cls, m)]
    if not getattr(cls, "discrete", False) and not hasattr(cls, "derivative"):
        missing.append("derivative (or discrete = True and step)")
    if getattr(cls, "discrete", False) and not hasattr(cls, "step"):
        missing.append("step")
    if missing:
        raise ValueError(f"{name} ({where}) lacks {', '.join(missing)}: see marinebench/observers/custom.py")
    unknown = set(cls.scenario_kinds) - set(SCENARIO_KINDS)
    if unknown:
        raise ValueError(f"{name}.scenario_kinds: {sorted(unknown)} (custom observers apply to {', '.join(SCENARIO_KINDS)})")
    _LOADED[source] = (mtime, cls)
    return cls


def source_digest(source: str) -> str | None:
    """SHA-256 of a ``.py`` source file (None for a module: its package version is what identifies it)."""
    where, _ = _split(source)
    return hashlib.sha256(Path(where).read_bytes()).hexdigest() if where.endswith(".py") else None


def resolve_source(source: Any, base: Path) -> Any:
    """A relative ``file.py:Class`` made absolute against ``base`` (the experiment file's folder)."""
    if not isinstance(source, str) or ":" not in source:
        return source
    where, _, name = source.rpartition(":")
    if not where.endswith(".py") or Path(where).is_absolute():
        return source
    return f"{(base / where).resolve()}:{name}"


class CustomTuning(BaseModel):
    """An observer class of your own (source: file.py:Class or module:Class; params: one mapping per run)."""

    model_config = ConfigDict(extra="forbid")
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
