"""Reading experiment and scenario YAML files into validated models, with file:key error mapping.

An experiment YAML names a scenario file (``scenario: ../scenarios/x.yaml``) or embeds a scenario
with overrides (``scenario: {from: ../scenarios/x.yaml, horizon: 10}``). ``--set dotted.key=value``
edits the resolved document before validation; list items are addressed by index
(``variants.0.observer.eps``) or by name (``variants[liu_eps0.1].observer.eps``), ``*`` stands for every key or
item (``scenarios.*.horizon``). :func:`preflight`
solves every observer design and checks the step before anything runs.
"""

from __future__ import annotations

import copy
import re
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from pydantic import ValidationError

from marinebench.config import DP_SIGNALS, TRUTH_SIGNALS, AnyScenario, Experiment, Variant
from marinebench.controllers.spec import check_built as check_controller
from marinebench.errors import ConfigError, ProtocolError
from marinebench.keypaths import did_you_mean, key_path, near_misses, unknown_key_hint
from marinebench.observers.custom import check_built as check_observer
from marinebench.observers.custom import observer_class
from marinebench.plugins import resolve_source, split_source
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
    for i, part in enumerate(parts):
        idx = _child(node, part, key)
        where.append(str(idx))
        if i == len(parts) - 1:
            node[idx] = value
        else:
            if isinstance(node, dict) and idx not in node:
                if i < 2:
                    _check_world_key(doc, key, where)
                node[idx] = {}
            node = node[idx]
    return ".".join(where)


def _child(node: Any, part: str | tuple[str], key: str) -> int | str:
    """The index in ``node`` that one part of a ``--set`` key names: a ``[name]`` selector (a tuple) the position of
    the list's item of that name, a number a list's position, any other part a mapping's key."""
    if isinstance(part, tuple):  # [name] selector in a list of named items
        if not isinstance(node, list):
            raise ConfigError("--set", key, f"'[{part[0]}]' selects from a list, found {type(node).__name__}")
        match = [j for j, item in enumerate(node) if isinstance(item, dict) and item.get("name") == part[0]]
        if not match:
            raise ConfigError("--set", key, f"no item named '{part[0]}'")
        return match[0]
    if isinstance(node, list):
        if not part.isdigit() or int(part) >= len(node):
            raise ConfigError("--set", key, f"'{part}' is not a valid index (0..{len(node) - 1})")
        return int(part)
    if isinstance(node, dict):
        return part
    raise ConfigError("--set", key, f"cannot descend into a {type(node).__name__}")


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


def _check_exists(resolved: Path, ref: str, path: Path, key: str, what: str) -> None:
    """ConfigError at ``key`` of ``path`` unless the ``what`` file a reference ``ref`` names is a file."""
    if resolved.is_dir():
        raise ConfigError(path, key, f"{ref} is a folder, not a file")
    if not resolved.exists():
        raise ConfigError(path, key, f"{what} file not found: {ref}{_looked_in(ref, resolved)}")


def _looked_in(ref: str, resolved: Path) -> str:
    """Where a relative reference was looked for: against the folder of the file that holds it, which is not the
    working directory a user may read it from."""
    return "" if Path(ref).is_absolute() else f" (relative to the file's folder: looked for {resolved})"


def read_scenario(path: Path, _seen: tuple[Path, ...] = ()) -> dict[str, Any]:
    """A scenario file; ``from: other.yaml`` in it starts from that scenario (relative path) and overrides keys."""
    doc = read_yaml(path)
    if "from" not in doc:
        return doc
    bpath = _from_path(doc.pop("from"), path, _seen, "scenario")
    return _deep_merge(read_scenario(bpath, (*_seen, path.resolve())), doc)


def _inline_scenario(scen: Any, path: Path, key: str, origins: dict[str, Path]) -> Any:
    """Replace a scenario reference (``file`` or ``{from: file, overrides...}``) by the merged document."""
    if not (isinstance(scen, str) or (isinstance(scen, dict) and "from" in scen)):
        return scen
    ref = scen if isinstance(scen, str) else scen["from"]
    overrides = {} if isinstance(scen, str) else {k: v for k, v in scen.items() if k != "from"}
    if not isinstance(ref, str):
        raise ConfigError(path, f"{key}.from", "expected a file path")
    spath = (path.parent / ref).resolve()
    _check_exists(spath, ref, path, key, "scenario")
    origins[key] = shown_path(spath)
    for dotted in _leaf_paths(overrides, key):
        origins["override " + dotted] = path
    return _deep_merge(read_scenario(spath), overrides)


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
    for s in sets:
        for dotted in apply_set(doc, s):
            origins["--set " + dotted] = Path("--set")
    return doc, origins


def _apply_profile(doc: dict, profile: str, path: Path, origins: dict[str, Path]) -> None:
    """Apply the ``dotted.key=value`` settings of the document's named profile (``--profile``); an error in one
    names the file and ``profiles.<name>.<i>``, where it is written."""
    profiles = doc.get("profiles") or {}
    if profile not in profiles:
        raise ConfigError(path, "profiles", f"no profile '{profile}' (have: {', '.join(sorted(profiles)) or 'none'})")
    for i, assignment in enumerate(profiles[profile]):
        try:
            for dotted in apply_set(doc, assignment):
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
    where = re.match(r"^([A-Za-z0-9_.-]+): (.+)$", msg)
    if where:  # a cross-field check that names its key, relative to where it sits: 'variants.1.scenarios: ...'
        key, msg = ".".join(filter(None, (key, where[1]))), where[2]
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
    if "variants" not in doc and is_scenario_file(path):
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


def preflight(exp: Experiment, file: Path, sweep_params: bool = True) -> None:
    """Solve every variant's observer design and check the step before anything runs, so an infeasible
    LMI or a too-large dt is a config error naming the file and key; check the per-run world settings of the
    variants and of the sweep's groups, and (``sweep_params``) that each sweep parameter's key and ``fixed`` settings
    name settings of the swept variant, valid at both ends of its range (its points are built, not designed or run)."""
    if exp.sweep is not None:
        swept = exp.part(exp.sweep_scenario()).scenario if exp.scenarios is not None else exp.scenario
        for group, world in exp.sweep.groups.items():
            _check_world(swept, world, file, f"sweep.groups.{group}")
    if exp.scenarios is None:
        _preflight_single(exp, file, "scenario", list(range(len(exp.variants))))
    else:
        position = {v.name: i for i, v in enumerate(exp.variants)}
        for name in exp.scenarios:
            part = exp.part(name)
            _preflight_single(part, file, f"scenarios.{name}", [position[v.name] for v in part.variants])
    if exp.sweep is not None and sweep_params:  # after the variants: what is left wrong is the sweep's own
        from marinebench.experiments.sweep import sweep_experiment

        # in one group: a world key that the groups set may still be swept in one of them (--groups NAME)
        sweep_experiment(exp, list(exp.sweep.params), list(exp.sweep.groups)[:1], 2, None, file)


@contextmanager
def _user_code(file: Path, key: str) -> Iterator[None]:
    """Run a custom class's own code at validation: whatever it raises (a constructor refusing its params, a
    member failing or returning the wrong thing, a ProtocolError: said as it is) becomes one config error at ``key``."""
    try:
        yield
    except ProtocolError as exc:
        raise ConfigError(file, key, str(exc)) from None
    except Exception as exc:  # noqa: BLE001 - the class's code: any exception is the user's to fix
        raise ConfigError(file, key, f"{type(exc).__name__}: {exc}") from None


@contextmanager
def _numerics(file: Path, key: str, failure: str, custom_key: str | None = None) -> Iterator[None]:
    """Build an observer's design or a world. A design that refuses its settings (an infeasible LMI), a custom
    class's constructor refusing its params (at ``custom_key``), and values valid in range but too extreme for the
    numerics (e.g. 1e300: an ArithmeticError or ValueError, as numpy's LinAlgError is) each become one config
    error (``failure``, then the exception); the numerics' warnings are shown only when the build succeeds."""
    from marinebench.errors import DesignError

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            yield
        except DesignError as exc:
            raise ConfigError(file, key, str(exc)) from None
        except Exception as exc:
            if custom_key is not None:
                raise ConfigError(file, custom_key, f"{type(exc).__name__}: {exc}") from None
            if not isinstance(exc, ArithmeticError | ValueError):
                raise
            first = str(exc).splitlines()[0] if str(exc) else "numerical failure"
            raise ConfigError(file, key, f"{failure} ({type(exc).__name__}: {first})") from None
    for w in caught:
        warnings.showwarning(w.message, w.category, w.filename, w.lineno)


def _preflight_single(exp: Experiment, file: Path, key: str, positions: list[int]) -> None:
    """Preflight of one scenario's variants (``key`` is where the scenario sits, ``positions`` the variants'
    indices in the file): each variant's controller or observer, the CDO designs, that each variant's world builds
    (one seed), the metrics' signals, the step."""
    from marinebench.errors import StiffnessError
    from marinebench.experiments.runner import make_world, plant_of
    from marinebench.sim.engine import check_step

    model_key = "design_vessel" if getattr(exp.scenario, "design_vessel", None) is not None else "vessel"
    with _numerics(file, f"{key}.{model_key}", "the vessel model cannot be built from these values"):
        plant = plant_of(exp.scenario)  # the model every variant's observer is designed on
    named = [(v.name, g) for i, v in zip(positions, exp.variants)
             if (g := _preflight_variant(exp, file, i, v, plant)) is not None]
    groups = [g for _, g in named]
    if exp.scenario.kind == "rov_tracking":
        _preflight_cdo(exp, file, key, positions)
    _preflight_metrics(exp, file, groups)
    _preflight_figures(exp, file, groups)
    # the world's numerics' warnings are shown only if it builds, passes the step check and starts finite
    with _numerics(file, key, "the world cannot be built from these values"):  # each variant's, one seed
        world = make_world(exp, np.arange(len(exp.variants)), np.zeros(len(exp.variants), dtype=int))
        if exp.engine.check_step:
            try:
                check_step(groups, exp.scenario.dt, exp.engine.stiffness_limit, world)
            except StiffnessError as exc:
                raise ConfigError(file, f"{key}.dt", f"{exc} ({_fastest(exp, named, world)})") from None
        if (problem := _first_step_problem(world)) is not None:  # after the step check, which says more
            raise ConfigError(file, key, f"the world cannot be run from these values ({problem})")


def _first_step_problem(world: Any) -> str | None:
    """What is not finite in the world's first step (its sensors sampled, then its state derivative, measurement
    and input at t = 0), or None. Values in range but absurd for the physics (a sea state's gamma of 1e300) would
    otherwise make every run diverge at once, found only after the whole simulation."""
    x0 = world.x0.copy()
    with np.errstate(all="ignore"):
        if hasattr(world, "begin_step"):
            world.begin_step(0, 0.0, x0)
        parts = dict(zip(("state derivative", "measurement", "input"), world.derivative(0.0, x0)))
    bad = (["initial state"] if not np.isfinite(x0).all() else []) + [n for n, a in parts.items() if not np.isfinite(a).all()]
    return f"not finite at t = 0: its {' and '.join(bad)}" if bad else None


def _fastest(exp: Experiment, named: list, world: Any) -> str:
    """Which variant has the fastest observer pole: its observer group's, or those its world integrates (one run per
    variant, as preflight builds it; a world's own setting can make them all alike)."""
    rates = dict.fromkeys((v.name for v in exp.variants), 0.0)
    for name, group in named:
        rates[name] = max(rates[name], group.observer.max_rate())
    for v, rate in zip(exp.variants, world.observer_rates() if hasattr(world, "observer_rates") else []):
        rates[v.name] = max(rates[v.name], float(rate))
    if len(rates) > 1 and len(set(rates.values())) == 1:
        return "every variant alike"
    return f"the fastest: variant {max(rates, key=rates.__getitem__)!r}"


def _check_world(scenario: Any, world: dict[str, float], file: Path, key: str) -> None:
    """Per-run world settings (a variant's ``world:``, a sweep group): keys the scenario takes per run, values within
    the bounds of its own fields (e.g. no negative noise level)."""
    unknown = sorted(set(world) - set(allowed := list(scenario.per_run_defaults())))
    if unknown:
        near = did_you_mean(list(dict.fromkeys(m for u in unknown for m in near_misses(u, allowed))))
        takes = near or (f" (allowed: {allowed})" if allowed else f" (the {scenario.kind} world takes none)")
        raise ConfigError(file, key, f"unknown per-run world keys {unknown}{takes}")
    try:
        scenario.check_per_run(world)
    except ValidationError as exc:
        err = exc.errors()[0]
        raise ConfigError(file, f"{key}.{err['loc'][0]}", err["msg"].removeprefix("Value error, ")) from None


def _preflight_variant(exp: Experiment, file: Path, i: int, v: Variant, plant: Any) -> Any:
    """Check variant ``i``: its per-run world keys, that it has what its scenario needs (a controller in a
    closed loop, an applicable observer otherwise), and that its design solves. Returns the observer's group
    for the step check, or None for a controller."""
    from marinebench.experiments.runner import make_observer, observer_kinds_for, wants_lumped
    from marinebench.sim.engine import ObserverGroup

    _check_world(exp.scenario, v.world, file, f"variants.{i}.world")
    closed_loop = exp.scenario.kind == "rov_tracking"
    if closed_loop != (v.controller is not None):
        need = "a 'controller'" if closed_loop else "an 'observer'"
        raise ConfigError(file, f"variants.{i}", f"scenario kind {exp.scenario.kind} needs {need} in every variant")
    if closed_loop:
        if v.controller.kind == "custom":
            with _user_code(file, f"variants.{i}.controller.params"):  # its constructor refusing its params
                built = v.controller.build(1)
            with _user_code(file, f"variants.{i}.controller.source"):
                check_controller(built, exp.scenario.control_period)
        return None
    if v.observer.kind not in (usable := observer_kinds_for(exp.scenario)):
        raise ConfigError(file, f"variants.{i}.observer.kind", f"'{v.observer.kind}' does not apply to scenario kind "
                          f"{exp.scenario.kind} (its observers: {', '.join(sorted(usable))})")
    custom = v.observer.kind == "custom"
    if custom and exp.scenario.kind not in (own := observer_class(v.observer.source).scenario_kinds):
        raise ConfigError(file, f"variants.{i}.observer.source", f"{split_source(v.observer.source)[1]} does not apply "
                          f"to scenario kind {exp.scenario.kind} (its scenario_kinds: {', '.join(own)})")
    with _numerics(file, f"variants.{i}.observer", "no design for these values",
                   f"variants.{i}.observer.params" if custom else None):
        group = ObserverGroup(make_observer(v.observer.kind, [v.observer], exp.scenario, plant, wants_lumped(exp)), [0])
    if custom:
        with _user_code(file, f"variants.{i}.observer.source"):
            check_observer(group.observer, 1)
    return group


def _preflight_cdo(exp: Experiment, file: Path, key: str, positions: list[int]) -> None:
    """Solve the scenario's CDO design (LMIs (39)-(40)) and each distinct per-variant CDO override's."""
    failure = "the CDO design fails for these values"
    with _numerics(file, f"{key}.cdo", failure):
        exp.scenario.cdo_design()
    checked = set()
    for i, v in zip(positions, exp.variants):
        if v.observer is None or not v.observer.cdo:
            continue
        cdo = v.observer.resolve(exp.scenario)[0]
        if (fingerprint := cdo.model_dump_json()) in checked:
            continue
        with _numerics(file, f"variants.{i}.observer.cdo", failure):
            exp.scenario.cdo_design(cdo)
        checked.add(fingerprint)


def _estimated(groups: list) -> set[str]:
    """The signals the variants' observers estimate; on a closed-loop world (no observer groups) its own."""
    from marinebench.rov_scenario import ROV_SIGNALS

    return set().union(*(g.observer.signals for g in groups)) if groups else set(ROV_SIGNALS)


def _preflight_figures(exp: Experiment, file: Path, groups: list) -> None:
    """Every figure's signals are in the traces: estimated by a variant's observer, with a truth in the world. Before,
    a figure of another signal failed after the whole simulation, with a traceback."""
    truth = TRUTH_SIGNALS.get(exp.scenario.kind)
    usable = _estimated(groups) & set(truth) if truth is not None else _estimated(groups)
    for f in exp.figures:
        if bad := [s for s in f.signals if s not in usable]:
            raise ConfigError(file, "figures", f"{f.file}: no trace of {bad} on this world (a figure may show: "
                              f"{', '.join(sorted(usable))})")


def _preflight_metrics(exp: Experiment, file: Path, groups: list) -> None:
    """Every metric's signals are ones the variants' observers estimate and the world has a truth of."""
    signals = _estimated(groups)
    truth = TRUTH_SIGNALS.get(exp.scenario.kind)
    for j, m in enumerate(exp.metrics):
        if m.kind not in ("j_tot", "int", "recovery"):
            if bad := set(m.signals) - signals:
                raise ConfigError(file, f"metrics.{j}.signals", f"unknown signals {sorted(bad)}")
            if truth is not None and set(m.signals) - set(truth):
                raise ConfigError(file, f"metrics.{j}.signals", f"{sorted(set(m.signals) - set(truth))}: an "
                                  f"{exp.scenario.kind} world has no truth of these (it has {', '.join(truth)})")
        if m.kind == "j_tot" and not set(DP_SIGNALS) <= signals:
            raise ConfigError(file, f"metrics.{j}", "j_tot needs the DP state estimates (pose, bias, velocity), "
                              "which no variant's observer produces (npo and resetting_fto do)")


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


def is_scenario_file(path: Path, _depth: int = 0) -> bool:
    """A scenario document has no ``variants`` key, nor does the file its ``from:`` starts from."""
    try:
        doc = read_yaml(path)
    except ConfigError:
        return False
    if "variants" in doc:
        return False
    base = doc.get("from")
    if isinstance(base, str) and _depth < 20 and (path.parent / base).exists():
        return is_scenario_file(path.parent / base, _depth + 1)
    return True
