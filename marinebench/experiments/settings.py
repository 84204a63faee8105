"""Where a sweep parameter lives in a variant: its ``key`` read as a path in the variant's settings.

A sweep parameter's ``key`` (``sweep.params.<name>.key`` in an experiment YAML) is an observer field (``k`` is
``observer.k``) or a dotted path under ``observer.``, ``controller.`` or ``world.`` (a per-run world key, e.g.
``world.gnss_sigma``, or a numeric setting of the world by its dotted path, ``world.waves.tp``). The sweep builds each point by writing the value at that path of the variant's settings
(:func:`put_setting`), and the figures and the grid's claims read the variant's own value back (:func:`tuning`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from marinebench.config import Experiment

MISSING: Any = object()
"""What :func:`setting_at` returns for a path that is not a setting of the variant."""


def setting_path(key: str) -> list[str]:
    """A sweep key as a path in the variant: ``k`` is ``observer.k``; ``observer.…``/``controller.…`` as given;
    ``world.<key>`` one key of the variant's flat ``world:`` mapping, dots and all (``world.waves.tp``)."""
    parts = key.split(".")
    if parts[0] == "world":
        return ["world", key.split(".", 1)[1]]
    return parts if parts[0] in ("observer", "controller") else ["observer", *parts]


def setting_at(doc: dict, path: list[str]) -> Any:
    """The value at ``path``, or :data:`MISSING`; a key of a settings mapping (a controller's ``yaw`` gains, the
    CDO's overrides) that is not set yet counts as present (None) when the model declares that mapping."""
    for i, part in enumerate(path):
        if not isinstance(doc, dict):
            return MISSING
        if part not in doc:
            return None if i == len(path) - 1 and i >= 2 else MISSING
        doc = doc[part]
    return doc


def put_setting(doc: dict, path: list[str], value: Any) -> None:
    """Write ``value`` at ``path``, creating the mappings on the way."""
    for part in path[:-1]:
        doc = doc.setdefault(part, {})
    doc[path[-1]] = value


def tuning(exp: Experiment, param: str, variant: str | None = None) -> float | None:
    """The swept variant's (or ``variant``'s) own value of a sweep parameter (of a ``world.<key>``, or of the ROV
    observers' settings: the variant's, else its scenario's), if it is a number inside the range.

    A parameter with ``fixed`` settings changes what its value means, so its own value is known in one case only:
    a ``<X>_scale`` key whose ``fixed`` sets ``<X>`` alone (Torben's c_ε: ``eps_scale`` with ``eps = [0.1, 0.1,
    0.01]``) has the value that, times the fixed ``X``, gives the variant's own ``X`` times its own ``X_scale``,
    when one number does so for every element (Table I's ε = [0.5, 0.5, 0.05] is c_ε = 5); otherwise None."""
    ps = exp.sweep.params[param]
    base = next(v for v in exp.variants if v.name == (variant or exp.sweep.variant))
    scenario = (exp.part(exp.sweep_scenario()) if exp.scenarios is not None else exp).scenario
    path = setting_path(ps.key)
    if not ps.fixed:
        value = _own_setting(base, scenario, path)
    else:
        value = _own_scale(ps.fixed, path, lambda p: _own_setting(base, scenario, p))
    return float(value) if isinstance(value, int | float) and ps.range[0] <= value <= ps.range[1] else None


def _own_setting(base, scenario, path: list[str]) -> Any:
    """The variant's own value at a setting ``path`` (a per-run world key's scenario default, the scenario's CDO/EO
    setting, Table II's controller gain when the variant leaves it unset)."""
    if path[0] == "world":  # a per-run key's default, or the world's own setting at that path
        return base.world.get(path[1], scenario.per_run_defaults().get(path[1], scenario.setting(path[1])))
    value = setting_at(base.model_dump(include={"observer", "controller"}, exclude_none=True), path)
    if value is None and path[0] == "observer" and len(path) == 3 and path[1] in ("cdo", "eo"):
        value = getattr(base.observer.resolve(scenario)[path[1] == "eo"], path[2], None)  # the scenario's CDO/EO
    if value is None and path[0] == "controller" and len(path) == 3 and path[1] in ("depth", "yaw"):
        value = getattr(base.controller.gains()[("depth", "yaw").index(path[1])], path[2], None)  # Table II's default
    return value


def _own_scale(fixed: dict[str, Any], path: list[str], own) -> float | None:
    """The scale ``c`` with ``c * fixed[X] == own(X) * own(X_scale)`` element by element, for a key ``path`` that
    names ``X_scale`` and a ``fixed`` that sets ``X`` alone; None otherwise (another key, unequal ratios, no number)."""
    import numpy as np

    if len(fixed) != 1 or not path[-1].endswith("_scale"):
        return None
    ((key, given),) = fixed.items()
    scaled = [*path[:-1], path[-1].removesuffix("_scale")]
    if setting_path(key) != scaled:
        return None
    try:
        ratios = np.ravel(np.asarray(own(scaled), dtype=float) * float(own(path)) / np.asarray(given, dtype=float))
    except (TypeError, ValueError, ZeroDivisionError):  # a setting that is not a number (or array) of the same shape
        return None
    finite = ratios.size > 0 and bool(np.all(np.isfinite(ratios)))
    return float(ratios[0]) if finite and np.allclose(ratios, ratios[0], rtol=1e-9, atol=0.0) else None
