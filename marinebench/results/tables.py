"""Markdown tables in the paper's layout: ours (mean and 95% CI over seeds) beside the paper's values."""

from __future__ import annotations

import math

import pandas as pd

from marinebench.config import Experiment

LABELS = {"u": "e_u", "v": "e_v", "r": "e_r", "sigma_u": "e_sigma_u", "sigma_v": "e_sigma_v", "sigma_r": "e_sigma_r"}


def fmt(x: float) -> str:
    return "–" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.3g}"


def markdown_table(exp: Experiment, summary: pd.DataFrame) -> str:
    spec = exp.table
    if spec is None:
        metric = exp.metrics[0].kind
        spec_title, signals, paper = f"{exp.name}: {metric} of the estimation errors", exp.metrics[0].signals, None
    else:
        metric, spec_title, signals, paper = spec.metric, spec.title, spec.signals, spec.paper
    window = next(m for m in exp.metrics if m.kind == metric)
    s = summary[summary["metric"] == metric].set_index(["variant", "signal"])
    header = ["variant"]
    for sig in signals:
        header.append(f"{LABELS.get(sig, sig)} ours")
        if paper is not None:
            header.append(f"{LABELS.get(sig, sig)} paper")
    lines = [f"## {spec_title}", ""]
    lines.append(
        f"Ours: {metric} of est − truth over t ∈ [{window.t_start:g}, {window.t_end or exp.scenario.horizon:g}] s, "
        f"mean over {exp.seeds} seed(s) with the 95% Student-t interval in brackets; scenario `{exp.scenario.name}`, "
        f"root seed {exp.seed}."
    )
    if paper is not None:
        lines.append(f"Columns marked *paper* are published values from {paper.source}, copied for comparison, not computed.")
    lines += ["", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for v in exp.variants:
        row = [v.name]
        for sig in signals:
            if (v.name, sig) in s.index:
                r = s.loc[(v.name, sig)]
                cell = fmt(r["mean"])
                if not math.isnan(r["ci_low"]):
                    cell += f" [{fmt(r['ci_low'])}, {fmt(r['ci_high'])}]"
                if r["n_diverged"]:
                    cell += f" ({int(r['n_diverged'])} diverged)"
            else:
                cell = "n/a"
            row.append(cell)
            if paper is not None:
                row.append(fmt(paper.values.get(v.name, {}).get(sig, float("nan"))))
        lines.append("| " + " | ".join(row) + " |")
    labels = {v.name: v.observer.model_dump() for v in exp.variants}
    lines += ["", "Variants:", ""]
    lines += [f"- `{name}`: " + ", ".join(f"{k}={val}" for k, val in t.items() if val is not None) for name, t in labels.items()]
    return "\n".join(lines) + "\n"
