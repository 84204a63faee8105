"""Two-parameter grid sweeps (``marinebench sweep P1 P2 --grid``): how two tunings interact.

A one-at-a-time sweep (Torben et al. Fig. 3) moves each parameter with the others at the paper's values;
the grid runs every combination of two (``sweep_experiment(..., grid=True)``: runs tagged ``param``,
``param_value``, ``param2``, ``param2_value``, ``gnss``), in one batch like any sweep. Here: its
``table.md`` (the seed-mean KPI as a matrix per world group and signal, with its lowest point and the
KPI's spread along each axis), its figure (one heat map per metric and group, the lowest point
starred and the swept variant's own tuning marked) and its ``claims.md``: each one-at-a-time claim of
``sweep.claims`` about one of the two parameters, checked along that parameter on every slice of the other
(:func:`grid_claims`), which maps where in the other tuning the paper's statement holds. These are maps,
not verdicts: the paper states its claims at its own tuning of the other parameter.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.colors import LogNorm

from marinebench.claims import SweepClaim
from marinebench.config import Experiment, SweepSpec
from marinebench.experiments.curves import curve_heading, curves_of, sweep_claims
from marinebench.experiments.settings import tuning
from marinebench.plotting.figures import plain_log_labels, save
from marinebench.results.claims import NARROW_NOTE, Check, format_check, on_seeds, statistic_note
from marinebench.results.tables import md_row, simulated_on

Surfaces = dict[tuple[str, str], pd.DataFrame]


def grid_surfaces(metrics: pd.DataFrame, metric: str, signals: list[str] | None = None) -> Surfaces:
    """The seed-mean KPI per (curve, signal) (``sweep.curves_of``: the world group, or the variant): rows
    ``param_value``, columns ``param2_value`` (sorted); NaN where every seed of a point diverged (diverged runs are
    left out of the mean)."""
    df = curves_of(metrics, metric, signals)
    order = [{v: i for i, v in enumerate(dict.fromkeys(df[c]))} for c in ("gnss", "signal")]
    groups = sorted(df.groupby(["gnss", "signal"], sort=False), key=lambda kd: [o[k] for o, k in zip(order, kd[0])])
    return {key: d.pivot_table(index="param_value", columns="param2_value", values="value", aggfunc="mean", dropna=False)
            .sort_index().sort_index(axis=1) for key, d in groups}


def _axes(metrics: pd.DataFrame) -> tuple[str, str]:
    return str(metrics["param"].iloc[0]), str(metrics["param2"].iloc[0])


def _edges(centres: np.ndarray, log: bool) -> np.ndarray:
    """Cell edges around the grid values: midpoints (geometric for log spacing) and as far again at the ends."""
    x = np.log(centres) if log else centres
    mid = (x[1:] + x[:-1]) / 2
    edges = np.concatenate([[2 * x[0] - mid[0]], mid, [2 * x[-1] - mid[-1]]]) if len(x) > 1 else np.array([x[0] - 1, x[0] + 1])
    return np.exp(edges) if log else edges


def grid_table(metrics: pd.DataFrame, metric: str, spec: SweepSpec, model: str = "") -> str:
    """table.md of a grid sweep: per group and signal the matrix of the seed-mean ``metric``, its lowest point,
    and how much each parameter moves it (the largest ratio max/min along a row or column)."""
    p1, p2 = _axes(metrics)
    surfaces = grid_surfaces(metrics, metric, spec.signals)
    n_seeds = int(metrics["seed"].nunique())
    lines = [f"## Grid: {metric} over {p1} × {p2}", "",
             (f"Mean over {n_seeds} seeds" if n_seeds > 1 else "One run per point (seed index 0)")
             + f"; rows {p1}, columns {p2}. Diverged runs are left out of the mean (– where all diverged)."
             + simulated_on(model), ""]
    if not surfaces:
        return "\n".join([*lines, f"No values of metric '{metric}'.", ""])
    group = curve_heading(metrics, spec)
    summary = [f"| {group} | signal | lowest | at {p1} | at {p2} | highest | spread along {p1} | spread along {p2} |",
               "|---|---|---|---|---|---|---|---|"]
    blocks = []
    for (g, sig), m in surfaces.items():
        values = m.to_numpy(dtype=float)
        if np.isnan(values).all():
            summary.append(f"| {g} | {sig} | – | – | – | – | – | – |")
            continue
        i, j = np.unravel_index(np.nanargmin(values), values.shape)
        if np.nanmax(values) == np.nanmin(values):
            summary.append(f"| {g} | {sig} | {values[i, j]:.4g} | (flat) | (flat) | {values[i, j]:.4g} | 1× | 1× |")
            continue
        along_p1 = np.nanmax(np.nanmax(values, axis=0) / np.nanmin(values, axis=0))  # down a column: p1 moves
        along_p2 = np.nanmax(np.nanmax(values, axis=1) / np.nanmin(values, axis=1))
        summary.append(f"| {g} | {sig} | {values[i, j]:.4g} | {m.index[i]:.4g} | {m.columns[j]:.4g} | "
                       f"{np.nanmax(values):.4g} | {along_p1:.3g}× | {along_p2:.3g}× |")
        head = f"| {p1} \\ {p2} | " + " | ".join(f"{c:.3g}" for c in m.columns) + " |"
        rows = [f"| {r:.3g} | " + " | ".join("–" if np.isnan(x) else f"{x:.4g}" for x in row) + " |"
                for r, row in zip(m.index, values)]
        blocks += ["", f"### {metric}, {group} {g}, signal {sig}", "", head, "|---" * (len(m.columns) + 1) + "|", *rows]
    notes = ["", (f"Spread along a parameter: the largest ratio of the highest to the lowest {metric} as that "
                  "parameter moves with the other held.")]
    return "\n".join([*lines, *summary, *notes, *blocks]) + "\n"


def grid_figure(metrics: pd.DataFrame, shown: list[str], exp: Experiment, path: Path) -> None:
    """One heat map per metric (rows; a row per variant too, when several were swept) and group and signal
    (columns): the seed-mean KPI over the grid on a log colour scale, its lowest point starred, the swept variant's
    own tuning (each variant's) marked ×."""
    p1, p2 = _axes(metrics)
    several = "sweep_variant" in metrics.columns  # then a surface's curve is named after its variant first
    rows = []  # (metric, the surfaces side by side)
    for metric in shown:
        surfaces = grid_surfaces(metrics, metric, exp.sweep.signals)
        for variant in dict.fromkeys(g.split("/")[0] for g, _ in surfaces) if several else [None]:
            rows.append((metric, {k: m for k, m in surfaces.items() if variant is None or k[0].split("/")[0] == variant}))
    cols = max(len(s) for _, s in rows)
    fig, axes = plt.subplots(len(rows), cols, figsize=(4.6 * cols, 3.8 * len(rows)), squeeze=False)
    own = {v: (tuning(exp, p1, v), tuning(exp, p2, v)) for v in exp.sweep.swept}
    for row, (metric, surfaces) in enumerate(rows):
        for ax in axes[row, len(surfaces):]:
            ax.axis("off")
        for ax, ((g, sig), m) in zip(axes[row], surfaces.items()):
            values = m.to_numpy(dtype=float)
            positive = values[np.isfinite(values) & (values > 0)]
            norm = LogNorm(positive.min(), positive.max()) if positive.size and positive.min() < positive.max() else None
            # x: the second parameter, y: the first, as in the table (rows p1, columns p2)
            log = [exp.sweep.params[p].spacing == "log" for p in (p2, p1)]
            mesh = ax.pcolormesh(_edges(m.columns.to_numpy(dtype=float), log[0]), _edges(m.index.to_numpy(dtype=float), log[1]),
                                 values, cmap="viridis", norm=norm)
            bar = fig.colorbar(mesh, ax=ax, label=metric)
            plain_log_labels(bar.ax.yaxis)
            variant = g.split("/")[0] if several else exp.sweep.variant
            _mark(ax, m, variant, own[variant])
            for axis, p in (("x", p2), ("y", p1)):
                if exp.sweep.params[p].spacing == "log":
                    getattr(ax, f"set_{axis}scale")("log")
                    plain_log_labels(getattr(ax, f"{axis}axis"))
                getattr(ax, f"set_{axis}label")(exp.sweep.params[p].label or p)
            ax.set_title(f"{metric}: {g}" + (f", {sig}" if sig != "z" else ""), fontsize=9)
    n_seeds = int(metrics["seed"].nunique())
    save(fig, f"{exp.name}: {', '.join(shown)} over {p1} × {p2}" + (f" (mean of {n_seeds} seeds)" if n_seeds > 1 else "")
         + f"\nmodel {exp.model_label()}", path)


def _mark(ax, m: pd.DataFrame, variant: str, own: tuple) -> None:
    """A heat map's marks: its lowest point starred (none on a flat surface), ``variant``'s own tuning ``own`` (p1, p2)
    crossed (none for a parameter without one); a surface without a value says 'every run diverged' instead."""
    values = m.to_numpy(dtype=float)
    if not np.isfinite(values).any():
        ax.text(0.5, 0.5, "every run diverged", transform=ax.transAxes, ha="center", va="center")
        return
    if np.nanmax(values) > np.nanmin(values):
        i, j = np.unravel_index(np.nanargmin(values), values.shape)
        ax.plot(m.columns[j], m.index[i], "*", color="white", mec="black", ms=12, label=f"lowest {values[i, j]:.3g}")
    if None not in own:
        y, x = own
        ax.plot(x, y, "x", color="red", ms=9, mew=2, label=f"{variant} ({y:g}, {x:g})")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7, loc="best")


@dataclass
class GridClaim:
    """One claim of ``sweep.claims`` checked along its parameter on each slice of the grid's other parameter."""

    claim: SweepClaim
    metric: str
    other: str
    slices: dict[float, list[Check]] = field(default_factory=dict)

    def holds_at(self, value: float) -> bool:
        return bool(self.slices[value]) and all(c.holds for c in self.slices[value])

    @property
    def holding(self) -> list[float]:
        return [v for v in self.slices if self.holds_at(v)]

    @property
    def failing(self) -> list[float]:
        return [v for v in self.slices if not self.holds_at(v)]


_SWAP = {"param": "param2", "param2": "param", "param_value": "param2_value", "param2_value": "param_value"}


def grid_claims(metrics: pd.DataFrame, spec: SweepSpec) -> list[GridClaim]:
    """Each claim about one of the grid's parameters, checked as in a one-at-a-time sweep
    (:func:`~marinebench.experiments.curves.sweep_claims`) on every slice of the other parameter, in its order."""
    p1, p2 = _axes(metrics)
    out = []
    for claim in spec.claims:
        if claim.param not in (p1, p2):
            continue
        along = metrics if claim.param == p1 else metrics.rename(columns=_SWAP)  # param: the claim's; param2: the slice
        res = GridClaim(claim, claim.metric or spec.shown[0], p2 if claim.param == p1 else p1)
        for value, part in along.groupby("param2_value", sort=True):
            checked = sweep_claims(part, spec.model_copy(update={"claims": [claim]}))
            res.slices[float(value)] = checked[0].checks if checked else []
        if any(res.slices.values()):  # e.g. a groups claim when only one group was swept: not checked
            out.append(res)
    return out


def _values(param: str, values: list[float]) -> str:
    return f"{param} ∈ {{{', '.join(f'{v:.3g}' for v in values)}}}" if values else "–"


def grid_claims_markdown(exp: Experiment, results: list[GridClaim], own: dict[str, float | None]) -> str:
    """``claims.md`` of a grid sweep: per claim the slices of the other parameter where it holds and where it
    fails, then every check. ``own``: the swept variant's own value of each parameter (marked), or None."""
    lines = [f"## Claims along the grid: sweep of {exp.name}", "",
             (f"Each claim of the sweep about one of the two parameters, checked as in a one-at-a-time sweep on "
              f"{on_seeds(exp.seeds)} (root seed {exp.seed}) along its parameter, on every slice of the other. The "
              "paper states each claim at its own tuning of the other parameter, so this maps where the statement holds; "
              "it is not a verdict. " + statistic_note(exp.seeds) + simulated_on(exp.model_label())
              + (f" {NARROW_NOTE}" if any(c.firm is False for r in results for cs in r.slices.values() for c in cs) else "")),
             "",
             "| # | claim | source | metric | along | holds at | fails at |", "|---|---|---|---|---|---|---|"]
    for i, r in enumerate(results, 1):
        mark = next((v for v in r.slices if own.get(r.other) is not None and np.isclose(v, own[r.other])), None)
        note = f" (config's {r.other} = {mark:.3g}: {'holds' if r.holds_at(mark) else 'fails'})" if mark is not None else ""
        lines.append(md_row([i, f"{r.claim.text}{note}", r.claim.source, r.metric, r.claim.param,
                             _values(r.other, r.holding), _values(r.other, r.failing)]))
    lines += ["", "| # | slice, group | signal | means | statistic [95% CI] | needs | check |", "|---|---|---|---|---|---|---|"]
    for i, r in enumerate(results, 1):
        for value, checks in r.slices.items():
            lines += [format_check(i, c, f"{r.other} = {value:.3g}, {c.where}") for c in checks]
    return "\n".join(lines) + "\n"


def grid_manifest_entries(results: list[GridClaim]) -> list[dict]:
    return [{"text": r.claim.text, "source": r.claim.source, "along": r.claim.param, "slices_of": r.other,
             "holds_at": r.holding, "fails_at": r.failing} for r in results]
