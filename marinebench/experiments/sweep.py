"""One-at-a-time parameter sweeps (Torben et al. Fig. 3) as a single batch through the one engine.

For each named parameter, ``n`` values over its range (the others at the config's values), for each
world group (e.g. differential and dual-band GNSS): ``n x len(params) x len(groups)`` runs, all in one
batch with per-run gains and parameters. Each run is a variant tagged with ``param``, ``param_value``
and ``gnss`` (the group), which become columns of ``metrics.csv``. Here: the sweep's points
(:func:`sweep_experiment`), its parameters given in place (:func:`inline_params`) and its folder's name
(:func:`sweep_suffix`); ``experiments/chunks.py`` runs them in chunks, resumably, and ``experiments/curves.py``
(``experiments/grid.py`` for a grid) makes the table, claims and figure of their ``metrics.csv``.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import re
from collections.abc import Mapping, Sequence
from numbers import Integral
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from marinebench.config import MAX_SWEEP_N, Experiment, SweepSpec, Variant
from marinebench.errors import ConfigError
from marinebench.experiments.settings import MISSING, put_setting, setting_at, setting_path
from marinebench.keypaths import did_you_mean, keyed_message, near_misses

GRID_N = 11  # points per axis of a grid sweep (`sweep --grid`) unless --n says otherwise
COMMAND_ARGS = {"params": "PARAM", "horizon": "--horizon", "grid": "--grid"}  # what the command's errors name
LIBRARY_ARGS = {"params": "params", "horizon": "horizon", "grid": "grid"}  # and marinebench.sweep's


def points_error(n: int | None, horizon: float | None) -> tuple[str, str] | None:
    """What is wrong with a sweep's ``n`` (points per parameter; a numpy integer too) or ``horizon`` (simulated
    seconds per run) as given to ``sweep --n/--horizon`` or :func:`marinebench.sweep`: ``(argument, what it must
    be)``, or None when both are in range or not given."""
    if n is not None and not (isinstance(n, Integral) and 2 <= n <= MAX_SWEEP_N):
        return "n", f"from 2 to {MAX_SWEEP_N} points per parameter"
    if horizon is not None and not (0 < horizon < float("inf")):  # nan fails both
        return "horizon", "a positive, finite number of seconds"
    return None


def sweep_suffix(exp: Experiment, params: list[str], groups: list[str] | None = None, n: int | None = None,
                 horizon: float | None = None, overrides: Sequence[str] = (), grid: bool = False) -> str:
    """``_sweep`` and what sets this sweep apart from the config's full one-seed sweep, so that none replaces
    another's folder: the parameters and world groups swept when only some of the config's (in the config's
    order), ``_n<N>`` for another number of points, ``_<T>s`` for another horizon, the command line's
    ``overrides`` (``--set key=value`` and ``--seed``, see :func:`override_tags`) and ``_<seeds>seeds`` for a
    Monte-Carlo sweep (``torben_fig3`` + ``_sweep_eps_20seeds``, ``_sweep_k_dgnss_n21_200s``,
    ``_sweep_eps_scenario.sensors.gm_time_constant=100_3seeds``; a parameter given in place is named by its
    argument alone: ``_sweep_k_omega=0.01..1000-log``). A grid sweep adds ``_grid`` and its two
    parameters in the order given (``_sweep_grid_k_eps``), ``_n<N>`` when not :data:`GRID_N` points per axis.
    Variants swept side by side (``sweep.variants``, ``--variants``) are named joined by ``+`` after the
    parameters (``_sweep_noise_scale_liu_eps0.1+proposed_d2.2``).
    ``exp`` is the config's experiment (its ``sweep`` section and seeds)."""
    spec = exp.sweep
    if grid:
        tags = ["grid", *params]
    else:  # a parameter given in place (KEY=LO..HI, among the overrides) is named by its argument, once
        in_place = {p for p in params if any(o.partition("=")[0].strip() == spec.params[p].key for o in overrides)}
        tags = [p for p in spec.params if p in params and p not in in_place] if set(params) < set(spec.params) else []
    if len(spec.swept) > 1:
        tags.append("+".join(spec.swept))
    if groups and set(groups) < set(spec.groups):
        tags += [g for g in spec.groups if g in groups]
    if n is not None and n != (GRID_N if grid else spec.n):
        tags.append(f"n{n}")
    own = (exp.part(exp.sweep_scenario()) if exp.scenarios is not None else exp).scenario.horizon
    if horizon is not None and horizon != own:
        tags.append(f"{horizon:g}s")
    tags += override_tags(overrides)
    if exp.seeds > 1:
        tags.append(f"{exp.seeds}seeds")
    return "_sweep" + "".join(f"_{t}" for t in tags)


def inline_params(args: Sequence[str],
                  what: str = COMMAND_ARGS["params"]) -> tuple[list[str], dict[str, tuple[str, str]]]:
    """The sweep command's PARAM arguments: the name of one of the config's ``sweep.params``, or a parameter given
    in place, ``KEY=LO..HI`` (``:log`` after it for log spacing), with ``KEY`` as :class:`~marinebench.config.SweepParam`
    reads it: ``delta_p1=0.5..3``, ``observer.cdo.lmi_decay=0.1..1``, ``world.gnss_sigma=0.05..3:log``. Such a
    parameter is named after the key's last part and added to (or replaces) ``sweep.params``; a config without a
    ``sweep`` section gets one. Returns the names, and for the parameters given in place the ``--set`` each stands
    for: ``{"sweep.params.<name>": (argument, value)}``. Errors name the arguments ``what`` (the command's
    ``PARAM``, :func:`marinebench.sweep`'s ``params``)."""
    names, sets = [], {}
    for arg in args:
        if "=" not in arg:
            names.append(arg)
            continue
        key, _, rest = arg.partition("=")
        bounds, _, spacing = rest.partition(":")
        lo, sep, hi = bounds.partition("..")
        try:
            if not (re.fullmatch(r"[A-Za-z_][\w.]*", key.strip()) and sep and spacing in ("", "linear", "log")):
                raise ValueError
            value = {"key": key.strip(), "range": [float(lo), float(hi)], "spacing": spacing or "linear"}
        except ValueError:
            raise ConfigError(what, arg, "expected a name of sweep.params or KEY=LO..HI[:log], e.g. delta_p1=0.5..3 or "
                              "world.gnss_sigma=0.05..3:log") from None
        name = value["key"].rsplit(".", 1)[-1]
        if f"sweep.params.{name}" in sets or name in names:
            raise ConfigError(what, arg, f"'{name}' is swept twice")
        names.append(name)
        sets[f"sweep.params.{name}"] = (arg, json.dumps(value))
    return names, sets


def with_params_in_place(exp: Experiment, inline: dict[str, tuple[str, str]], file: Path) -> Experiment:
    """A loaded experiment with the parameters given in place (:func:`inline_params`) in its ``sweep.params``
    (a ``sweep`` section made for them when it has none), validated again, and without the section's claims about
    them at values outside their new ranges (:func:`claims_beyond`): what ``marinebench sweep`` does to the
    document before validating it, for :func:`marinebench.sweep`, whose experiment may be loaded already. An error
    names the argument (:func:`in_place_error`)."""
    if not inline:
        return exp
    doc = exp.model_dump()
    spec = doc["sweep"] or {}
    params = (spec.get("params") or {}) | {key.removeprefix("sweep.params."): json.loads(value)
                                           for key, (_, value) in inline.items()}
    doc["sweep"] = spec | {"params": params, "claims": claims_beyond(spec.get("claims"), inline)[0]}
    try:
        return Experiment.model_validate(doc)
    except ValidationError as exc:
        from marinebench.loading import validation_to_config_error

        raise in_place_error(validation_to_config_error(exc, {"": file}), inline) from None


def in_place_error(exc: ConfigError, inline: dict[str, tuple[str, str]]) -> ConfigError:
    """An error about parameters given in place (its key ``sweep.params.<name>...``; a grid's pair:
    ``sweep.params.<a>,<b>``) naming the arguments as typed (``k=-1..2:log: bad range ...``); any other as it is."""
    if not exc.key.startswith("sweep.params."):
        return exc
    about = exc.key.removeprefix("sweep.params.").split(".")[0].split(",")
    given = [inline[f"sweep.params.{name}"][0] for name in about if f"sweep.params.{name}" in inline]
    return ConfigError(" ".join(given), "", exc.message) if given else exc


def claims_beyond(claims: Any, inline: dict[str, tuple[str, str]]) -> tuple[list, list[str]]:
    """A parameter given in place over a narrower range than the config's (``k=0.5..1`` on Torben's Fig. 3, whose
    claim compares k = 0.7 with k = 0) leaves the config's ``sweep.claims`` about it at values outside that range
    unchecked: ``claims`` (the document's, as written) without them, and a note on each one left out. Claims whose
    values lie inside the new range, and those about other parameters, stay as they are."""
    kept, notes = [], []
    for i, claim in enumerate(claims if isinstance(claims, list) else []):
        given = inline.get(f"sweep.params.{claim.get('param')}") if isinstance(claim, dict) else None
        values = _claim_values(claim) if given else []
        lo, hi = json.loads(given[1])["range"] if given else (0, 0)
        outside = [v for v in values if isinstance(v, (int, float)) and not lo <= v <= hi]
        if outside:
            notes.append(f"sweep.claims.{i} is not checked ('{claim.get('text', '')}'): "
                         f"{', '.join(f'{v:g}' for v in outside)} outside {given[0]}")
        else:
            kept.append(claim)
    return kept, notes


def _claim_values(claim: dict) -> list:
    """The parameter values a sweep claim (as written) is about: a probe's ``at`` and ``vs``, a trend's range."""
    values = [claim.get("at"), claim.get("vs")] if claim.get("kind") == "probe" else (
        list(claim.get("range") or []) if claim.get("kind") == "trend" else [])
    return [v for v in values if v is not None]


def override_tags(overrides: Sequence[str], limit: int = 60) -> list[str]:
    """Folder-name tags of command-line overrides, one per ``key=value`` as given, lists as their
    comma-separated items (``scenario.sensors.gm_time_constant=100``, ``seed=7``,
    ``variants[resetting].observer.eps=0.1,0.1,0.01``), or, when they would make the name longer than
    ``limit`` characters, one tag ``set-<digest>`` (the overrides themselves are in the manifest)."""
    tags = []
    for item in overrides:
        key, _, value = item.partition("=")
        value = re.sub(r"\s*,\s*", ",", value.strip().strip("[](){}"))
        tags.append(re.sub(r"[^A-Za-z0-9._+,=\[\]-]+", "-", f"{key.strip()}={value}"))
    if sum(len(t) + 1 for t in tags) > limit:
        return ["set-" + hashlib.sha256("\n".join(overrides).encode()).hexdigest()[:8]]
    return tags


def sweep_experiment(exp: Experiment, params: list[str], groups: list[str] | None, n: int | None,
                     horizon: float | None, file: Path, overrides: Sequence[str] = (), grid: bool = False,
                     args: Mapping[str, str] = COMMAND_ARGS) -> Experiment:
    """The experiment whose variants are the sweep's points, each run with the experiment's seeds.

    One at a time (default): ``n`` values of each parameter, the others at the variant's settings; every run
    is tagged ``param``, ``param_value`` and ``gnss`` (its world group). ``grid``: every combination of the
    ``n`` values (default :data:`GRID_N`) of exactly two parameters, tagged also ``param2``, ``param2_value``.
    The experiment (and its output folder) is named by :func:`sweep_suffix`: a Monte-Carlo sweep, or one of
    some of the parameters or groups, with other points, another horizon or command-line ``overrides``, does
    not replace the full sweep. Errors about the request name the arguments ``args`` (the command's
    :data:`COMMAND_ARGS`, :func:`marinebench.sweep`'s :data:`LIBRARY_ARGS`)."""
    spec = exp.sweep
    if spec is None:
        raise ConfigError(file, "sweep", "this config has no 'sweep' section: give the parameters in place, "
                          "KEY=LO..HI[:log] (e.g. marinebench sweep delta_p1=0.5..3 --config FILE)")
    name = exp.name + sweep_suffix(exp, params, groups, n, horizon, overrides, grid)
    exp = exp.part(exp.sweep_scenario()) if exp.scenarios is not None else exp
    groups = _checked_request(spec, params, groups, grid, file, args)
    several = len(spec.swept) > 1
    n = n or (GRID_N if grid else spec.n)
    variants = [v for base in (next(v for v in exp.variants if v.name == name) for name in spec.swept)
                for axes in ([params] if grid else [[p] for p in params])
                for v in _points(spec, base, axes, groups, n, file, exp.scenario, several)]
    scenario = exp.scenario if horizon is None else _with_horizon(exp, horizon, file, args["horizon"])
    return exp.model_copy(update={"variants": variants, "figures": [], "table": None, "sweep": None, "name": name,
                                  "scenario": scenario})


def as_swept(exp: Experiment, params: list[str], horizon: float | None = None) -> Experiment:
    """The config a sweep of ``params`` ran, for its ``config.resolved.yaml``: ``sweep.params`` and
    ``sweep.claims`` cut to those parameters, and the swept world's horizon the ``horizon`` its runs had
    (``sweep --horizon``; ``compare`` pairs only runs of the same world). Every parameter of a file must be a
    setting of each swept variant, and ``--variants`` may sweep a variant of which another parameter is no
    setting (``delta_p1`` beside Liu's ESO), so the uncut config would not validate as a file."""
    spec = exp.sweep
    update: dict[str, Any] = {"sweep": spec.model_copy(update={
        "params": {p: spec.params[p] for p in params}, "claims": [c for c in spec.claims if c.param in params]})}
    if horizon is not None and exp.scenarios is not None:
        name = exp.sweep_scenario()
        update["scenarios"] = {**exp.scenarios, name: exp.scenarios[name].model_copy(update={"horizon": horizon})}
    elif horizon is not None:
        update["scenario"] = exp.scenario.model_copy(update={"horizon": horizon})
    return exp.model_copy(update=update)


def _with_horizon(exp: Experiment, horizon: float, file: Path, arg: str) -> Any:
    """The experiment's world run for ``horizon`` seconds, validated as if the file said so (its metric windows,
    the step count)."""
    try:
        exp.check_windows(horizon)
        return type(exp.scenario).model_validate(exp.scenario.model_dump() | {"horizon": horizon})
    except ValueError as exc:  # a metric window past the horizon, or the world's own checks (a ValidationError)
        msg = exc.errors()[0]["msg"].removeprefix("Value error, ") if isinstance(exc, ValidationError) else str(exc)
        raise ConfigError(arg, "", f"{horizon:g} s: {keyed_message(msg)[1]} ({file})") from None  # the key is --horizon


def _checked_request(spec: SweepSpec, params: list[str], groups: list[str] | None, grid: bool, file: Path,
                     args: Mapping[str, str]) -> list[str]:
    """The command line's parameters and world groups checked against the config's sweep section; the groups
    to run (default: all of the config's)."""
    unknown = [p for p in params if p not in spec.params]
    if unknown:
        near = did_you_mean(list(dict.fromkeys(m for p in unknown for m in near_misses(p, sorted(spec.params)))))
        raise ConfigError(file, "sweep.params", f"unknown parameter(s) {unknown}{near}; sweepable: {sorted(spec.params)}")
    twice = sorted({p for p in params if list(params).count(p) > 1})
    if twice and not grid:
        raise ConfigError(args["params"], "", f"parameter(s) {twice} given more than once ({file})")
    if grid and (len(params) != 2 or params[0] == params[1]):
        raise ConfigError(args["grid"], "", f"a grid sweep takes two different parameters, got {params} ({file})")
    groups = groups or list(spec.groups)
    bad = [g for g in groups if g not in spec.groups]
    if bad:
        raise ConfigError(file, "sweep.groups", f"unknown group(s) {bad}; available: {sorted(spec.groups)}")
    return groups


def _points(spec: SweepSpec, base: Variant, axes: list[str], groups: list[str], n: int, file: Path,
            scenario: Any, several: bool = False) -> list[Variant]:
    """The variants of one sweep axis (one parameter) or of a grid (two): ``base``'s settings with each swept
    parameter's ``fixed`` settings applied, at every combination of the axes' ``n`` values, in every world group.
    A run's per-run world settings are the variant's own, then its group's, then the sweep's ``world.<key>`` values
    (a key that a group sets is refused when several groups are swept: they would not differ in it). When
    ``several`` variants are swept side by side, each point is named after ``base`` too and tagged
    ``sweep_variant`` (a column of metrics.csv)."""
    settings = base.model_dump(include={"observer", "controller"}, exclude_none=True) | {"world": {}}
    swept_groups = {g: spec.groups[g] for g in groups}
    for p in axes:
        ps = spec.params[p]
        _check_key(settings, ps.key, base.name, scenario, swept_groups, file, f"sweep.params.{p}.key")
        for key, value in ps.fixed.items():
            if key.startswith("world."):
                _check_key(settings, key, base.name, scenario, swept_groups, file, f"sweep.params.{p}.fixed")
            put_setting(settings, setting_path(key), value)
    grids = [spec.params[p].values(n) for p in axes]
    variants = []
    for index in itertools.product(*(range(n) for _ in axes)):
        values = [float(points[i]) for points, i in zip(grids, index)]
        point = copy.deepcopy(settings)
        for p, value in zip(axes, values):
            put_setting(point, setting_path(spec.params[p].key), value)
        tags = {"param": axes[0], "param_value": values[0]}
        if len(axes) == 2:
            tags |= {"param2": axes[1], "param2_value": values[1]}
        if several:
            tags |= {"sweep_variant": base.name}
        for g in groups:
            world = base.world | spec.groups[g] | point["world"]
            try:
                scenario.check_world(world)
                variants.append(Variant.model_validate({
                    **point, "name": (f"{base.name}_" if several else "")
                    + "_".join(f"{p}_{i:03d}" for p, i in zip(axes, index)) + f"_{g}",
                    "world": world, "tags": tags | {"gnss": g}}))
            except ValidationError as exc:
                at = ", ".join(f"{p}={v:g}" for p, v in zip(axes, values))
                raise ConfigError(file, f"sweep.params.{axes[-1] if len(axes) == 1 else ','.join(axes)}",
                                  f"{at}: {exc.errors()[0]['msg'].removeprefix('Value error, ')}") from None
    return variants


def _check_key(settings: dict, key: str, variant: str, scenario: Any, groups: dict[str, dict], file: Path, where: str) -> None:
    """A sweep key names a setting of the variant, or a per-run world key of its scenario that no group sets when
    several ``groups`` are swept."""
    if key.startswith("world."):
        name, own = key.removeprefix("world."), scenario.per_run_defaults()
        if name not in own and scenario.setting(name) is None:
            takes = f"its per-run keys: {', '.join(own)}" if own else f"the {scenario.kind} world takes none"
            raise ConfigError(file, where, f"'{key}' is neither a per-run world key ({takes}) nor a numeric setting of "
                              f"the world by its dotted path (e.g. world.sensors.<key>; {' and '.join(scenario.SHARED)} "
                              "are every run's)")
        clash = [g for g, world in groups.items() if name in world]
        if clash and len(groups) > 1:
            raise ConfigError(file, where, f"'{key}' is also set by world group(s) {clash}, which would not differ in it: "
                              "sweep it in one group (--groups NAME), whose value it replaces, or in groups that do not set it")
    elif setting_at(settings, setting_path(key)) is MISSING:
        raise ConfigError(file, where, f"'{key}' is not a setting of variant '{variant}' (an observer field, or a path "
                          f"under observer., controller. or world.)")
