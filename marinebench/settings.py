"""Partial settings over a validated model: a variant's controller gains over Table II, its CDO/EO settings
over the scenario's. Unknown or invalid keys become a ValueError that names them, so config validation
reports them as one line with the key path."""

from __future__ import annotations

from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

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
