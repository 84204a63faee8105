"""Registered kinds, as accepted by the ``kind:`` discriminators of the config files."""

from __future__ import annotations

import typing


def _kinds_of(union) -> dict[str, str]:
    """kind -> first docstring line; a class serving several kinds may describe each in ``KIND_DOCS``."""
    members = typing.get_args(typing.get_args(union)[0]) if typing.get_origin(union) is typing.Annotated else (union,)
    out = {}
    for m in members:
        doc = (m.__doc__ or "").strip().splitlines()[0]
        for kind in typing.get_args(m.model_fields["kind"].annotation):  # Literal["a"] or Literal["a", "b"]
            out[kind] = getattr(m, "KIND_DOCS", {}).get(kind, doc)
    return out


def _per_run(scenario: type) -> str:
    """' Per run (world:, world.<key> sweeps): a, b.' for a scenario kind whose runs may set world keys of their own
    (its defaults need no file: ``model_construct`` fills them without the required fields)."""
    keys = list(scenario.model_construct().per_run_defaults())
    return f" Per run (world:, world.<key> sweeps): {', '.join(keys)}." if keys else ""


def kinds() -> dict[str, dict[str, str]]:
    from marinebench.config import ObserverTuning
    from marinebench.dp_scenario import DpScenario, Event
    from marinebench.environment.signals import Signal
    from marinebench.experiments.runner import scenario_kinds_for
    from marinebench.models.cybership2 import CyberShip2Params
    from marinebench.models.rov import LeonardLikeParams
    from marinebench.models.supply import SupplyParams
    from marinebench.rov_scenario import RovScenario
    from marinebench.scenario import Scenario
    from marinebench.sensors.noise import Noise

    return {
        "scenarios": {kind: doc + _per_run(cls) for cls in (Scenario, DpScenario, RovScenario)
                      for kind, doc in _kinds_of(cls).items()},
        "vessels": {**_kinds_of(CyberShip2Params), **_kinds_of(SupplyParams), **_kinds_of(LeonardLikeParams)},
        "observers": {kind: f"{doc} [{', '.join(scenario_kinds_for(kind))}]" for kind, doc in _kinds_of(ObserverTuning).items()},
        "controllers": {"rise": "RISE (Fischer et al. 2014), rov_tracking scenarios",
                        "srise": "S+RISE (Tijjani eqs. 14-17); feedback: cdo makes it CDO-S+RISE",
                        "custom": "a controller class of your own (source: file.py:Class; command(e1, e1_dot, h) -> tau)"},
        "signals": _kinds_of(Signal),
        "noise": _kinds_of(Noise),
        "events": _kinds_of(Event),
        "metrics": {
            "std": "standard deviation of est - truth over the window (Bejarano Tables III/IV)",
            "rmse": "root mean square of est - truth over the window",
            "max_abs": "largest |est - truth| over the window (peaking)",
            "j_tot": "Torben eq. (50): integral of the bis-scaled state-error norm over a window",
            "int": "Tijjani INT: integral of tau^2 from the time the robot reaches the reference",
            "recovery": "time after each push until the tracking error is back within a band (Tijjani S3)",
        },
    }
