"""Registered kinds, as accepted by the ``kind:`` discriminators of the config files."""

from __future__ import annotations

import re
import types
import typing


def _doc(model: type, kind: str) -> str:
    """A kind's description: its model's first docstring line; a class serving several kinds may describe each in
    ``KIND_DOCS``."""
    return getattr(model, "KIND_DOCS", {}).get(kind, (model.__doc__ or "").strip().splitlines()[0])


def _per_run(scenario: type) -> str:
    """' Per run (world:, world.<key> sweeps): a, b; ...' for a scenario kind whose runs may set world keys of their
    own (its defaults need no file: ``model_construct`` fills them without the required fields)."""
    keys = list(scenario.model_construct().per_run_defaults())
    return (f" Per run (world:, world.<key> sweeps): {', '.join(keys)}; any other setting by its dotted path "
            "(sensors.ts, a number a sweep may vary; a switch, text, list or section too), in a world of its own.") if keys else ""


#: Descriptions of the kinds whose models do not tell them apart (one ControllerSpec, one ErrorMetric for three).
CONTROLLER_DOCS = {"rise": "RISE (Fischer et al. 2014), rov_tracking scenarios",
                   "srise": "S+RISE (Tijjani eqs. 14-17); feedback: cdo makes it CDO-S+RISE",
                   "custom": "a controller class of your own (source: file.py:Class or module:Class; command(e1, e1_dot, h) -> tau)"}
METRIC_DOCS = {
    "std": "standard deviation of est - truth over the window (Bejarano Tables III/IV)",
    "rmse": "root mean square of est - truth over the window",
    "max_abs": "largest |est - truth| over the window (peaking)",
    "j_tot": "Torben eq. (50): integral of the bis-scaled state-error norm over a window",
    "int": "Tijjani INT: integral of tau^2 from the time the robot reaches the reference",
    "recovery": "time after each push until the tracking error is back within a band (Tijjani S3)",
}


def kinds() -> dict[str, dict[str, str]]:
    """group -> kind -> one line describing it (``marinebench list``), from :func:`kind_models`: an observer with
    the scenario kinds it runs on, a scenario with the world keys its runs may set."""
    from marinebench.experiments.runner import scenario_kinds_for

    models = kind_models()
    docs = {group: {kind: _doc(model, kind) for kind, model in entries.items()} for group, entries in models.items()}
    docs["scenarios"] = {kind: doc + _per_run(models["scenarios"][kind]) for kind, doc in docs["scenarios"].items()}
    docs["observers"] = {kind: f"{doc} [{', '.join(scenario_kinds_for(kind))}]" for kind, doc in docs["observers"].items()}
    return docs | {"controllers": CONTROLLER_DOCS, "metrics": METRIC_DOCS}


def _models_of(union) -> dict[str, type]:
    """kind -> the model class that reads it (the members of a ``kind:`` union, or one model)."""
    members = typing.get_args(typing.get_args(union)[0]) if typing.get_origin(union) is typing.Annotated else (union,)
    return {kind: m for m in members for kind in typing.get_args(m.model_fields["kind"].annotation)}


def kind_models() -> dict[str, dict[str, type]]:
    """group -> kind -> the pydantic model of its settings, for the groups of :func:`kinds` that have models."""
    from marinebench.config import ErrorMetric, IntMetric, JTotMetric, ObserverTuning, RecoveryMetric
    from marinebench.controllers.spec import ControllerSpec
    from marinebench.dp_scenario import DpScenario, Event
    from marinebench.environment.signals import Signal
    from marinebench.models.cybership2 import CyberShip2Params
    from marinebench.models.rov import LeonardLikeParams
    from marinebench.models.supply import SupplyParams
    from marinebench.rov_scenario import RovScenario
    from marinebench.scenario import Scenario
    from marinebench.sensors.noise import Noise

    return {
        "scenarios": {k: m for cls in (Scenario, DpScenario, RovScenario) for k, m in _models_of(cls).items()},
        "vessels": {k: m for cls in (CyberShip2Params, SupplyParams, LeonardLikeParams) for k, m in _models_of(cls).items()},
        "observers": _models_of(ObserverTuning),
        "controllers": _models_of(ControllerSpec),
        "signals": _models_of(Signal),
        "noise": _models_of(Noise),
        "events": _models_of(Event),
        "metrics": {k: m for cls in (ErrorMetric, JTotMetric, IntMetric, RecoveryMetric) for k, m in _models_of(cls).items()},
    }


def type_name(tp) -> str:
    """A field's type as a user writes it: ``float | None``, ``tuple[float, float]``, ``'linear' | 'log'``; a nested
    mapping as its kinds (``{kind: jonswap}``) or, without a kind, ``mapping``."""
    if typing.get_origin(tp) is typing.Annotated:
        return type_name(typing.get_args(tp)[0])
    if typing.get_origin(tp) is typing.Literal:
        return " | ".join(repr(a) for a in typing.get_args(tp))
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        return " | ".join(type_name(a) for a in typing.get_args(tp))
    args = typing.get_args(tp)
    if args:
        return f"{typing.get_origin(tp).__name__}[{', '.join(type_name(a) for a in args)}]"
    if tp is type(None):
        return "None"
    if isinstance(tp, type) and hasattr(tp, "model_fields"):  # a nested mapping: its kind, or its own keys
        kinds = typing.get_args(tp.model_fields["kind"].annotation) if "kind" in tp.model_fields else ()
        return " | ".join(f"{{kind: {k}}}" for k in kinds) if kinds else "mapping"
    return tp.__name__ if isinstance(tp, type) else re.sub(r"typing\.", "", str(tp))


def _default(value) -> str:
    """A default as a user reads it: a nested mapping's kind (or 'its defaults'), anything else as repr."""
    if hasattr(type(value), "model_fields"):
        return f"{{kind: {value.kind}}}" if "kind" in type(value).model_fields else "its defaults"
    return repr(value)


def fields_of(model: type, prefix: str = "") -> list[tuple[str, str, str, str]]:
    """(name, type, default, description) of each setting of ``model`` but ``kind``, in declaration order, a nested
    mapping's settings under their dotted names (``sensors.gnss_sigma``; one with a ``kind`` of its own is listed by
    that kind); the default is ``required`` for a field without one."""
    from pydantic_core import PydanticUndefined

    rows = []
    for name, info in model.model_fields.items():
        if name == "kind":
            continue
        tp = info.annotation
        if isinstance(tp, type) and hasattr(tp, "model_fields") and "kind" not in tp.model_fields:
            rows += fields_of(tp, f"{prefix}{name}.")
            continue
        if info.default_factory is not None:
            default = _default(info.default_factory())
        elif info.default is PydanticUndefined:
            default = "required"
        else:
            default = _default(info.default)
        rows.append((prefix + name, type_name(tp), default, " ".join((info.description or "").split())))
    return rows
