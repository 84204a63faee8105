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

M = TypeVar("M", bound=BaseModel)


def over(model: type[M], base: dict[str, Any], settings: dict[str, Any], name: str, what: str = "key") -> M:
    """``model`` validated from ``base`` with ``settings`` over it; ``name`` and ``what`` word the errors
    ("depth: unknown srise gain(s) ['x'] (...)", "yaw.delta1: Input should be ...")."""
    unknown = sorted(set(settings) - set(model.model_fields))
    if unknown:
        raise ValueError(f"{name}: unknown {what}(s) {unknown} (its {what}s: {', '.join(model.model_fields)})")
    try:
        return model.model_validate({**base, **settings})
    except ValidationError as exc:
        err = exc.errors()[0]
        raise ValueError(f"{name}.{'.'.join(map(str, err['loc']))}: {err['msg']}") from None
