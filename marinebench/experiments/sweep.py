"""One-at-a-time parameter sweeps (Torben et al. Fig. 3) as a single batch through the one engine.

For each named parameter, ``n`` values over its range (the others at the config's values), for each
world group (e.g. differential and dual-band GNSS): ``n x len(params) x len(groups)`` runs, all in one
batch with per-run gains and parameters. Each run is a variant tagged with ``param``, ``param_value``
and ``gnss`` (the group), which become columns of ``metrics.csv``.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from pydantic import ValidationError
from scipy.stats import spearmanr

from marinebench.claims import GroupsClaim, ProbeClaim, TrendClaim
from marinebench.config import Experiment, SweepSpec, Variant
from marinebench.errors import ClusterError, ConfigError
from marinebench.experiments.settings import MISSING, put_setting, setting_at, setting_path, tuning
from marinebench.keypaths import did_you_mean, near_misses
from marinebench.metrics.stats import mean_ci
from marinebench.plotting.figures import plain_log_labels, save
from marinebench.results.claims import Check, ClaimResult, Region, bootstrap_ci
from marinebench.results.stored import read_tidy
from marinebench.results.tables import simulated_on

GRID_N = 11  # points per axis of a grid sweep (`sweep --grid`) unless --n says otherwise
MAX_SWEEP_N = 1000  # points per swept parameter at most (a grid has the square): more is a typo, not a study


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


def inline_params(args: Sequence[str]) -> tuple[list[str], dict[str, tuple[str, str]]]:
    """The sweep command's PARAM arguments: the name of one of the config's ``sweep.params``, or a parameter given
    in place, ``KEY=LO..HI`` (``:log`` after it for log spacing), with ``KEY`` as :class:`~marinebench.config.SweepParam`
    reads it: ``delta_p1=0.5..3``, ``observer.cdo.lmi_decay=0.1..1``, ``world.gnss_sigma=0.05..3:log``. Such a
    parameter is named after the key's last part and added to (or replaces) ``sweep.params``; a config without a
    ``sweep`` section gets one. Returns the names, and for the parameters given in place the ``--set`` each stands
    for: ``{"sweep.params.<name>": (argument, value)}``."""
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
            raise ConfigError("PARAM", arg, "expected a name of sweep.params or KEY=LO..HI[:log], e.g. delta_p1=0.5..3 or "
                              "world.gnss_sigma=0.05..3:log") from None
        name = value["key"].rsplit(".", 1)[-1]
        if f"sweep.params.{name}" in sets or name in names:
            raise ConfigError("PARAM", arg, f"'{name}' is swept twice")
        names.append(name)
        sets[f"sweep.params.{name}"] = (arg, json.dumps(value))
    return names, sets


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
                     horizon: float | None, file: Path, overrides: Sequence[str] = (), grid: bool = False) -> Experiment:
    """The experiment whose variants are the sweep's points, each run with the experiment's seeds.

    One at a time (default): ``n`` values of each parameter, the others at the variant's settings; every run
    is tagged ``param``, ``param_value`` and ``gnss`` (its world group). ``grid``: every combination of the
    ``n`` values (default :data:`GRID_N`) of exactly two parameters, tagged also ``param2``, ``param2_value``.
    The experiment (and its output folder) is named by :func:`sweep_suffix`: a Monte-Carlo sweep, or one of
    some of the parameters or groups, with other points, another horizon or command-line ``overrides``, does
    not replace the full sweep."""
    spec = exp.sweep
    if spec is None:
        raise ConfigError(file, "sweep", "this config has no 'sweep' section: give the parameters in place, "
                          "KEY=LO..HI[:log] (e.g. marinebench sweep delta_p1=0.5..3 --config FILE)")
    name = exp.name + sweep_suffix(exp, params, groups, n, horizon, overrides, grid)
    exp = exp.part(exp.sweep_scenario()) if exp.scenarios is not None else exp
    groups = _checked_request(spec, params, groups, grid, file)
    several = len(spec.swept) > 1
    n = n or (GRID_N if grid else spec.n)
    variants = [v for base in (next(v for v in exp.variants if v.name == name) for name in spec.swept)
                for axes in ([params] if grid else [[p] for p in params])
                for v in _points(spec, base, axes, groups, n, file, exp.scenario, several)]
    scenario = exp.scenario if horizon is None else _with_horizon(exp, horizon, file)
    return exp.model_copy(update={"variants": variants, "figures": [], "table": None, "sweep": None, "name": name,
                                  "scenario": scenario})


def as_swept(exp: Experiment, params: list[str]) -> Experiment:
    """The config a sweep of ``params`` ran, for its ``config.resolved.yaml``: ``sweep.params`` and
    ``sweep.claims`` cut to those parameters. Every parameter of a file must be a setting of each swept variant,
    and ``--variants`` may sweep a variant of which another parameter is no setting (``delta_p1`` beside Liu's
    ESO), so the uncut config would not validate as a file."""
    spec = exp.sweep
    return exp.model_copy(update={"sweep": spec.model_copy(update={
        "params": {p: spec.params[p] for p in params}, "claims": [c for c in spec.claims if c.param in params]})})


def _with_horizon(exp: Experiment, horizon: float, file: Path) -> Any:
    """The experiment's world run for ``horizon`` seconds, validated as if the file said so (its metric windows,
    the step count)."""
    try:
        exp.check_windows(horizon)
        return type(exp.scenario).model_validate(exp.scenario.model_dump() | {"horizon": horizon})
    except ValueError as exc:  # a metric window past the horizon, or the world's own checks (a ValidationError)
        msg = exc.errors()[0]["msg"].removeprefix("Value error, ") if isinstance(exc, ValidationError) else str(exc)
        raise ConfigError("--horizon", "", f"{horizon:g} s: {msg.removeprefix('horizon: ')} ({file})") from None


def _checked_request(spec: SweepSpec, params: list[str], groups: list[str] | None, grid: bool, file: Path) -> list[str]:
    """The command line's parameters and world groups checked against the config's sweep section; the groups
    to run (default: all of the config's)."""
    unknown = [p for p in params if p not in spec.params]
    if unknown:
        near = did_you_mean(list(dict.fromkeys(m for p in unknown for m in near_misses(p, sorted(spec.params)))))
        raise ConfigError(file, "sweep.params", f"unknown parameter(s) {unknown}{near}; sweepable: {sorted(spec.params)}")
    twice = sorted({p for p in params if list(params).count(p) > 1})
    if twice and not grid:
        raise ConfigError("PARAM", "", f"parameter(s) {twice} given more than once ({file})")
    if grid and (len(params) != 2 or params[0] == params[1]):
        raise ConfigError("--grid", "", f"a grid sweep takes two different parameters, got {params} ({file})")
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
                scenario.check_per_run(world)
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
        if name not in own:
            takes = f"its per-run keys: {', '.join(own)}" if own else f"the {scenario.kind} world takes none"
            raise ConfigError(file, where, f"'{key}' is not a per-run world key ({takes})")
        clash = [g for g, world in groups.items() if name in world]
        if clash and len(groups) > 1:
            raise ConfigError(file, where, f"'{key}' is also set by world group(s) {clash}, which would not differ in it: "
                              "sweep it in one group (--groups NAME), whose value it replaces, or in groups that do not set it")
    elif setting_at(settings, setting_path(key)) is MISSING:
        raise ConfigError(file, where, f"'{key}' is not a setting of variant '{variant}' (an observer field, or a path "
                          f"under observer., controller. or world.)")


Curves = dict[tuple[str, str, str], pd.DataFrame]


def curves_of(metrics: pd.DataFrame, metric: str, signals: list[str] | None) -> pd.DataFrame:
    """The rows of one metric (``signals``: some of its signals, default all), diverged runs' values NaN, with the
    ``gnss`` column naming the curve each run is on: its world group, or when several variants were swept side
    by side, the variant (``sweep_variant``) and, unless it is the only ``default`` one, the group (``eo``,
    ``npo/dgnss``)."""
    df = metrics[(metrics["metric"] == metric) & (metrics["signal"].isin(signals) if signals else True)].copy()
    df.loc[df["status"] != "ok", "value"] = np.nan
    if "sweep_variant" in df.columns:
        df["gnss"] = df["sweep_variant"].where(df["gnss"] == "default", df["sweep_variant"] + "/" + df["gnss"])
    return df


def curve_heading(metrics: pd.DataFrame, spec: SweepSpec | None) -> str:
    """The table column naming :func:`curves_of`'s curves: ``gnss`` (the world groups; ``group`` when the sweep has
    none named), or ``variant`` (``variant/gnss``) when several variants were swept side by side."""
    default = spec is not None and set(spec.groups) == {"default"}
    if "sweep_variant" in metrics.columns:
        return "variant" if default else "variant/gnss"
    return "group" if default else "gnss"


def own_runs(metrics: pd.DataFrame, spec: SweepSpec) -> pd.DataFrame:
    """The runs of ``sweep.variant`` (what the sweep's claims are about) when several variants were swept side by
    side; all runs otherwise."""
    if "sweep_variant" not in metrics.columns:
        return metrics
    return metrics[metrics["sweep_variant"] == spec.variant].drop(columns="sweep_variant")


def _per_seed_curves(metrics: pd.DataFrame, metric: str, signals: list[str] | None = None) -> Curves:
    """The KPI per (param, curve, signal), in sweep order: rows are the parameter values (sorted), columns
    the seeds; NaN where a run diverged. ``signals`` restricts the metric's signals (default: all); the curves
    are :func:`curves_of`'s."""
    df = curves_of(metrics, metric, signals)
    order = [{v: i for i, v in enumerate(dict.fromkeys(df[c]))} for c in ("param", "gnss", "signal")]
    groups = sorted(df.groupby(["param", "gnss", "signal"], sort=False), key=lambda kd: [o[k] for o, k in zip(order, kd[0])])
    return {key: d.pivot(index="param_value", columns="seed", values="value").sort_index() for key, d in groups}


def _at(curve: pd.DataFrame, value: float, log: bool) -> np.ndarray:
    """Each seed's KPI at ``value``, interpolated linearly in the value (in its log for log spacing)."""
    x = curve.index.to_numpy(dtype=float)
    x, v = (np.log(x), np.log(value)) if log else (x, value)
    return np.array([np.interp(v, x, curve[c].to_numpy(dtype=float)) for c in curve.columns])


def _fmt(m: float, lo: float, hi: float, pct: bool = False) -> str:
    """A mean with its interval; '–' where every run diverged."""
    if not np.isfinite(m):
        return "–"
    f = (lambda x: f"{100 * x:+.1f} %") if pct else (lambda x: f"{x:.4g}")
    return f(m) if not np.isfinite(lo) else f"{f(m)} [{f(lo)}, {f(hi)}]"


def sweep_table(metrics: pd.DataFrame, metric: str, spec: SweepSpec | None = None, model: str = "") -> str:
    """table.md: range of the seed-mean curve per parameter, group and signal; with ``spec``, the KPI at
    each parameter's probe values (and its change against the first probe, paired over seeds), the
    Spearman rank correlation over each parameter's ``trend`` range, and the ratio of each curve (world group, or
    variant swept side by side) to each earlier one.
    ``model``: the simulated vessel model (``Experiment.model_label``), named under the heading."""
    curves = _per_seed_curves(metrics, metric, spec.signals if spec else None)
    group = curve_heading(metrics, spec)
    if not curves:
        return f"## Sweep: {metric} vs each parameter\n\nNo values of metric '{metric}'.\n"
    n_seeds = max(c.shape[1] for c in curves.values())
    lines = [f"## Sweep: {metric} vs each parameter", "",
             (f"{n_seeds} runs per point (seeds 0..{n_seeds - 1}); curves are the mean over seeds, with 95 % "
              "Student-t intervals over seeds in brackets" if n_seeds > 1 else "One run per point (seed index 0)")
             + "; min/max are those of the curve." + simulated_on(model), "",
             f"| param | {group} | signal | points | min | at value | max | at value | diverged |",
             "|---|---|---|---|---|---|---|---|---|"]
    for (p, g, sig), c in curves.items():
        m, diverged = c.mean(axis=1), int(c.isna().to_numpy().sum())
        if m.isna().all():
            lines.append(f"| {p} | {g} | {sig} | {len(m)} | – | – | – | – | {diverged} |")
            continue
        lines.append(f"| {p} | {g} | {sig} | {len(m)} | {m.min():.4g} | {m.idxmin():.4g} | {m.max():.4g} | "
                     f"{m.idxmax():.4g} | {diverged} |")
    if spec is not None:
        lines += _probe_section(curves, spec, metric, group) + _trend_section(curves, spec, group) + _groups_section(curves, group, spec)
    return "\n".join(lines) + "\n"


def _probe_section(curves: Curves, spec: SweepSpec, metric: str, group: str) -> list[str]:
    """The KPI at each parameter's probe values, and its change against the first probe (paired over seeds)."""
    rows = []
    for (p, g, sig), c in curves.items():
        ps = spec.params.get(p)
        if ps is None or not ps.probes:
            continue
        log = ps.spacing == "log"
        first = _at(c, ps.probes[0], log)
        for v in ps.probes:
            at = _at(c, v, log)
            change = "–" if v == ps.probes[0] else _fmt(*mean_ci(at / first - 1), pct=True)
            rows.append(f"| {p} | {g} | {sig} | {v:g} | {_fmt(*mean_ci(at))} | {change} |")
    if not rows:
        return []
    return ["", f"### {metric} at the probe values", "",
            ("Interpolated between sweep points (in the log of the value for log spacing); the change is against "
             "the first probe, per seed, then averaged."), "",
            f"| param | {group} | signal | value | {metric} | change vs first probe |", "|---|---|---|---|---|---|", *rows]


def _trend_section(curves: Curves, spec: SweepSpec, group: str) -> list[str]:
    """Spearman's rank correlation of the mean curve with the value over each parameter's ``trend`` range."""
    rows = []
    for (p, g, sig), c in curves.items():
        ps = spec.params.get(p)
        if ps is None or ps.trend is None:
            continue
        x = c.index.to_numpy(dtype=float)
        inside = (x >= ps.trend[0]) & (x <= ps.trend[1])
        rho = spearmanr(x[inside], c.mean(axis=1).to_numpy()[inside]).statistic if inside.sum() > 2 else np.nan
        rho = f"{rho:+.2f}" if np.isfinite(rho) else "–"  # too few points, or every run diverged
        rows.append(f"| {p} | {g} | {sig} | [{ps.trend[0]:g}, {ps.trend[1]:g}] | {int(inside.sum())} | {rho} |")
    if not rows:
        return []
    return ["", "### Trends", "", ("Spearman rank correlation of the mean curve with the value over the range "
            "(+1: grows monotonically)."), "", f"| param | {group} | signal | range | points | Spearman ρ |",
            "|---|---|---|---|---|---|", *rows]


def _groups_section(curves: Curves, heading: str, spec: SweepSpec) -> list[str]:
    """Each curve's mean over each earlier curve's, point by point (when more than one world group, or variant, ran),
    and where the ratio crosses 1; ``heading``: :func:`curve_heading`."""
    groups = list(dict.fromkeys(g for _, g, _ in curves))
    if len(groups) < 2:
        return []
    against = f"`{groups[0]}`" if len(groups) == 2 else "each earlier one (in the order run)"
    lines = ["", f"### Between {'variants' if heading.startswith('variant') else 'groups'}", "",
             (f"Ratio of the mean curves, point by point, against {against}; it crosses 1 (the curves are equal) at "
              "the values listed, linear between points (in the log of the value for log spacing), or stays at 1 "
              "(to 1e-6) over the ranges listed."), "",
             "| param | signal | ratio | min | at value | max | at value | equal at |", "|---|---|---|---|---|---|---|---|"]
    for p, sig in dict.fromkeys((p, sig) for p, _, sig in curves):
        log = p in spec.params and spec.params[p].spacing == "log"
        for i, g in enumerate(groups):
            for ref in groups[:i]:
                if (p, g, sig) not in curves or (p, ref, sig) not in curves:
                    continue
                r = curves[p, g, sig].mean(axis=1) / curves[p, ref, sig].mean(axis=1)
                cells = ("– | – | – | – | –" if r.isna().all()  # every run of one group diverged
                         else f"{r.min():.3g} | {r.idxmin():.4g} | {r.max():.3g} | {r.idxmax():.4g} | {_equal_at(r, log)}")
                lines.append(f"| {p} | {sig} | {g} / {ref} | {cells} |")
    return lines


#: Relative distance from the level within which a point counts as on it: metrics.csv keeps 7 significant digits, so
#: two equal curves read back may differ by about 1e-7.
ON_LEVEL = 1e-6


def crossings(x: np.ndarray, y: np.ndarray, level: float = 1.0, log: bool = False) -> list[tuple[float, float]]:
    """Where the curve ``y(x)`` (x ascending) meets ``level``, as ``(from, to)``: a crossing between two neighbouring
    finite points on either side of it, linear between them (in ``log(x)`` with ``log``), is ``(x0, x0)``; a stretch of
    points on it (within :data:`ON_LEVEL`) is its first and last point."""
    ok = np.isfinite(y)
    x, d = x[ok], y[ok] - level
    d[np.abs(d) <= ON_LEVEL * abs(level)] = 0.0
    u = np.log(x) if log else x
    found = []
    for i in range(len(d)):
        if d[i] == 0:
            if i == 0 or d[i - 1] != 0:
                found.append((float(x[i]), float(x[i])))
            else:
                found[-1] = (found[-1][0], float(x[i]))
        elif i + 1 < len(d) and d[i] * d[i + 1] < 0:
            t = u[i] + (u[i + 1] - u[i]) * d[i] / (d[i] - d[i + 1])
            at = float(np.exp(t) if log else t)
            found.append((at, at))
    return found


def _equal_at(r: pd.Series, log: bool) -> str:
    """The table's *equal at* cell: where the ratio curve ``r`` meets 1 (:func:`crossings`), 'everywhere', or '–'."""
    x = r.index.to_numpy(dtype=float)
    found = crossings(x, r.to_numpy(dtype=float), log=log)
    if found == [(x[0], x[-1])] and np.isfinite(r.to_numpy(dtype=float)).all():
        return "everywhere"
    return ", ".join(f"{a:.4g}" if a == b else f"{a:.4g}–{b:.4g}" for a, b in found) or "–"


def sweep_claims(metrics: pd.DataFrame, spec: SweepSpec) -> list[ClaimResult]:
    """Check the sweep's claims on each group's curves of ``sweep.variant`` (a groups claim about two variants: on
    theirs, in each group); claims about a parameter, a group or a variant not swept this time are left out."""
    results, own = [], own_runs(metrics, spec)
    for claim in spec.claims:
        if claim.param not in set(metrics["param"]):
            continue
        metric = claim.metric or spec.shown[0]
        signals = [claim.signal] if claim.signal else spec.signals
        curves = {(g, sig): c for (p, g, sig), c in _per_seed_curves(own, metric, signals).items() if p == claim.param}
        log = spec.params[claim.param].spacing == "log"
        res = ClaimResult(claim, metric)
        if isinstance(claim, GroupsClaim) and claim.above not in spec.groups:  # two variants, in each group
            res.checks += _variants_checks(claim, metrics, metric, signals)
        elif isinstance(claim, GroupsClaim):
            for sig in dict.fromkeys(sig for _, sig in curves):
                if (claim.above, sig) in curves and (claim.below, sig) in curves:
                    res.checks.append(_groups_check(claim, curves[claim.above, sig], curves[claim.below, sig], sig))
        else:
            for (g, sig), c in curves.items():
                if claim.groups is None or g in claim.groups:
                    check = _probe_check if isinstance(claim, ProbeClaim) else _trend_check
                    res.checks.append(check(claim, c, log, g, sig))
        if res.checks:  # e.g. a groups claim when only one group was swept: not checked this time
            results.append(res)
    return results


def _variants_checks(claim: GroupsClaim, metrics: pd.DataFrame, metric: str, signals: list[str] | None) -> list[Check]:
    """A groups claim about two variants swept side by side: one check per world group and signal (none when either
    variant was not swept)."""
    curves = {(g, sig): c for (p, g, sig), c in _per_seed_curves(metrics, metric, signals).items() if p == claim.param}
    checks = []
    for g, sig in dict.fromkeys((g.partition("/")[2] or "default", sig) for g, sig in curves):
        a, b = ((name if g == "default" else f"{name}/{g}", sig) for name in (claim.above, claim.below))
        if a in curves and b in curves:
            checks.append(_groups_check(claim, curves[a], curves[b], sig, a[0], b[0]))
    return checks


def _probe_check(claim: ProbeClaim, c: pd.DataFrame, log: bool, group: str, sig: str) -> Check:
    at, vs = _at(c, claim.at, log), _at(c, claim.vs, log)
    ratio = float(np.nanmean(at) / np.nanmean(vs))
    ci = bootstrap_ci([at, vs], lambda x, y: np.nanmean(x) / np.nanmean(y), scale="log")
    means = {f"{claim.param}={claim.at:g}": float(np.nanmean(at)), f"{claim.param}={claim.vs:g}": float(np.nanmean(vs))}
    region = Region(-np.inf, claim.factor)
    return Check(group, sig, means, ratio, ci, f"< {claim.factor:g}", ratio in region, region)


def _trend_check(claim: TrendClaim, c: pd.DataFrame, log: bool, group: str, sig: str) -> Check:
    x = c.index.to_numpy(dtype=float)
    inside = (x >= claim.range[0]) & (x <= claim.range[1])

    def rho(per_seed: np.ndarray) -> float:  # rows: seeds, columns: the points inside the range
        return float(spearmanr(x[inside], np.nanmean(per_seed, axis=0)).statistic) if inside.sum() > 2 else np.nan

    values = c.to_numpy(dtype=float).T[:, inside]
    r = rho(values)
    sign = -1.0 if claim.decreasing else 1.0
    means = {f"{claim.param}={v:g}": float(np.nanmean(_at(c, v, log))) for v in claim.range}
    needs = f"{'<' if claim.decreasing else '>'} {sign * claim.min_rho:+g} (Spearman ρ)"
    region = Region(-np.inf, -claim.min_rho) if claim.decreasing else Region(claim.min_rho, np.inf)
    ci = bootstrap_ci([values], rho, bounds=(-1.0, 1.0))
    return Check(group, sig, means, r, ci, needs, r in region, region)


def _groups_check(claim: GroupsClaim, above: pd.DataFrame, below: pd.DataFrame, sig: str, above_name: str | None = None,
                  below_name: str | None = None) -> Check:
    """``above``'s curve over ``below``'s at its lowest (named by the claim's groups, or the curves' names)."""
    above_name, below_name = above_name or claim.above, below_name or claim.below
    seeds = above.columns.intersection(below.columns)
    a, b = above[seeds].to_numpy(dtype=float).T, below[seeds].to_numpy(dtype=float).T  # rows: seeds

    def curve(x: np.ndarray, y: np.ndarray) -> np.ndarray:  # the ratio of the mean curves, point by point
        return np.nanmean(x, axis=0) / np.nanmean(y, axis=0)

    def lowest(x: np.ndarray, y: np.ndarray) -> float:  # nan (the check fails) where every run diverged
        r = curve(x, y)
        return float(np.nanmin(r)) if not np.isnan(r).all() else np.nan

    ratios = curve(a, b)
    i = int(np.nanargmin(ratios)) if not np.isnan(ratios).all() else 0
    ratio, at = float(ratios[i]), float(above.index[i])
    means = {f"{above_name} at {claim.param}={at:.3g}": float(above.loc[at].mean()), below_name: float(below.loc[at].mean())}
    region = Region(1 / claim.factor, np.inf)
    return Check(f"{above_name} / {below_name}", sig, means, ratio, bootstrap_ci([a, b], lowest, scale="log"),
                 f"> {region.lo:.3g} at every value", ratio in region, region)


def sweep_figure(metrics: pd.DataFrame, shown: list[str], exp: Experiment, path: Path) -> None:
    """Fig. 3 layout: one panel per parameter (and a column per metric of ``shown``, and per signal when several
    curves share each), the KPI against the value, one curve per curve of :func:`curves_of` (group or variant; and
    signal, when there are several and one curve each): the mean over seeds, with the seeds' range shaded when
    there are several, and a dotted line at ``sweep.variant``'s own value (Table I's k = 0.7, δ = 2.5 s and c_ε = 5)."""
    per_metric = {metric: _per_seed_curves(metrics, metric, exp.sweep.signals) for metric in shown}
    params = list(dict.fromkeys(p for curves in per_metric.values() for p, _, _ in curves))
    columns = []  # (metric, its curves in the panel, the signals they show)
    for metric, curves in per_metric.items():
        signals = list(dict.fromkeys(sig for _, _, sig in curves))  # in the metrics' order (u, v, sigma_u, ...)
        if len({g for _, g, _ in curves}) > 1 and len(signals) > 1:  # several curves a signal: a column each
            columns += [(metric, {k: c for k, c in curves.items() if k[2] == sig}, [sig]) for sig in signals]
        else:
            columns.append((metric, curves, signals))
    own = {p: tuning(exp, p) for p in params}  # the swept variant's own value of each, or None
    rows, cols = max(1, len(params)), len(columns)
    fig, axes = plt.subplots(rows, cols, figsize=(7 if cols == 1 else 5 * cols, 2.6 * rows), squeeze=False)
    for col, (metric, curves, signals) in enumerate(columns):
        n_groups, n_signals = len({g for _, g, _ in curves}), len(signals)
        # one signal: name it on the axis (the table's "e_v"); the J_tot state "z" needs no name
        ylabel = metric if n_signals > 1 or signals == ["z"] else f"{metric} (e_{signals[0]})"
        for ax, p in zip(axes[:, col], params):
            for (q, g, sig), c in curves.items():
                if q != p:
                    continue
                x = c.index.to_numpy(dtype=float)
                label = g if n_signals == 1 else sig if n_groups == 1 else f"{g}, {sig}"
                (line,) = ax.plot(x, c.mean(axis=1), ".-", ms=3, lw=1, label=label)
                if c.shape[1] > 1:
                    ax.fill_between(x, c.min(axis=1), c.max(axis=1), color=line.get_color(), alpha=0.2, lw=0)
            _dress(ax, exp, p, ylabel, own[p], legend=n_groups * n_signals > 1)  # a lone curve needs no legend
    n_seeds = max((c.shape[1] for curves in per_metric.values() for c in curves.values()), default=1)
    seeds = f", mean of {n_seeds} seeds (band: their range)" if n_seeds > 1 else ""
    dotted = f"; dotted: {exp.sweep.variant}'s own value" if any(v is not None for v in own.values()) else ""
    save(fig, f"{exp.name}: {', '.join(shown)} sensitivity\n(one parameter at a time{seeds}{dotted}; model {exp.model_label()})",
         path)


def _dress(ax, exp: Experiment, param: str, ylabel: str, own: float | None, legend: bool) -> None:
    """A sweep panel's axes: the parameter's scale and label, a dotted line at the swept variant's ``own`` value."""
    if own is not None:
        ax.axvline(own, color="0.4", ls=":", lw=1)
    if exp.sweep.params[param].spacing == "log":
        ax.set_xscale("log")
        plain_log_labels(ax.xaxis)
    ax.set_xlabel(exp.sweep.params[param].label or param)
    ax.set_ylabel(ylabel)
    if legend:
        ax.legend(fontsize=8)
    ax.grid(alpha=0.3)


def run_chunk(exp: Experiment, variants: list[Variant], progress=None) -> tuple[str, float]:
    """Simulate one chunk of a sweep (in this process or on a Dask worker): its tidy metrics as CSV text
    (full precision) and its simulation wall time."""
    from marinebench.experiments.runner import run

    result = run(exp.model_copy(update={"variants": variants}), progress=progress, traces=False)
    return result.metrics.to_csv(index=False, float_format="%.17g"), result.wall_time


def chunks_of(exp: Experiment, chunk_size: int) -> list[list]:
    """The sweep's variants in the chunks :func:`run_chunked` runs: at most ``chunk_size`` runs each (runs =
    variants x seeds), whole variants, at least one variant."""
    per_chunk = max(1, chunk_size // exp.seeds)
    return [exp.variants[i : i + per_chunk] for i in range(0, len(exp.variants), per_chunk)]


def run_chunked(exp: Experiment, target: Path, chunk_size: int, progress=None, on_start=None,
                pool=None) -> tuple[pd.DataFrame, float, int]:
    """Run the sweep's runs in chunks, saving each chunk's metrics in ``.<target>.partial/``.

    An interrupted sweep resumes: chunks already on disk for the same inputs (``provenance.inputs_key``: the
    resolved config, marinebench's source files, package versions, custom classes' files) are loaded, not
    rerun (one that cannot be read back runs again). Runs are independent of the batch they are in (per-run
    seeding), so chunking does not change any number. With a ``pool`` (``experiments.cluster``: local worker processes or Dask) the unfinished chunks
    are submitted at once and each is saved here as it arrives, so the numbers are the same as in one
    process and an interrupted parallel sweep resumes the same way.
    Returns (metrics in chunk order, simulation wall time summed over the chunks run, chunks run).
    """
    import shutil

    from marinebench.experiments.cluster import ChunkFailed
    from marinebench.experiments.runner import steps
    from marinebench.provenance import inputs_key
    from marinebench.results.writer import atomic_write_text

    key = inputs_key(exp)
    partial = partial_dir(target)
    check_partial(target)
    if partial.exists() and _kept_key(partial) != key:
        shutil.rmtree(partial)  # a different sweep, or other code, was interrupted here: start afresh
    partial.mkdir(parents=True, exist_ok=True)
    atomic_write_text(partial / "key", key)
    chunks = chunks_of(exp, chunk_size)
    paths = [partial / CHUNK_FILE.format(c) for c in range(len(chunks))]
    n_steps = steps(exp)
    if on_start is not None:
        on_start(n_steps * len(chunks))
    kept = {c: frame for c, path in enumerate(paths) if (frame := _kept_chunk(path, chunks[c])) is not None}
    pending = [c for c in range(len(chunks)) if c not in kept]
    if progress is not None:
        progress(n_steps * (len(chunks) - len(pending)))
    if pool is None:
        finished = ((c, run_chunk(exp, chunks[c], progress)) for c in pending)
    else:
        finished = pool.results(run_chunk, {c: (exp, chunks[c]) for c in pending}, progress, n_steps, key[:12])
    wall = 0.0
    try:
        for c, (csv, w) in finished:
            atomic_write_text(paths[c], csv)
            wall += w
    except ChunkFailed as exc:
        raise ClusterError(f"{pool.option}: chunk {exc.chunk} failed on a worker ({type(exc.cause).__name__}: "
                           f"{exc.cause}); the finished chunks are kept in {partial}, rerun the same command to "
                           "resume") from None
    frames = [kept[c] if c in kept else read_tidy(path) for c, path in enumerate(paths)]  # kept ones: read once
    return pd.concat(frames, ignore_index=True), wall, len(pending)


CHUNK_FILE = "chunk-{:04d}.csv"  # a finished chunk's metrics in partial_dir(target)


def _kept_key(partial: Path) -> str | None:
    """The inputs key the kept chunks of ``partial`` were run for (None when it cannot be read)."""
    try:
        return (partial / "key").read_text(encoding="utf-8").strip()
    except (OSError, UnicodeDecodeError):
        return None


def _kept_chunk(path: Path, variants: list[Variant]) -> pd.DataFrame | None:
    """The finished chunk of ``variants`` that ``path`` holds: readable, with a row of each (None without one). One
    that is not (a file damaged or edited since) is removed, and the chunk runs again; before, it counted as
    finished and the sweep failed with a traceback after simulating every other chunk."""
    from marinebench.results.stored import METRICS_COLUMNS, StoredResultError, read_columns

    if not path.exists():
        return None
    try:
        frame = read_columns(path, METRICS_COLUMNS, ("seed", "value"))
    except StoredResultError:
        frame = None
    if frame is not None and set(frame["variant"]) == {v.name for v in variants}:
        return frame
    path.unlink()
    return None


def partial_dir(target: Path) -> Path:
    """Where :func:`run_chunked` keeps the finished chunks of the sweep that writes ``target``."""
    return target.parent / f".{target.name}.partial"


def check_partial(target: Path) -> None:
    """Refuse (a :class:`ConfigError` naming it) a :func:`partial_dir` that is not the kept chunks of a sweep, which
    :func:`run_chunked` would remove or write into: a file or symbolic link there, or a folder with other files
    than ``key``, ``chunk-*.csv`` and their temporary files. Before, a file there was a traceback."""
    partial = partial_dir(target)
    if partial.is_symlink() or (partial.exists() and not partial.is_dir()):
        raise ConfigError(str(partial), "", "a file or symbolic link where a sweep keeps its finished batches: not "
                          "replaced (move it, or choose another --out)")
    ours = re.compile(r"\.?(key|chunk-\d{4}\.csv)(\..+)?")  # atomic_write_text's temporary: .<name>.<random>
    if partial.is_dir() and (other := sorted(p.name for p in partial.iterdir() if not ours.fullmatch(p.name))):
        named = ", ".join(other[:3]) + (", ..." if len(other) > 3 else "")
        raise ConfigError(str(partial), "", f"a folder of other files ({named}) where a sweep keeps its finished "
                          "batches: not replaced (move it, or choose another --out)")


def finished_chunks(target: Path) -> int:
    """How many chunks of the sweep that writes ``target`` are finished and kept (an interrupted sweep)."""
    return len(list(partial_dir(target).glob(CHUNK_FILE.replace("{:04d}", "*"))))


def discard_partial(target: Path) -> None:
    import shutil

    shutil.rmtree(partial_dir(target), ignore_errors=True)
