"""JSON Schema of the YAML files *as written*, for editors (``marinebench schema``).

The pydantic models describe a resolved document. A file as written differs in three ways, handled by
:mod:`marinebench.loading` before validation, so the schema allows them too:

- ``from: other.yaml`` at the top of an experiment or scenario file: the file holds only overrides, merged
  key by key over the other one, so every key becomes optional, at any depth;
- an experiment's ``scenario:`` (and each of ``scenarios:``) may be a scenario file's path, or
  ``{from: path, ...overrides}``, besides a whole world written inline;
- an experiment's ``name`` defaults to the file's stem.

Every mapping still refuses unknown keys, so an editor flags a typo as the loader would. Unions that
pydantic checks with a discriminator become ``anyOf`` (a partial document matches several of them).
"""

from __future__ import annotations

import copy
from typing import Any, Literal

from pydantic import TypeAdapter

PARTIAL = "__partial"  # suffix of the deep-partial copy of a definition


def _rewrite(node: Any, partial: bool) -> Any:
    """A copy of ``node`` with ``oneOf`` as ``anyOf``; with ``partial`` also without ``required`` and with
    every ``$ref`` pointing at the partial copy of its definition."""
    if isinstance(node, list):
        return [_rewrite(n, partial) for n in node]
    if not isinstance(node, dict):
        return node
    out = {}
    for key, value in node.items():
        if key == "discriminator":
            continue
        if key == "required" and partial:
            continue
        if key == "$ref" and partial:
            out[key] = value + PARTIAL
            continue
        out["anyOf" if key == "oneOf" else key] = _rewrite(value, partial)
    return out


def _with_from(schema: dict) -> dict:
    """An object schema that also takes a ``from:`` path, and requires it."""
    out = copy.deepcopy(schema)
    out["properties"] = {"from": {"type": "string", "description": "the file these keys override (a relative path)"},
                         **out.get("properties", {})}
    out["required"] = ["from"]
    return out


def _definitions(model_schema: dict, root_name: str) -> tuple[dict, dict]:
    """(root, defs): each definition as is (``oneOf`` -> ``anyOf``) and as a deep-partial copy."""
    defs = {}
    for name, d in model_schema.pop("$defs", {}).items():
        defs[name] = _rewrite(d, partial=False)
        defs[name + PARTIAL] = _rewrite(d, partial=True)
    root = _rewrite(model_schema, partial=False)
    defs[root_name + PARTIAL] = _rewrite(model_schema, partial=True)
    return root, defs


def _scenario_refs(kinds: list[str], partial: bool) -> dict:
    """What an experiment's ``scenario:`` may be: a path, ``{from: path, ...}``, a whole world inline, or (in a
    file that starts ``from:`` another experiment, ``partial``) overrides of that experiment's world."""
    return {"anyOf": [
        {"type": "string", "description": "a scenario file (a relative path)"},
        *({"$ref": f"#/$defs/{k}"} for k in kinds),
        *({"$ref": f"#/$defs/{k}{PARTIAL}_from"} for k in kinds),
        *(({"$ref": f"#/$defs/{k}{PARTIAL}"} for k in kinds) if partial else ()),
    ]}


def _scenario_defs() -> tuple[dict, list[str]]:
    from marinebench.config import AnyScenario

    union = TypeAdapter(AnyScenario).json_schema(ref_template="#/$defs/{model}")
    kinds = [ref["$ref"].rsplit("/", 1)[1] for ref in union["oneOf"]]
    _, defs = _definitions(union, "AnyScenario")
    for k in kinds:
        defs[k + PARTIAL + "_from"] = _with_from(defs[k + PARTIAL])
    return defs, kinds


def file_schema(kind: Literal["experiment", "scenario"] = "experiment") -> dict:
    """The JSON Schema (draft 2020-12) of an experiment or a scenario YAML file as written."""
    from marinebench.config import Experiment

    scen_defs, kinds = _scenario_defs()
    if kind == "scenario":
        return {"$schema": "https://json-schema.org/draft/2020-12/schema", "title": "marinebench scenario file",
                "$defs": scen_defs,
                "anyOf": [*({"$ref": f"#/$defs/{k}"} for k in kinds),
                          *({"$ref": f"#/$defs/{k}{PARTIAL}_from"} for k in kinds)]}
    root, defs = _definitions(Experiment.model_json_schema(ref_template="#/$defs/{model}"), "Experiment")
    defs.update(scen_defs)
    for doc, partial in ((root, False), (defs["Experiment" + PARTIAL], True)):
        refs, props = _scenario_refs(kinds, partial), doc["properties"]
        props["scenario"] = {"anyOf": [*refs["anyOf"], {"type": "null"}],
                             "description": props["scenario"].get("description", "")}
        props["scenarios"] = {"anyOf": [{"type": "object", "additionalProperties": refs}, {"type": "null"}],
                              "description": props["scenarios"].get("description", "")}
    root["required"] = [r for r in root.get("required", []) if r != "name"]  # default: the file's stem
    defs["Experiment"] = root
    defs["Experiment_from"] = _with_from(defs["Experiment" + PARTIAL])
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "title": "marinebench experiment file",
            "$defs": defs, "anyOf": [{"$ref": "#/$defs/Experiment"}, {"$ref": "#/$defs/Experiment_from"}]}
