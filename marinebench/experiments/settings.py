"""Where a sweep parameter lives in a variant: its ``key`` read as a path in the variant's settings.

A sweep parameter's ``key`` (``sweep.params.<name>.key`` in an experiment YAML) is an observer field (``k`` is
``observer.k``) or a dotted path under ``observer.``, ``controller.`` or ``world.`` (a per-run world key, e.g.
``world.gnss_sigma``). The sweep builds each point by writing the value at that path of the variant's settings
(:func:`put_setting`), and the grid figure reads the variant's own tuning back (:func:`setting_at`).
"""

from __future__ import annotations

from typing import Any

MISSING: Any = object()
"""What :func:`setting_at` returns for a path that is not a setting of the variant."""


def setting_path(key: str) -> list[str]:
    """A sweep key as a path in the variant: ``k`` is ``observer.k``; ``observer.…``/``controller.…``/``world.…``
    as given."""
    parts = key.split(".")
    return parts if parts[0] in ("observer", "controller", "world") else ["observer", *parts]


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
