"""Partial settings over a validated model: a variant's controller gains over Table II, its CDO/EO settings
over the scenario's. Unknown or invalid keys become a ValueError that names them, so config validation
reports them as one line with the key path. ``STRICT`` is the pydantic configuration of every model read from a
file."""

from __future__ import annotations

from typing import Any, TypeVar

from pydantic import BaseModel, ConfigDict, ValidationError

#: Every file-level model: an unknown key is an error (a typo must not be silently ignored), and so is a
#: non-finite number (YAML's .inf / .nan would pass ``gt=0`` bounds and fail deep in a design or the engine).
STRICT = ConfigDict(extra="forbid", allow_inf_nan=False)
#: Names that flow into metrics.csv, tables and folder names (experiments, scenarios, variants, metrics, sweep
#: parameters and groups): no spaces, slashes or pipes.
NAME = r"^[A-Za-z0-9_.+-]+$"
#: Why a boolean turned up where a word or a number was meant, for the errors that say so.
YAML_BOOLEANS = "YAML reads an unquoted true, false, yes, no, on or off as a boolean"

M = TypeVar("M", bound=BaseModel)


def over(model: type[M], base: dict[str, Any], settings: dict[str, Any], name: str, what: str = "key") -> M:
    """``model`` validated from ``base`` with ``settings`` over it; ``name`` and ``what`` word the errors
    ("depth: unknown srise gain(s) ['x'] (...)", "yaw.delta1: Input should be ...")."""
    unknown = sorted(set(settings) - set(model.model_fields))
    if unknown:
        raise ValueError(f"{name}: unknown {what}(s) {unknown} (its {what}s: {', '.join(model.model_fields)})")
    try:
        read = model.model_validate({**base, **settings})
    except ValidationError as exc:
        err = exc.errors()[0]
        raise ValueError(f"{name}.{'.'.join(map(str, err['loc']))}: {err['msg']}") from None
    if found := lax_boolean(settings, read.model_dump()):
        raise ValueError(f"{'.'.join(map(str, (name, *found[0])))}: {found[1]}")
    return read


def lax_boolean(given: Any, read: Any, path: tuple[str | int, ...] = ()) -> tuple[tuple[str | int, ...], str] | None:
    """The first place where pydantic's lax mode took a boolean for a number or a number for a boolean, found by
    walking what a file gave (``given``) beside what the validated model holds (``read``, its ``model_dump()``):
    ``seeds: true`` would run 1 seed and ``eps: yes`` mean 1.0 (YAML reads an unquoted true, yes or on as a
    boolean), ``notch: 1`` would mean true. Returns the key's path below ``given`` and the error message, or None.
    Places whose shape a validator changed (a scalar spread into a tuple) are not compared."""
    if isinstance(given, dict) and isinstance(read, dict):
        pairs = [(k, given[k], read[k]) for k in given if k in read]
    elif isinstance(given, list) and isinstance(read, list | tuple) and len(given) == len(read):
        pairs = list(zip(range(len(given)), given, read, strict=True))
    elif isinstance(given, bool) and isinstance(read, int | float) and not isinstance(read, bool):
        number = "an integer" if isinstance(read, int) else "a number"
        return path, f"Input should be {number}, not a boolean ({YAML_BOOLEANS})"
    elif isinstance(read, bool) and isinstance(given, int | float) and not isinstance(given, bool):
        return path, "Input should be true or false, not a number"
    else:
        return None
    for key, g, r in pairs:
        if found := lax_boolean(g, r, (*path, key)):
            return found
    return None
