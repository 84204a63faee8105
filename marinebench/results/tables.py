"""Markdown tables in the paper's layout: ours (mean and 95% CI over seeds) beside the paper's values."""

from __future__ import annotations

import math
import re

import pandas as pd

from marinebench.config import Experiment

LABELS = {"u": "e_u", "v": "e_v", "r": "e_r", "sigma_u": "e_sigma_u", "sigma_v": "e_sigma_v", "sigma_r": "e_sigma_r"}


def _window(exp: Experiment, name: str) -> str:
    m = next((m for m in exp.metrics if m.label == name), None)
    if m is None:
        return f"{name}: observer diagnostic"
    if m.kind == "j_tot":
        a, b = m.window(exp.scenario.horizon)
        return f"{name}: ∫‖z_bis − ẑ_bis‖dt over t ∈ [{a:g}, {b:g}) s"
    if m.kind == "int":
        return f"{name}: ∫τ²dt from the first time the tracking error is within {_per_signal(m.tol)}"
    if m.kind == "recovery":
        what = "the same run without the pushes" if m.against == "undisturbed" else "the reference"
        return f"{name}: largest time after a push until the vehicle stays within {_per_signal(m.tol)} of {what} [s]"
    return f"{name}: {m.kind} of {_error_text(exp)} over t ∈ [{m.t_start:g}, {m.t_end or exp.scenario.horizon:g}] s"


def _study_window(parts: dict[str, Experiment], name: str) -> str:
    """:func:`_window` over a multi-scenario experiment's ``parts`` (scenario -> :meth:`Experiment.part`): one text
    when the scenarios agree, else each text followed by the scenarios it holds in (a metric over the whole
    horizon where the horizons differ)."""
    where: dict[str, list[str]] = {}
    for scen, part in parts.items():
        where.setdefault(_window(part, name), []).append(scen)
    if len(where) == 1:
        return next(iter(where))
    return "; ".join(f"{text} in {', '.join(scens)}" for text, scens in where.items())


def _per_signal(value) -> str:
    """A tolerance given per signal ({'depth': 0.01, 'yaw': 0.0175}) as '0.01 (depth), 0.0175 (yaw)'."""
    if isinstance(value, dict):
        return ", ".join(f"{v:g} ({k})" for k, v in value.items())
    return f"{value:g}"


def _error_text(exp: Experiment) -> str:
    """What an error metric's ``est − truth`` is: a closed-loop variant observed through no observer is scored on
    its tracking error (its 'estimate' is the reference, rov_scenario's ``estimates``)."""
    tracking = [v.observer is None for v in exp.variants]
    if all(tracking):
        return "the tracking error (reference − actual)"
    if any(tracking):
        return "est − truth (for controllers without an observer: reference − actual)"
    return "est − truth"


def settings_text(settings) -> str:
    """``key=value, ...`` of an observer or controller, leaving out unset (None) and empty settings and those another
    kind reads (a model's ``ONLY_FOR``: RISE's ``preset`` is not shown for S+RISE or a custom controller)."""
    only_for = getattr(type(settings), "ONLY_FOR", {})
    return ", ".join(f"{k}={val}" for k, val in settings.model_dump().items()
                     if val is not None and val != {} and settings.kind in only_for.get(k, (settings.kind,)))


def variant_text(v) -> str:
    """A variant's settings as the list under a table gives them: its controller's, its observer's, and the world
    settings it runs with (``world: sensors.hold=measurement``), if any."""
    parts = [settings_text(t) for t in (v.controller, v.observer) if t is not None]
    if v.world:
        parts.append("world: " + ", ".join(f"{k}={val}" for k, val in v.world.items()))
    return "; ".join(parts)


def md_cell(text: object) -> str:
    """``text`` as one cell of a markdown pipe table: a ``|`` in it (a label "RISE | old", a claim about |e_u|) escaped
    as ``\\|``, so that it does not split the row; a line break as a space."""
    return str(text).replace("|", "\\|").replace("\n", " ")


def md_row(cells: list) -> str:
    """One row of a markdown pipe table, every cell through :func:`md_cell`."""
    return "| " + " | ".join(md_cell(c) for c in cells) + " |"


def md_split(line: str) -> list[str]:
    """The cells of a row :func:`md_row` wrote, unescaped (``report`` reads table.md and claims.md back)."""
    return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", line.strip().strip("|"))]


def fmt(x: float) -> str:
    return "–" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.3g}"


def _cell(r) -> str:
    cell = fmt(r["mean"])
    if not math.isnan(r["ci_low"]):
        cell += f" [{fmt(r['ci_low'])}, {fmt(r['ci_high'])}]"
    if r["n_diverged"]:
        cell += f" ({int(r['n_diverged'])} diverged)"
    return cell


def _shown(r: pd.Series, display) -> pd.Series:
    """A summary row in the table's display unit (``table.display``: value x scale)."""
    if display is None:
        return r
    r = r.copy()
    r[["mean", "ci_low", "ci_high"]] = r[["mean", "ci_low", "ci_high"]] * display.scale
    return r


def simulated_on(model: str) -> str:
    """The sentence naming the simulated vessel model (``Experiment.model_label``) in a table or claims file:
    every output says which model its numbers come from (Tijjani's are on the assumed ``leonard_like``)."""
    return f" Simulated on the model `{model}`." if model else ""


def _preamble(exp: Experiment, windows: str, where: str, paper) -> list[str]:
    """The lines under a table's title: what 'ours' is (the metrics' windows, seeds, CI) and, when the table
    carries the paper's values, that those columns are copied, not computed."""
    over = (f"Mean over {exp.seeds} seeds with the 95% Student-t interval in brackets" if exp.seeds > 1
            else "One seed, so no interval")
    lines = [f"Ours: {windows}. {over}; {where}." + simulated_on(exp.model_label())]
    if paper is not None:
        units = paper.units
        lines.append(f"Columns marked *paper* are published values from {paper.source}, copied for comparison, "
                     "not computed" + (" (paper units: " + "; ".join(f"{k}: {u}" for k, u in units.items()) + ")"
                                       if units else "") + ".")
    return lines


def _grid(header: list[str]) -> list[str]:
    return ["", md_row(header), "|" + "---|" * len(header)]


def study_table(exp: Experiment, summary: pd.DataFrame) -> str:
    """Multi-scenario layout (Tijjani Table III): a row per (metric, signal, scenario), a column per variant,
    each followed by the paper's value when given."""
    spec = exp.table
    names = spec.shown if spec is not None else [m.label for m in exp.metrics]
    signals = spec.signals if spec is not None else ["depth", "yaw"]
    paper = spec.paper if spec is not None else None
    display = spec.display if spec is not None else {}
    s = summary.set_index(["scenario", "variant", "signal", "metric"])
    header = ["index", "scenario"]
    for v in exp.variants:
        header += [f"{v.label or v.name} ours"] + ([f"{v.label or v.name} paper"] if paper is not None else [])
    parts = {scen: exp.part(scen) for scen in exp.scenario_names}
    windows = "; ".join(_study_window(parts, n) for n in names)
    lines = [f"## {spec.title if spec else exp.name}", ""]
    lines += _preamble(exp, windows, f"root seed {exp.seed}; '–' where a variant does not run on a scenario", paper)
    lines += _grid(header)
    for name in names:
        for sig in signals:
            d = display.get(f"{name}/{sig}")
            label = f"{name} {sig}" + (f" [{d.unit}]" if d and d.unit else "")
            for scen in exp.scenario_names:
                if not any((scen, v.name, sig, name) in s.index for v in exp.variants) and not any(
                        f"{scen}/{name}/{sig}" in vals for vals in (paper.values.values() if paper else [])):
                    continue  # the metric does not apply to this scenario (e.g. recovery without pushes)
                row = [label, scen]
                for v in exp.variants:
                    key = (scen, v.name, sig, name)
                    row.append(_cell(_shown(s.loc[key], d)) if key in s.index else "–")
                    if paper is not None:
                        row.append(fmt(paper.values.get(v.name, {}).get(f"{scen}/{name}/{sig}", float("nan"))))
                lines.append(md_row(row))
    lines += ["", "Variants:", ""]
    for v in exp.variants:
        where = ", ".join(v.scenarios or exp.scenario_names)
        lines.append(f"- `{v.name}` ({where}): " + variant_text(v))
    return "\n".join(lines) + "\n"


def markdown_table(exp: Experiment, summary: pd.DataFrame) -> str:
    """``table.md``: a row per variant, a column per (metric, signal) with the paper's value beside each of the
    first metric's (the paper's values are of that metric), and optionally a row of one variant's change relative
    to another (``table.relative``). Without a ``table:`` section, every metric gets such a table of its signals,
    one under the other. A multi-scenario experiment gets :func:`study_table`'s layout."""
    if exp.scenarios is not None:
        return study_table(exp, summary)
    spec = exp.table
    names, paper, display = (spec.shown, spec.paper, spec.display) if spec else ([m.label for m in exp.metrics], None, {})
    blocks = _blocks(exp)
    s = summary.set_index(["variant", "signal", "metric"])
    paper_of = names[0] if paper is not None else None  # the paper's column beside each of this metric's

    def row(label: str, columns, cell, paper_key: str) -> str:
        cells = [label]
        for name, sig in columns:
            cells.append(cell(name, sig))
            if name == paper_of:
                cells.append(fmt(paper.values.get(paper_key, {}).get(sig, float("nan"))))
        return md_row(cells)

    def ours(variant: str):
        def cell(name, sig):
            key = (variant, sig, name)
            return _cell(_shown(s.loc[key], display.get(f"{name}/{sig}"))) if key in s.index else "n/a"
        return cell

    def table(columns) -> list[str]:
        return [*_grid(_variant_header(columns, display, len({n for n, _ in columns}) > 1, paper_of)),
                *(row(v.name, columns, ours(v.name), v.name) for v in exp.variants)]

    (title, columns), *more = blocks
    lines = [f"## {title}", "", *_preamble(exp, "; ".join(_window(exp, n) for n in names),
                                          f"scenario `{exp.scenario.name}`, root seed {exp.seed}", paper), *table(columns)]
    for title, columns in more:  # without a table: section, the second metric's on
        lines += ["", f"## {title}", *table(columns)]
    if spec is not None and spec.relative is not None:
        a, b = spec.relative
        lines.append(row(f"{a} vs {b} [%]", blocks[0][1], _change_in_percent(s, a, b), f"{a}_vs_{b}"))
    return "\n".join(lines + _variant_lines(exp)) + "\n"


def _variant_lines(exp: Experiment) -> list[str]:
    """The list of variants under a table, each with its settings."""
    return ["", "Variants:", "", *(f"- `{v.name}`: " + variant_text(v) for v in exp.variants)]


def _blocks(exp: Experiment) -> list[tuple[str, list[tuple[str, str]]]]:
    """(title, its (metric, signal) columns) of each table in ``table.md``: the ``table:`` section's one, or without
    it one per metric, of that metric's signals."""
    spec = exp.table
    if spec is None:
        return [(f"{exp.name}: {m.label}", [(m.label, sig) for sig in m.signals]) for m in exp.metrics]
    return [(spec.title or f"{exp.name}: {spec.shown[0]}", [(name, sig) for name in spec.shown for sig in spec.signals])]


def _variant_header(columns: list[tuple[str, str]], display, multi: bool, paper_of: str | None) -> list[str]:
    """``variant``, then a column per (metric, signal): named by the metric when there are several, else 'ours',
    each of metric ``paper_of``'s followed by the paper's."""
    header = ["variant"]
    for name, sig in columns:
        d = display.get(f"{name}/{sig}")
        label = LABELS.get(sig, sig) + (f" [{d.unit}]" if d and d.unit else "")
        ours = f"{name} ({label})" if multi else f"{label} ours"
        header += [ours] + ([f"{ours.removesuffix(' ours')} paper"] if name == paper_of else [])
    return header


def _change_in_percent(s: pd.DataFrame, a: str, b: str):
    """The cells of ``table.relative``'s row: variant a's mean vs b's in % ('–' where either is missing)."""
    def change(name, sig):
        if (a, sig, name) not in s.index or (b, sig, name) not in s.index:
            return "–"
        pct = 100 * (s.loc[(a, sig, name), "mean"] / s.loc[(b, sig, name), "mean"] - 1)
        return "–" if math.isnan(pct) else f"{pct:+.1f}"
    return change
