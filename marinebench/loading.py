"""Reading experiment and scenario YAML files into validated models, with file:key error mapping.

An experiment YAML names a scenario file (``scenario: ../scenarios/x.yaml``) or embeds a scenario
with overrides (``scenario: {from: ../scenarios/x.yaml, horizon: 10}``). ``--set dotted.key=value``
edits the resolved document before validation; list items are addressed by index
(``variants.0.observer.eps``) or by name (``variants[liu_eps0.1].observer.eps``), ``*`` stands for every key or
item (``scenarios.*.horizon``); a whole world set to a scenario file (``scenario=../scenarios/y.yaml``) is read as the
config's own reference, relative to the working directory (:func:`_set_world`). :func:`load_checked` then runs :func:`marinebench.preflight.preflight`, which
solves every observer design and checks the step before anything runs.
"""

from __future__ import annotations

import copy
import re
from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from marinebench.config import AnyScenario, Experiment
from marinebench.errors import ConfigError
from marinebench.keypaths import key_path, keyed_message, unknown_key_hint
from marinebench.plugins import resolve_source
from marinebench.preflight import preflight
from marinebench.settings import YAML_BOOLEANS, lax_boolean


class YamlLoader(yaml.SafeLoader):
    """``yaml.safe_load`` with YAML 1.2's floats: PyYAML follows YAML 1.1, where ``1e8`` and ``5.0e6`` (no dot
    or no exponent sign) are strings, while editors and the JSON Schema of ``marinebench schema`` read numbers.
    A key written twice in one mapping is an error (YAML 1.2 requires unique keys; PyYAML keeps the last one
    silently, so a second ``observer:`` would replace the first without a word)."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value if isinstance(node, yaml.MappingNode) else ():
            if isinstance(key_node, yaml.ScalarNode) and key_node.tag != "tag:yaml.org,2002:merge":
                key = self.construct_object(key_node)
                if key in seen:
                    raise yaml.constructor.ConstructorError(None, None, f"duplicate key {key!r}", key_node.start_mark)
                seen.add(key)
        return super().construct_mapping(node, deep)


YamlLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float", re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9][0-9_]*)[eE][-+]?[0-9]+$"),
    list("-+0123456789."))


def read_yaml(path: Path) -> dict[str, Any]:
    """A YAML file's top-level mapping (:class:`YamlLoader`); ConfigError naming the file otherwise."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(path, "", "file not found") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(path, "", f"not UTF-8 text (byte {exc.start}): a YAML file is UTF-8") from None
    except OSError as exc:
        raise ConfigError(path, "", f"cannot read ({exc.strerror})") from None
    try:
        doc = yaml.load(text, Loader=YamlLoader)  # YamlLoader is a SafeLoader
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ConfigError(path, "", f"invalid YAML: {where}{problem}") from None
    if not isinstance(doc, dict):
        raise ConfigError(path, "", "expected a mapping at the top level")
    return doc


def _deep_merge(base: dict, over: dict) -> dict:
    out = copy.deepcopy(base)
    for k, v in over.items():
        out[k] = _deep_merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else copy.deepcopy(v)
    return out


def _leaf_paths(d: dict, prefix: str) -> list[str]:
    out = []
    for k, v in d.items():
        out += _leaf_paths(v, f"{prefix}.{k}") if isinstance(v, dict) and v else [f"{prefix}.{k}"]
    return out


_TOKEN = re.compile(r"([^.\[\]]+)|\[([^\]]+)\]")


def _split_path(key: str) -> list[str | tuple[str]]:
    parts: list[str | tuple[str]] = []
    pos = 0
    for m in _TOKEN.finditer(key):
        sep = key[pos:m.start()]  # the first part starts the key; a name after it follows a dot, a [name] may
        allowed = ("",) if not parts else (".",) if m.group(1) is not None else ("", ".")
        if sep not in allowed:
            raise ValueError(f"malformed key '{key}'")
        parts.append(m.group(1) if m.group(1) is not None else (m.group(2),))
        pos = m.end()
    if not parts or pos != len(key):
        raise ValueError(f"malformed key '{key}'")
    return parts


def apply_set(doc: dict, assignment: str) -> list[str]:
    """Apply one ``dotted.key=value`` override in place (value parsed as YAML); returns the keys it set as dotted
    paths of the document, a ``[name]`` selector replaced by the item's index (``variants.0.observer.eps``). A ``*``
    part stands for every key of a mapping or item of a list there (``scenarios.*.horizon=20``: every world)."""
    if "=" not in assignment:
        raise ConfigError("--set", assignment, "expected dotted.key=value")
    key, raw = assignment.split("=", 1)
    try:
        value = yaml.load(raw, Loader=YamlLoader) if raw != "" else ""  # YamlLoader is a SafeLoader
        parts = _split_path(key.strip())
    except (yaml.YAMLError, ValueError) as exc:
        raise ConfigError("--set", key, str(exc).splitlines()[0]) from None
    return [_assign(doc, path, key, copy.deepcopy(value)) for path in _expanded(doc, parts, key)]


def _expanded(doc: dict, parts: list, key: str) -> list[list]:
    """The paths ``parts`` stands for: a ``*`` part replaced by each key of the mapping (index of the list) there."""
    if "*" not in parts:
        return [parts]
    i = parts.index("*")
    node: Any = doc
    where: list[str] = []
    for part in parts[:i]:
        idx = _child(node, part, key)
        where.append(str(idx))
        if isinstance(node, dict) and idx not in node:
            if len(where) <= 2:
                _check_world_key(doc, key, where)  # scenarios.* on an experiment with one world: say where
            raise ConfigError("--set", key, f"'*' has nothing to stand for: there is no '{idx}'")
        node = node[idx]
    if isinstance(node, dict):
        members = list(node)
    elif isinstance(node, list):
        members = [str(j) for j in range(len(node))]
    else:
        members = []
    if not members:
        raise ConfigError("--set", key, f"'*' has nothing to stand for: an empty or scalar value ({node!r})")
    return [path for m in members for path in _expanded(doc, [*parts[:i], m, *parts[i + 1:]], key)]


def _assign(doc: dict, parts: list, key: str, value: Any) -> str:
    """Set the value at one path of the document (creating missing mappings); the path as dotted indices."""
    node: Any = doc
    where: list[str] = []
    i = 0
    while True:
        part, i = _dotted_key(node, parts, i)
        idx = _child(node, part, key)
        where.append(str(idx))
        if i == len(parts):
            node[idx] = value
            return ".".join(where)
        if isinstance(node, dict) and idx not in node:
            if len(where) <= 2:
                _check_world_key(doc, key, where)
            node[idx] = {}
        node = node[idx]


def _dotted_key(node: Any, parts: list, i: int) -> tuple[Any, int]:
    """The part of a ``--set`` key at ``i``, or, where the mapping there has it as one key, the longest run of names
    from ``i`` joined by dots (a world setting written ``waves.tp: 8``, set by ``...world.waves.tp=6``); and the
    index of the part after it."""
    if isinstance(node, dict):
        for j in range(len(parts), i + 1, -1):
            run = parts[i:j]
            if all(isinstance(p, str) for p in run) and ".".join(run) in node:
                return ".".join(run), j
    return parts[i], i + 1


def _child(node: Any, part: str | tuple[str], key: str) -> int | str:
    """The index in ``node`` that one part of a ``--set`` key names: a ``[name]`` selector (a tuple) the position of
    the list's item of that name, a number a list's position, any other part a mapping's key."""
    if isinstance(part, tuple):  # [name] selector in a list of named items
        if not isinstance(node, list):
            raise ConfigError("--set", key, f"'[{part[0]}]' selects from a list, found {type(node).__name__}")
        match = [j for j, item in enumerate(node) if isinstance(item, dict) and item.get("name") == part[0]]
        if not match:
            names = _item_names(node)
            raise ConfigError("--set", key, f"no item named '{part[0]}'" + (f" (have: {', '.join(names)})" if names else ""))
        return match[0]
    if isinstance(node, list):
        if not part.isdigit() or int(part) >= len(node):
            raise ConfigError("--set", key, f"'{part}' is not a valid index (0..{len(node) - 1}){_by_name(node, part, key)}")
        return int(part)
    if isinstance(node, dict):
        return part
    raise ConfigError("--set", key, f"cannot descend into a {type(node).__name__}")


def _item_names(node: list) -> list[str]:
    """The names of a list's named items (variants, metrics), in order."""
    return [item["name"] for item in node if isinstance(item, dict) and isinstance(item.get("name"), str)]


def _by_name(node: list, part: str, key: str) -> str:
    """The hint for a list item named as a mapping's key (``variants.rise``, or ``variants.proposed_d1.2``, whose
    name has a dot): the key with the ``[name]`` selector; for another word, the names there are; else ''."""
    names = _item_names(node)
    if part.isdigit() or not names:
        return ""
    for name in sorted(names, key=len, reverse=True):  # the longest name the key spells out from this part on
        if name == part or name.startswith(part + "."):
            fixed, found = re.subn(rf"\.{re.escape(name)}(?=\.|$)", f"[{name}]", key.strip(), count=1)
            if found:
                return f" (did you mean {fixed}? an item is selected by its name in brackets)"
    return f" (its items by name: {', '.join(f'[{name}]' for name in names)})"


def _check_world_key(doc: dict, key: str, where: list[str]) -> None:
    """A ``--set`` that would create a partial world: ``scenario.<key>`` on an experiment whose worlds are under
    ``scenarios:``, the reverse, or ``scenarios.<new name>.<key>``; say where the key goes instead."""
    rest = key.strip().split(".", len(where))[-1]
    if where == ["scenario"] and isinstance(doc.get("scenarios"), dict):
        raise ConfigError("--set", key, f"this experiment's worlds are under 'scenarios' ({', '.join(doc['scenarios'])}): "
                          f"set scenarios.<name>.{rest}")
    if where[0] == "scenarios" and "scenario" in doc:
        raise ConfigError("--set", key, f"this experiment has one world, under 'scenario': set scenario.{rest.split('.', 1)[1] if '.' in rest else '<key>'}")
    if len(where) == 2 and where[0] == "scenarios":
        raise ConfigError("--set", key, f"no scenario '{where[1]}' (have: {', '.join(doc['scenarios'])})")


def shown_path(path: Path) -> Path:
    """A resolved file as a user names it, for error messages and manifests: relative to the working directory
    when it lies below it (``scenarios/cs2_noisy.yaml`` beside ``configs/x.yaml`` on the command line),
    otherwise absolute. Never machine-specific in results written from the repository's root."""
    try:
        return path.relative_to(Path.cwd().resolve())
    except ValueError:
        return path


def _from_path(ref: Any, path: Path, seen: tuple[Path, ...], what: str) -> Path:
    """The file a ``from:`` in ``path`` names (relative to it), checked: a path, not circular, existing."""
    if not isinstance(ref, str):
        raise ConfigError(path, "from", f"expected a path to the {what} file")
    bpath = (path.parent / ref).resolve()
    if bpath in seen or bpath == path.resolve():
        raise ConfigError(path, "from", f"circular {what} reference to {ref}")
    _check_exists(bpath, ref, path, "from", what)
    return shown_path(bpath)  # errors in it then name it as the user would


def _check_exists(resolved: Path, ref: str, path: Path, key: str, what: str, against: str = "the file's folder") -> None:
    """ConfigError at ``key`` of ``path`` unless the ``what`` file a reference ``ref`` names is a file (a relative
    ``ref`` was looked for ``against`` a folder: the file's that holds it, or the working directory)."""
    if resolved.is_dir():
        raise ConfigError(path, key, f"{ref} is a folder, not a file")
    if not resolved.exists():
        raise ConfigError(path, key, f"{what} file not found: {ref}{_looked_in(ref, resolved, against)}")


def _looked_in(ref: str, resolved: Path, against: str = "the file's folder") -> str:
    """Where a relative reference was looked for: against the folder of the file that holds it, which is not the
    working directory a user may read it from (or, for a ``--set``, against the working directory)."""
    return "" if Path(ref).is_absolute() else f" (relative to {against}: looked for {resolved})"


def read_scenario(path: Path, _seen: tuple[Path, ...] = ()) -> dict[str, Any]:
    """A scenario file; ``from: other.yaml`` in it starts from that scenario (relative path) and overrides keys."""
    doc = read_yaml(path)
    if "from" not in doc:
        return doc
    bpath = _from_path(doc.pop("from"), path, _seen, "scenario")
    return _deep_merge(read_scenario(bpath, (*_seen, path.resolve())), doc)


def _is_reference(scen: Any) -> bool:
    """A world given as a scenario file (``file`` or ``{from: file, overrides...}``), not as its keys."""
    return isinstance(scen, str) or (isinstance(scen, dict) and "from" in scen)


def _inline_scenario(scen: Any, path: Path, key: str, origins: dict[str, Path], folder: Path | None = None) -> Any:
    """Replace a scenario reference (``file`` or ``{from: file, overrides...}``) by the merged document; a relative
    file is looked for in ``folder`` (default: that of ``path``, the file that names it)."""
    if not _is_reference(scen):
        return scen
    ref = scen if isinstance(scen, str) else scen["from"]
    overrides = {} if isinstance(scen, str) else {k: v for k, v in scen.items() if k != "from"}
    if not isinstance(ref, str):
        raise ConfigError(path, f"{key}.from", "expected a file path")
    spath = ((path.parent if folder is None else folder) / ref).resolve()
    _check_exists(spath, ref, path, key, "scenario", "the file's folder" if folder is None else "the working directory")
    origins[key] = shown_path(spath)
    for dotted in _leaf_paths(overrides, key):
        origins["override " + dotted] = path
    world = read_scenario(spath)
    if "variants" in world:
        raise ConfigError(path, key, f"{ref} is an experiment file (it has variants), not a scenario: name the scenario "
                          "file it runs in (its 'scenario:')")
    return _deep_merge(world, overrides)


def _base_experiment(doc: dict, path: Path, seen: tuple[Path, ...]) -> tuple[dict, dict[str, Path]]:
    """The resolved document of the experiment named by ``from:`` (relative path), without its name."""
    bpath = _from_path(doc.pop("from"), path, seen, "experiment")
    base, origins = resolve_document(bpath, _seen=(*seen, path.resolve()))
    base.pop("name", None)  # the derived file is its own experiment
    origins = {**{k: v for k, v in origins.items() if k}, "from": bpath}
    for dotted in _own_leaves(base):  # a bad key there is named in that file (unless it came from further back)
        origins.setdefault("override " + dotted, bpath)
    return base, origins


def _own_leaves(doc: dict) -> list[str]:
    """The dotted leaves of an experiment document's keys outside its world (whose origins are tracked apart)."""
    return [leaf for k, v in doc.items() if k not in ("name", "from", "scenario", "scenarios")
            for leaf in (_leaf_paths(v, k) if isinstance(v, dict) and v else [k])]


def _resolve_sources(doc: dict, folder: Path) -> None:
    """A custom observer's or controller's ``source: file.py:Class`` is relative to the file that names it."""
    variants = doc.get("variants")
    for v in variants if isinstance(variants, list) else []:
        for part in ("observer", "controller"):
            if isinstance(v, dict) and isinstance(v.get(part), dict) and "source" in v[part]:
                v[part]["source"] = resolve_source(v[part]["source"], folder)


def resolve_document(path: Path, sets: list[str] = (), profile: str | None = None,
                     _seen: tuple[Path, ...] = ()) -> tuple[dict, dict[str, Path]]:
    """Read an experiment file, inline its scenario, apply a profile and ``--set``; returns (document, origins).

    ``from: other.yaml`` starts from that experiment (its scenario resolved relative to it) and merges this
    file's keys over it (mappings key by key, lists replaced), e.g. the same experiment on another plant."""
    doc = read_yaml(path)
    base, origins = _base_experiment(doc, path, _seen) if "from" in doc else ({}, {})
    _resolve_sources(doc, path.parent)
    origins[""] = path
    if base:  # this file's keys over the base's, with those it overrides in the base's world
        leaves = _own_leaves(doc)
        if isinstance(doc.get("scenario"), dict) and "from" not in doc["scenario"]:
            leaves += _leaf_paths(doc["scenario"], "scenario")
        for dotted in leaves:
            origins["override " + dotted] = path
    if "scenario" in doc:
        doc["scenario"] = _inline_scenario(doc["scenario"], path, "scenario", origins)
    if isinstance(doc.get("scenarios"), dict):
        for name, scen in doc["scenarios"].items():
            doc["scenarios"][name] = _inline_scenario(scen, path, f"scenarios.{name}", origins)
    doc = _deep_merge(base, doc)
    doc.setdefault("name", path.stem)
    if profile is not None:
        _apply_profile(doc, profile, path, origins)
    _apply_sets(doc, sets, origins)
    return doc, origins


def _apply_sets(doc: dict, sets: list[str], origins: dict[str, Path]) -> None:
    """The command line's ``--set`` settings, in order, each key's origin ``--set`` (a whole world's: its file)."""
    for s in sets:
        for dotted in apply_set(doc, s):
            if not _set_world(doc, dotted, Path("--set"), origins, Path.cwd()):
                origins["--set " + dotted] = Path("--set")


def _set_world(doc: dict, dotted: str, path: Path, origins: dict[str, Path], folder: Path | None = None) -> bool:
    """A setting of a whole world (``scenario``, ``scenarios.<name>``) to a scenario file, ``scenario=FILE`` or
    ``scenario={from: FILE, horizon: 10}``: the file inlined as the config's own reference would be, the origins of
    the world it replaces forgotten. A relative FILE is looked for in ``folder``: the working directory for
    ``--set`` (``path`` is ``--set``), the config's folder for a profile's setting (``path`` is the config). False
    for any other setting; a world's ``from`` alone is refused (it was read with the world's file)."""
    parts = dotted.split(".")
    if parts[-1] == "from" and _is_world(parts[:-1]):
        world = ".".join(parts[:-1])
        raise ConfigError(path, dotted, f"a world's 'from' was read with its file: set the whole world to run on "
                          f"another scenario file, {world}=FILE (or '{world}={{from: FILE, horizon: 10}}' to change "
                          "some of its keys)")
    # the mapping that holds the world: the document's, or its study's (a list there: pydantic's error follows)
    holder = doc if len(parts) == 1 else doc.get("scenarios") if isinstance(doc.get("scenarios"), dict) else {}
    if not (_is_world(parts) and _is_reference(holder.get(parts[-1]))):
        return False
    for origin in [o for o in origins if o.split(" ", 1)[-1] == dotted or o.split(" ", 1)[-1].startswith(dotted + ".")]:
        del origins[origin]  # what the config (or an earlier setting) said of the world replaced
    holder[parts[-1]] = _inline_scenario(holder[parts[-1]], path, dotted, origins, folder)
    return True


def _is_world(parts: list[str]) -> bool:
    """A dotted key's parts name a whole world: ``scenario``, or ``scenarios.<name>``."""
    return parts == ["scenario"] or (len(parts) == 2 and parts[0] == "scenarios")


def _apply_profile(doc: dict, profile: str, path: Path, origins: dict[str, Path]) -> None:
    """Apply the ``dotted.key=value`` settings of the document's named profile (``--profile``); an error in one
    names the file and ``profiles.<name>.<i>``, where it is written."""
    profiles = doc.get("profiles") or {}
    if profile not in profiles:
        raise ConfigError(path, "profiles", f"no profile '{profile}' (have: {', '.join(sorted(profiles)) or 'none'})")
    for i, assignment in enumerate(profiles[profile]):
        try:
            for dotted in apply_set(doc, assignment):
                if not _set_world(doc, dotted, path, origins):
                    origins["override " + dotted] = path
        except ConfigError as exc:
            raise ConfigError(path, f"profiles.{profile}.{i}", f"{exc.key}: {exc.message}") from None


def validation_to_config_error(exc: ValidationError, origins: dict[str, Path], root: Any = Experiment) -> ConfigError:
    """pydantic's first error as one line naming the file the key came from (the experiment, a scenario file, an
    override or a ``--set``) and the key as written in YAML (:func:`keypaths.key_path`); an unknown key gets the
    near misses among the keys allowed there, and the keys of any further errors are named."""
    errors = exc.errors()
    err = errors[0]
    unknown = err["type"] == "extra_forbidden"
    key, allowed = key_path(root, err["loc"], unknown)
    msg = err["msg"].removeprefix("Value error, ")
    if unknown:
        msg = "unknown key" + unknown_key_hint(key, allowed)
    elif err["type"] == "literal_error" and isinstance(err.get("input"), bool):
        msg += f" ({YAML_BOOLEANS}: quote the word)"
    named, rest = keyed_message(msg)
    if named:  # a cross-field check that names its key, relative to where it sits: 'variants.1.scenarios: ...';
        # one of a pair ('horizon|dt: ...'): the one a --set gave, which is what the user just changed, else the first
        keys = [".".join(filter(None, (key, k))) for k in named]
        key, msg = next((k for k in keys if _origin_of(k, origins) == Path("--set")), keys[0]), rest
    file = _origin_of(key, origins)
    # the other keys with errors (a union's other members failing at the same key add nothing)
    first = key or "(top level)"
    keys = list(dict.fromkeys(k for e in errors[1:] if (k := key_path(root, e["loc"])[0] or "(top level)") != first))
    if keys:
        shown = ", ".join(keys[:3]) + (", …" if len(keys) > 3 else "")
        msg += f" (and {len(keys)} more: {shown})"
    return ConfigError(file, key or "(top level)", msg)


def _origin_of(key: str, origins: dict[str, Path]) -> Path:
    """The file a key was written in: the experiment, the scenario file it lives in, the file of a ``from:``
    override or ``--set`` (last wins)."""
    file = origins[""]
    for origin in sorted(o for o in origins if o.startswith("scenario")):
        if key == origin or key.startswith(origin + "."):
            file = origins[origin]
    for origin, source in origins.items():
        for tag in ("override ", "--set "):
            if not origin.startswith(tag):
                continue
            dotted = origin[len(tag):]
            # the key set there, a field inside it, or one the setting wrote into (or created on its way down)
            if key == dotted or key.startswith(dotted + ".") or dotted.startswith(key + "."):
                file = source
    return file


def load_experiment(path: str | Path, sets: list[str] = (), profile: str | None = None) -> tuple[Experiment, dict]:
    """Load and validate an experiment config; raises ConfigError naming the file and key."""
    path = Path(path)
    doc, origins = resolve_document(path, sets, profile)
    if not _experiment_only(doc) and is_scenario_file(path):
        raise ConfigError(path, "", "a scenario file (a world), not an experiment: experiments name it under "
                          "'scenario:' (marinebench validate checks scenario files)")
    try:
        exp = Experiment.model_validate(doc)
    except ValidationError as exc:
        raise validation_to_config_error(exc, origins) from None
    _refuse_lax_booleans(doc, exp.model_dump(), origins)
    return exp, origins


def _refuse_lax_booleans(doc: dict, read: dict, origins: dict[str, Path]) -> None:
    """A boolean where a number belongs, or the reverse, is a wrong type (:func:`settings.lax_boolean`), named
    in the file (or ``--set``) it came from."""
    if found := lax_boolean(doc, read):
        key = ".".join(map(str, found[0]))
        raise ConfigError(_origin_of(key, origins), key, found[1])


def load_checked(path: str | Path, sets: list[str] = (), profile: str | None = None,
                 sweep_params: bool = True) -> tuple[Experiment, dict]:
    """:func:`load_experiment`, then :func:`preflight`: an experiment ready to run, and the files it came from
    (what ``marinebench run`` and :func:`marinebench.load` do before simulating). ``sweep_params=False`` leaves the
    sweep's parameters to the sweep command, which checks the ones it is asked for (``--set sweep.variant`` may
    leave the others without a setting to vary)."""
    exp, origins = load_experiment(path, sets, profile)
    try:
        preflight(exp, Path(path), sweep_params)
    except ConfigError as exc:  # a design that fails for a value a --set or a scenario file gave: name that
        if exc.file == str(path) and (source := _origin_of(exc.key, origins)) != origins[""]:
            raise ConfigError(source, exc.key, exc.message) from None
        raise
    return exp, origins


def load_scenario(path: str | Path):
    """Validate a scenario file of any kind (``kind:`` picks the model; default open_loop_asv)."""
    from pydantic import TypeAdapter

    path = Path(path)
    doc = read_scenario(path)
    try:
        scenario = TypeAdapter(AnyScenario).validate_python(doc)
    except ValidationError as exc:
        raise validation_to_config_error(exc, {"": path}, AnyScenario) from None
    _refuse_lax_booleans(doc, scenario.model_dump(), {"": path})
    return scenario


def _experiment_only(doc: dict) -> bool:
    """Whether ``doc`` has a key only experiments have (``variants``, ``scenario``, ``metrics``, ...; ``name`` and
    ``description`` both have). Before, an experiment without its ``variants`` was read as a scenario file."""
    return bool(doc.keys() & (Experiment.model_fields.keys() - {"name", "description"}))


def is_scenario_file(path: Path, _depth: int = 0) -> bool:
    """A scenario document has no key only experiments have, nor does the file its ``from:`` starts from."""
    try:
        doc = read_yaml(path)
    except ConfigError:
        return False
    if _experiment_only(doc):
        return False
    base = doc.get("from")
    if isinstance(base, str) and _depth < 20 and (path.parent / base).exists():
        return is_scenario_file(path.parent / base, _depth + 1)
    return True
