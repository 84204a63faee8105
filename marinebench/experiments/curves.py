"""One-at-a-time sweeps' results (Torben et al. Fig. 3): the curves, their ``table.md``, ``claims.md`` and figure.

A sweep's ``metrics.csv`` (:mod:`marinebench.experiments.sweep` designs its runs) holds one KPI per run, tagged
``param``, ``param_value`` and ``gnss``; here the runs of each parameter become curves, one per world group
(or per variant, when several were swept side by side; :func:`curves_of`), with the seeds' spread. From them:
:func:`sweep_table` (each curve's range, the KPI at the claims' probe values with its paired change, the
Spearman trend, the ratio of two curves and where they cross), :func:`sweep_claims` (the checks of
``sweep.claims``) and :func:`sweep_figure` (Fig. 3's layout). ``experiments/grid.py`` does the same for a
two-parameter grid, on these curves.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from marinebench.claims import GroupsClaim, ProbeClaim, TrendClaim
from marinebench.config import Experiment, SweepSpec
from marinebench.experiments.settings import tuning
from marinebench.metrics.stats import mean_ci, spearman_rows
from marinebench.plotting.figures import plain_log_labels, save
from marinebench.results.claims import Check, ClaimResult, Region, bootstrap_ci
from marinebench.results.tables import simulated_on

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
        rho = spearman_rows(x[inside], c.mean(axis=1).to_numpy()[None, inside])[0] if inside.sum() > 2 else np.nan
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
    ci = bootstrap_ci([at, vs], lambda x, y: np.nanmean(x, axis=1) / np.nanmean(y, axis=1), scale="log")
    means = {f"{claim.param}={claim.at:g}": float(np.nanmean(at)), f"{claim.param}={claim.vs:g}": float(np.nanmean(vs))}
    region = Region(-np.inf, claim.factor)
    return Check(group, sig, means, ratio, ci, f"< {claim.factor:g}", ratio in region, region)


def _trend_check(claim: TrendClaim, c: pd.DataFrame, log: bool, group: str, sig: str) -> Check:
    x = c.index.to_numpy(dtype=float)
    inside = (x >= claim.range[0]) & (x <= claim.range[1])

    def rho(per_seed: np.ndarray) -> np.ndarray:  # (resamples, seeds, the points inside the range) -> (resamples,)
        curves = np.nanmean(per_seed, axis=1)
        return spearman_rows(x[inside], curves) if inside.sum() > 2 else np.full(len(curves), np.nan)

    values = c.to_numpy(dtype=float).T[:, inside]
    r = float(rho(values[None])[0])
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
        return np.nanmean(x, axis=-2) / np.nanmean(y, axis=-2)

    def lowest(x: np.ndarray, y: np.ndarray) -> np.ndarray:  # per resample; nan (the check fails) where every run diverged
        return np.nanmin(curve(x, y), axis=1)

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
