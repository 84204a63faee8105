"""One-at-a-time parameter sweeps (Torben et al. Fig. 3) as a single batch through the one engine.

For each named parameter, ``n`` values over its range (the others at the config's values), for each
world group (e.g. differential and dual-band GNSS): ``n x len(params) x len(groups)`` runs, all in one
batch with per-run gains and parameters. Each run is a variant tagged with ``param``, ``param_value``
and ``gnss`` (the group), which become columns of ``metrics.csv``.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import pandas as pd
from pydantic import ValidationError

from marinebench.config import Experiment, Variant
from marinebench.errors import ConfigError


def sweep_experiment(exp: Experiment, params: list[str], groups: list[str] | None, n: int | None,
                     horizon: float | None, file: Path) -> Experiment:
    """The experiment whose variants are the sweep's points (one seed each by default)."""
    spec = exp.sweep
    if spec is None:
        raise ConfigError(file, "sweep", "this config has no 'sweep' section")
    unknown = [p for p in params if p not in spec.params]
    if unknown:
        raise ConfigError(file, "sweep.params", f"unknown parameter(s) {unknown}; sweepable: {sorted(spec.params)}")
    groups = groups or list(spec.groups)
    bad = [g for g in groups if g not in spec.groups]
    if bad:
        raise ConfigError(file, "sweep.groups", f"unknown group(s) {bad}; available: {sorted(spec.groups)}")
    base = next(v for v in exp.variants if v.name == spec.variant)
    n = n or spec.n
    variants = []
    for p in params:
        ps = spec.params[p]
        if ps.key not in type(base.observer).model_fields:
            raise ConfigError(file, f"sweep.params.{p}.key", f"'{ps.key}' is not a field of {base.observer.kind}")
        for i, value in enumerate(ps.values(n)):
            try:
                observer = type(base.observer).model_validate({**base.observer.model_dump(), **ps.fixed, ps.key: float(value)})
            except ValidationError as exc:
                raise ConfigError(file, f"sweep.params.{p}", exc.errors()[0]["msg"]) from None
            for g in groups:
                variants.append(Variant(name=f"{p}_{i:03d}_{g}", observer=observer, world=spec.groups[g],
                                        tags={"param": p, "param_value": float(value), "gnss": g}))
    update = {"variants": variants, "figures": [], "table": None, "sweep": None, "name": f"{exp.name}_sweep"}
    scenario = exp.scenario if horizon is None else exp.scenario.model_copy(update={"horizon": horizon})
    update["scenario"] = scenario
    return exp.model_copy(update=update)


def sweep_table(metrics: pd.DataFrame, metric: str) -> str:
    df = metrics[metrics["metric"] == metric]
    lines = [f"## Sweep: {metric} vs each parameter", "",
             "One run per point (seed index 0); ‘best’ is the value with the lowest KPI.", "",
             "| param | gnss | points | min | at value | max | at value | diverged |", "|---|---|---|---|---|---|---|---|"]
    for (p, g), d in df.groupby(["param", "gnss"], sort=False):
        ok = d[d["status"] == "ok"]
        if ok.empty:
            lines.append(f"| {p} | {g} | {len(d)} | – | – | – | – | {len(d)} |")
            continue
        lo, hi = ok.loc[ok["value"].idxmin()], ok.loc[ok["value"].idxmax()]
        lines.append(f"| {p} | {g} | {len(d)} | {lo['value']:.4g} | {lo['param_value']:.4g} | {hi['value']:.4g} | "
                     f"{hi['param_value']:.4g} | {int((d['status'] != 'ok').sum())} |")
    return "\n".join(lines) + "\n"


def sweep_figure(metrics: pd.DataFrame, metric: str, exp: Experiment, path: Path) -> None:
    """Fig. 3 layout: one panel per parameter, the KPI against the value, one curve per group."""
    df = metrics[(metrics["metric"] == metric) & (metrics["signal"] == "z")]
    params = list(dict.fromkeys(df["param"]))
    fig, axes = plt.subplots(len(params), 1, figsize=(7, 2.6 * len(params)), squeeze=False)
    for ax, p in zip(axes[:, 0], params):
        d = df[df["param"] == p]
        for g, dg in d.groupby("gnss", sort=False):
            dg = dg.sort_values("param_value")
            ax.plot(dg["param_value"], dg["value"], ".-", ms=3, lw=1, label=g)
        if exp.sweep.params[p].spacing == "log":
            ax.set_xscale("log")
        ax.set_xlabel(p)
        ax.set_ylabel(metric)
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    fig.suptitle(f"{exp.name}: {metric} sensitivity (one parameter at a time)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run_chunked(exp: Experiment, target: Path, chunk_size: int, progress=None, on_start=None) -> tuple[pd.DataFrame, float, int]:
    """Run the sweep's runs in chunks, saving each chunk's metrics in ``.<target>.partial/``.

    An interrupted sweep resumes: chunks already on disk for the same experiment (same resolved config,
    compared by hash) are loaded, not rerun. Runs are independent of the batch they are in (per-run
    seeding), so chunking does not change any number. Returns (metrics, simulation wall time, chunks run).
    """
    import hashlib
    import shutil

    from marinebench.experiments.runner import run
    from marinebench.results.writer import atomic_write_text

    key = hashlib.sha256(exp.model_dump_json().encode()).hexdigest()
    partial = target.parent / f".{target.name}.partial"
    stale = partial.exists() and (
        not (partial / "key").exists() or (partial / "key").read_text().strip() != key
    )
    if stale:
        shutil.rmtree(partial)  # a different sweep was interrupted here: start afresh
    partial.mkdir(parents=True, exist_ok=True)
    atomic_write_text(partial / "key", key)
    chunks = [exp.variants[i : i + chunk_size] for i in range(0, len(exp.variants), chunk_size)]
    n_steps = round(exp.scenario.horizon / exp.scenario.dt)
    if on_start is not None:
        on_start(n_steps * len(chunks))
    frames, wall, ran = [], 0.0, 0
    for c, variants in enumerate(chunks):
        path = partial / f"chunk-{c:04d}.csv"
        if path.exists():
            frames.append(pd.read_csv(path))
            if progress is not None:
                progress(n_steps)
            continue
        result = run(exp.model_copy(update={"variants": variants}), progress=progress, traces=False)
        atomic_write_text(path, result.metrics.to_csv(index=False, float_format="%.17g"))
        frames.append(pd.read_csv(path))
        wall += result.wall_time
        ran += 1
    return pd.concat(frames, ignore_index=True), wall, ran


def discard_partial(target: Path) -> None:
    import shutil

    shutil.rmtree(target.parent / f".{target.name}.partial", ignore_errors=True)
