"""Key paths of config errors: pydantic's error location read against the config's types, so that an error names
the dotted key a user writes in YAML, and an unknown key comes with the keys allowed where it was found.

pydantic's locations carry more than the keys: a discriminated union adds the member's tag
(``variants.0.observer.bejarano.delta``), a plain union the member's type (``k.list[float].0``). Both are
dropped here by walking the location through the type annotations (models, lists, dicts, unions) from the root
type, instead of matching a list of known tags, so a new kind needs no change here.
"""

from __future__ import annotations

import difflib
import re
import types
from typing import Annotated, Any, Literal, Union, get_args, get_origin

from pydantic import BaseModel, Tag
from pydantic.fields import FieldInfo


def _members(tp: Any, discriminator: str = "kind") -> list[tuple[Any, set[str]]]:
    """The alternatives of a (possibly annotated, optional or union) type, each with the tags that select it: a
    ``Tag`` around it, or the values of its ``Literal`` discriminator field (``kind``)."""
    tags: set[str] = set()
    while get_origin(tp) is Annotated:
        tp, *meta = get_args(tp)
        tags |= {m.tag for m in meta if isinstance(m, Tag)}
        discriminator = next((m.discriminator for m in meta if isinstance(m, FieldInfo) and isinstance(m.discriminator, str)),
                             discriminator)
    if get_origin(tp) in (Union, types.UnionType):
        return [(m, t | tags) for alt in get_args(tp) for m, t in _members(alt, discriminator)]
    if _is_model(tp) and discriminator in tp.model_fields:
        kind = tp.model_fields[discriminator].annotation
        if get_origin(kind) is Literal:
            tags |= {str(v) for v in get_args(kind)}
    return [(tp, tags)]


def _is_model(tp: Any) -> bool:
    return isinstance(tp, type) and issubclass(tp, BaseModel)


def _inner(tp: Any, index: int) -> Any:
    args = get_args(tp)
    return args[index] if len(args) > index else Any


def key_path(root: Any, loc: tuple, unknown: bool = False) -> tuple[str, list[str]]:
    """The dotted key of pydantic location ``loc`` under type ``root``, and, when ``unknown`` (an extra key), the
    keys allowed beside it."""
    parts: list[str] = []
    tp = root
    for i, p in enumerate(loc):
        members = _members(tp)
        models = [m for m, _ in members if _is_model(m)]
        if isinstance(p, int):
            seqs = [m for m, _ in members if get_origin(m) in (list, tuple)]
            tp = _inner(seqs[0], 0) if seqs else Any
            parts.append(str(p))
            continue
        tagged = [m for m, tags in members if p in tags]
        if tagged and len(members) > 1:  # a discriminated union's member, named by its tag: not a key in the YAML
            tp = tagged[0]
            continue
        holders = [m for m in models if p in m.model_fields]
        if holders:
            tp = holders[0].model_fields[p].annotation
            parts.append(p)
            continue
        dicts = [m for m, _ in members if get_origin(m) is dict]
        if dicts:
            tp = _inner(dicts[0], 1)
            parts.append(p)
            continue
        if unknown and i == len(loc) - 1:
            parts.append(p)
            return ".".join(parts), sorted({f for m in models for f in m.model_fields}) + nested_keys(models, p)
        if tp is not Any and len(members) > 1:  # a plain union's member named by its type, e.g. 'list[float]'
            tp = Any
            continue
        parts.append(str(p))
    return ".".join(parts), []


def nested_keys(models: list[Any], name: str, depth: int = 3) -> list[str]:
    """Dotted paths below ``models``' fields, at most ``depth`` keys long, that end in a field ``name``: where a
    key written at the wrong level belongs (``horizon`` at the top is ``scenario.horizon``). A list's item is
    written ``<i>``, a mapping's value ``<name>``; shortest first."""
    found: set[str] = set()
    for model in models:
        for field, info in model.model_fields.items():
            for inner, step in _children(info.annotation):
                if name in inner.model_fields:
                    found.add(f"{field}{step}.{name}")
                if depth > 2:
                    found |= {f"{field}{step}.{sub}" for sub in nested_keys([inner], name, depth - 1)}
    return sorted(found, key=lambda k: (k.count("."), k))


def _children(tp: Any) -> list[tuple[type[BaseModel], str]]:
    """The model types a field of type ``tp`` holds, each with the step to it: '' (the field itself), '.<i>' (a
    list's items) or '.<name>' (a mapping's values)."""
    out = []
    for member, _ in _members(tp):
        if _is_model(member):
            out.append((member, ""))
        elif get_origin(member) in (list, tuple, dict):
            step = ".<name>" if get_origin(member) is dict else ".<i>"
            out += [(m, step) for m, _ in _members(_inner(member, 1 if step == ".<name>" else 0)) if _is_model(m)]
    return out


def near_misses(key: str, allowed: list[str]) -> list[str]:
    """Up to three of ``allowed`` closest to the last part of ``key`` (a typo's likely intent, case aside: ``xuu``
    finds ``X_uu``), closest first."""
    name = key.rsplit(".", 1)[-1].lower()
    scores = {a: difflib.SequenceMatcher(None, name, a.lower()).ratio() for a in allowed}
    return sorted((a for a in allowed if scores[a] >= 0.6), key=lambda a: (-scores[a], a))[:3]  # ties by name


def did_you_mean(names: list[str]) -> str:
    """' (did you mean a, b or c?)', or '' for no names."""
    if not names:
        return ""
    return f" (did you mean {' or '.join(names) if len(names) < 3 else ', '.join(names[:-1]) + ' or ' + names[-1]}?)"


def unknown_key_hint(key: str, allowed: list[str], most: int = 12) -> str:
    """' (did you mean delta_p1 or delta_psi1?)' for a near miss among the keys allowed beside ``key``; else the
    same key one or two levels further down (dotted entries of ``allowed``, :func:`nested_keys`); else the
    allowed keys."""
    deeper = [a for a in allowed if "." in a]
    allowed = [a for a in allowed if "." not in a]
    near = near_misses(key, allowed)
    if near:
        return did_you_mean(near)
    if deeper:
        parent = key.rpartition(".")[0]
        return did_you_mean([f"{parent}.{d}" if parent else d for d in deeper[:3]])
    if allowed:
        shown = ", ".join(allowed[:most]) + (", …" if len(allowed) > most else "")
        return f" (allowed here: {shown})"
    return ""


#: A cross-field check's message naming the key(s) it is about, relative to where the check sits:
#: ``variants.1.scenarios: ...``, or a pair checked together, ``horizon|dt: ...`` (the first is the one to name
#: unless the user just changed the other).
_KEYED = re.compile(r"^([A-Za-z0-9_.|-]+): (.+)$", re.DOTALL)


def keyed_message(msg: str) -> tuple[list[str], str]:
    """The keys a check's message names before its colon (:data:`_KEYED`) and the rest of it; ``([], msg)`` for a
    message that names none."""
    where = _KEYED.match(msg)
    return (where[1].split("|"), where[2]) if where else ([], msg)
