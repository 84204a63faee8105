"""Write an experiment's or a sweep's result directory atomically."""

from __future__ import annotations

import time
from pathlib import Path

import pandas as pd
import yaml

from marinebench.experiments.curves import sweep_claims, sweep_figure, sweep_table
from marinebench.experiments.grid import (
    grid_claims,
    grid_claims_markdown,
    grid_figure,
    grid_manifest_entries,
    grid_table,
)
from marinebench.experiments.runner import RunResult, summarise
from marinebench.experiments.settings import tuning
from marinebench.experiments.sweep import as_swept
from marinebench.metrics.stats import diverged_runs_quiet
from marinebench.plotting.figures import timeseries, tracking
from marinebench.provenance import inputs_key
from marinebench.results.claims import ClaimResult, manifest_entries
from marinebench.results.claims import evaluate as evaluate_claims
from marinebench.results.claims import markdown as claims_markdown
from marinebench.results.tables import markdown_table
from marinebench.results.traces import FILE as TRACES_FILE
from marinebench.results.traces import write_traces
from marinebench.results.writer import atomic_directory, manifest

_RK4 = "plant and observers integrated jointly by fixed-step RK4; dt refused unless dt*|lambda|max <= stiffness_limit"
STANDARD_ASSUMPTIONS = {
    "open_loop_asv": [
        ("Liu-Wang-Peng ESO reconstructed (LIU19 text unavailable): eps-scaled ESO, k=(3,3,1), linear corrections "
        "by default (shared/reference/baselines.md s.1)"),
        ("Bejarano LMIs with an added disk region |lambda| <= rho (default max(50, 5 delta)) because (16)/(28) are "
        "flat in the gains; time-scaled solve for delta >= 50 (baselines.md s.2.4)"),
        ("Bejarano LMI objective beta + mu tr(P) (trace_weight, default 1e-3) instead of beta: without it the "
        "rotational problem (and the positional one with k_n = 0) has no attained optimum and its gains depend on "
        "where the solver stops (design/lmi.py)"),
        "true lumped disturbance sigma from eq. (6) with g = 0",
        _RK4,
    ],
    "dp_supply": [_RK4],
    "rov_tracking": [
        ("plant, CDO and EO integrated jointly by fixed-step RK4 at dt; sensors sampled and held, controllers "
        "discrete at control_period, commands through the thrust allocation and saturation"),
    ],
}


#: How ``metrics.csv`` writes a float: 7 significant digits.
METRICS_FLOAT = "%.6e"


def as_written(metrics: pd.DataFrame) -> pd.DataFrame:
    """The metrics as ``metrics.csv`` holds them, every float to :data:`METRICS_FLOAT`. Tables and claims are made
    from these, so that they are what anyone makes of the file: from the unrounded values a mean can round the
    other way in its fourth digit (18.59 against 18.6 in one cell of the k x c_eps grid)."""
    out = metrics.copy()
    for col in out.select_dtypes("float").columns:
        out[col] = [float(METRICS_FLOAT % x) for x in out[col]]
    return out


def _steps(worlds: dict) -> dict:
    """dt, horizon and steps of the world (or of each named world)."""
    info = {name: {"dt": sc.dt, "horizon": sc.horizon, "steps": round(sc.horizon / sc.dt)} for name, sc in worlds.items()}
    return next(iter(info.values())) if len(info) == 1 else {"scenarios": info}


def resolved_yaml(exp) -> str:
    """The experiment with every default filled in, as written to ``config.resolved.yaml``."""
    return yaml.safe_dump(exp.model_dump(mode="json"), sort_keys=False, allow_unicode=True)


def model_assumptions(worlds: dict, variants=()) -> list[str]:
    """What the worlds' own settings assume (each world's ``assumptions()``: a DP model mismatch, where an ROV world's
    observers start, with the per-run world keys the ``variants`` set), as manifest lines naming the worlds that
    share each."""
    per_run = {key for v in variants for key in v.world}
    shared: dict[str, list[str]] = {}
    for w in worlds.values():
        for text in w.assumptions(per_run):
            shared.setdefault(text, []).append(w.name)
    return [f"scenario{'s' * (len(names) > 1)} {', '.join(names)}: {text}" for text, names in shared.items()]


def write_run(result: RunResult, out_dir: Path, sources: dict[str, Path], claims: list[ClaimResult] | None = None) -> Path:
    """Write one experiment's result directory atomically (``claims``: its checked claims, if already evaluated on
    the metrics :func:`as_written`; a config with ``claims:`` also gets ``claims.md``, one with
    ``engine.write_traces`` ``traces.csv.gz``). ``table.md`` and ``claims.md`` are made from ``metrics.csv``'s values.
    A result that kept no traces (``marinebench.run(..., traces=False)``) of an experiment that draws figures or
    writes them is a ValueError, before anything is written."""
    exp = result.experiment
    parts = list(result.parts.values()) or [result]
    drawn = [part for part in parts if part.experiment.figures or part.experiment.engine.write_traces]
    if any(part.traced.size == 0 for part in drawn):
        raise ValueError(f"{exp.name}: this result kept no traces, which its figures are drawn from "
                         "(run with traces=True)")
    metrics = as_written(result.metrics)
    if claims is None:
        claims = evaluate_claims(exp, metrics)
    with atomic_directory(out_dir) as tmp:
        (tmp / "config.resolved.yaml").write_text(resolved_yaml(exp), encoding="utf-8")
        metrics.to_csv(tmp / "metrics.csv", index=False, float_format=METRICS_FLOAT)
        (tmp / "table.md").write_text(markdown_table(exp, summarise(metrics)), encoding="utf-8")
        if claims:
            (tmp / "claims.md").write_text(claims_markdown(exp, claims), encoding="utf-8")
        if exp.engine.write_traces:
            write_traces(result, tmp / TRACES_FILE)
        figdir = tmp / "figures"
        figdir.mkdir()
        for part in parts:
            variant, seed = part.run_variant[part.traced], part.run_seed[part.traced]  # the traces' columns
            draw_figures(part.experiment, (*part.traces, variant, seed), figdir)
        worlds = {name: exp.part(name).scenario for name in exp.scenario_names}
        (tmp / "manifest.json").write_text(
            manifest(
                experiment=exp.name,
                model=exp.model_label(),
                inputs_key=inputs_key(exp),
                config_files={k or "experiment": str(v) for k, v in sources.items()},
                seed=exp.seed,
                seeds=exp.seeds,
                runs=len(result.run_seed),
                diverged_runs=int((result.metrics.groupby(["scenario", "variant", "seed"])["status"].first() != "ok").sum()),
                **_steps(worlds),
                max_observer_rate=result.max_rate,
                wall_time_s=round(result.wall_time, 3),
                assumptions=STANDARD_ASSUMPTIONS[worlds[exp.scenario_names[0]].kind] + model_assumptions(worlds, exp.variants)
                + list(exp.assumptions),
                designs=result.designs,
                claims=manifest_entries(claims),
            ),
            encoding="utf-8",
        )
    return out_dir


def draw_figures(part, traced: tuple, figdir: Path) -> None:
    """Draw the figures of one scenario's ``part`` of an experiment from its ``traced`` arrays, ``(t, truth, est,
    variant, seed)`` (``RunResult.traces`` and its traced runs, or :func:`~marinebench.results.traces.traced_arrays`
    of a written ``traces.csv.gz``) into ``figdir``."""
    for spec in part.figures:
        draw = tracking if spec.kind == "tracking" else timeseries
        draw(part, spec, *traced, figdir / spec.file)


def redraw_figures(folder: Path) -> list[str]:
    """Draw a result folder's figures again, without simulating, and swap them in for ``figures/`` atomically;
    returns the files drawn. A run's are drawn from its ``traces.csv.gz`` and the ``figures:`` of its
    ``config.resolved.yaml`` (edited, say, to show other signals or variants); a sweep's (its manifest names the
    ``params`` swept) from its ``metrics.csv`` and the ``sweep:`` of its ``config.resolved.yaml`` (the metrics,
    signals and axis labels shown). Raises MarinebenchError naming the folder or file."""
    from marinebench.errors import MarinebenchError
    from marinebench.loading import load_experiment
    from marinebench.results.stored import read_manifest
    from marinebench.results.traces import read_traces, traced_arrays

    folder = Path(folder)
    stored = read_manifest(folder)
    if "params" not in stored and not (folder / TRACES_FILE).exists():
        if not (folder / "config.resolved.yaml").exists() and (tree := _redrawable_inside(folder)) is not None:
            raise MarinebenchError(f"{folder}: not a result folder but a tree of them: name the ones to redraw "
                                   f"({tree})")
        raise MarinebenchError(f"{folder}: no {TRACES_FILE} to draw from (run the config with --traces)")
    figures = folder / "figures"
    if figures.is_symlink() or (figures.exists() and not figures.is_dir()):  # someone's: it would be swapped out
        raise MarinebenchError(f"{figures}: {'a symbolic link' if figures.is_symlink() else 'a file'}, not the "
                               "result's figures folder: not replaced (move it)")
    exp, _ = load_experiment(folder / "config.resolved.yaml")
    if "params" in stored:  # a sweep's manifest names the parameters swept
        return [_redraw_sweep_figure(folder, exp, bool(stored.get("grid")), figures)]
    frame = read_traces(folder / TRACES_FILE)
    with atomic_directory(figures, results=False) as figdir:
        for name in exp.scenario_names:
            part = exp.part(name)
            try:
                traced = traced_arrays(frame, part)
            except ValueError as exc:
                raise MarinebenchError(f"{folder / TRACES_FILE}: {exc}") from None
            _check_traced(folder, part, traced)
            draw_figures(part, traced, figdir)
    return [spec.file for name in exp.scenario_names for spec in exp.part(name).figures]


def _redrawable_inside(tree: Path) -> str | None:
    """What :func:`redraw_figures` can draw among the result folders right inside ``tree`` (a sweep's, a run's with
    traces), said for a refusal; None when it holds none."""
    from marinebench.results.stored import read_manifest

    inside = sorted(p.parent for p in tree.glob("*/manifest.json"))
    if not inside:
        return None
    can = [d for d in inside if (d / TRACES_FILE).exists() or "params" in read_manifest(d)]
    return (f"{len(can)} of its {len(inside)} can be, sweeps and runs with --traces, e.g. {can[0]}" if can else
            f"none of its {len(inside)} can be: only sweeps and runs with --traces")


def sweep_figure_file(grid: bool) -> str:
    """The file in a sweep's ``figures/``: the heat maps of a grid, or the curves."""
    return "grid.png" if grid else "sweep.png"


def _redraw_sweep_figure(folder: Path, exp, grid: bool, figures: Path) -> str:
    """:func:`redraw_figures` of a sweep's folder: its figure drawn as ``sweep`` drew it (from the values
    ``metrics.csv`` holds, as there) into ``figures``; returns the file's name."""
    from marinebench.errors import MarinebenchError
    from marinebench.results.stored import StoredResultError, read_metrics

    if exp.sweep is None:
        raise MarinebenchError(f"{folder / 'config.resolved.yaml'}: no sweep: section to draw the sweep's figure by")
    metrics = read_metrics(folder / "metrics.csv")
    if missing := [c for c in ["gnss", "param", "param_value", *(["param2", "param2_value"] if grid else [])]
                   if c not in metrics.columns]:
        raise StoredResultError(f"{folder / 'metrics.csv'}: missing column(s) {missing}; is this a "
                                f"{'grid ' if grid else ''}sweep's metrics.csv?")
    swept = set(metrics["param"]) | (set(metrics["param2"]) if grid else set())
    if lost := sorted(swept - set(exp.sweep.params)):  # the figure marks each parameter's own value by its sweep.params
        raise MarinebenchError(f"{folder / 'config.resolved.yaml'}: sweep.params: no {lost}, which {folder / 'metrics.csv'} "
                               f"holds (have: {', '.join(exp.sweep.params)})")
    for metric in exp.sweep.shown:
        signals = set(metrics.loc[metrics["metric"] == metric, "signal"])
        if not signals or not set(exp.sweep.signals or signals) <= signals:
            what, holds = ((f"signal(s) {sorted(set(exp.sweep.signals) - signals)} of metric {metric}",
                            f"its signals there: {', '.join(sorted(signals))}") if signals else
                           (f"metric {metric}", f"it holds metrics {', '.join(sorted(set(metrics['metric'])))}"))
            raise MarinebenchError(f"{folder / 'config.resolved.yaml'}: sweep: no {what} in {folder / 'metrics.csv'} "
                                   f"({holds})")
    file = sweep_figure_file(grid)
    with diverged_runs_quiet(), atomic_directory(figures, results=False) as figdir:
        (grid_figure if grid else sweep_figure)(metrics, exp.sweep.shown, exp, figdir / file)
    return file


def _check_traced(folder: Path, part, traced: tuple) -> None:
    """Each edited figure draws only what ``traces.csv.gz`` holds: its signals (a truth, and an estimate where the
    figure needs one) and seed 0 of each of its variants. Before, another signal or a variant added to the config
    after the run was a traceback (KeyError, IndexError)."""
    from marinebench.errors import MarinebenchError
    from marinebench.plotting.figures import traces_needed

    _, truth, est, run_variant, run_seed = traced
    traced_names = {part.variants[i].name for i, s in zip(run_variant, run_seed) if s == 0}
    for spec in part.figures:
        need_truth, need_est = traces_needed(spec)
        missing = [s for s in need_truth if s not in truth] + [f"{s} (estimate)" for s in need_est if s not in est]
        untraced = [v for v in spec.variants or [v.name for v in part.variants] if v not in traced_names]
        if missing or untraced:
            what = f"no trace of {missing}" if missing else f"no seed-0 run of variants {untraced}"
            raise MarinebenchError(f"{folder / 'config.resolved.yaml'}: figures: {spec.file}: {what} in {TRACES_FILE} "
                                   f"(it holds signals {', '.join(sorted(truth))}; variants {', '.join(sorted(traced_names))})")


def write_sweep(target: Path, exp, base, config: Path, metrics: pd.DataFrame, params: list[str], grid: bool,
                started: float, **run_info) -> tuple[list[ClaimResult], list]:
    """Write a sweep's result directory atomically: ``metrics.csv``, ``config.resolved.yaml`` (of ``base``, the
    config swept), ``table.md`` (a table, or with ``grid`` a matrix, per shown metric), ``claims.md`` (the checks
    of ``sweep.claims``, or with ``grid`` where along the grid each holds), ``figures/`` and ``manifest.json``.

    ``exp`` is the sweep's experiment (one variant per point), ``started`` the ``time.perf_counter()`` at which
    the command started, ``run_info`` what the manifest records of how the sweep ran (overrides, points, groups,
    batches, executor, times). Returns the checked claims and the claims mapped over a grid."""
    shown = base.sweep.shown
    metrics = as_written(metrics)
    table, figure = (grid_table, grid_figure) if grid else (sweep_table, sweep_figure)
    # the table shows '–' where every run of a point diverged, and a claim there fails: without numpy's warnings
    with diverged_runs_quiet(), atomic_directory(target) as tmp:
        claims = [] if grid else sweep_claims(metrics, base.sweep)
        mapped = grid_claims(metrics, base.sweep) if grid else []  # the same claims, along each slice of the grid
        metrics.to_csv(tmp / "metrics.csv", index=False, float_format=METRICS_FLOAT)
        swept = as_swept(base, params, exp.scenario.horizon)  # with the horizon its runs had (--horizon)
        (tmp / "config.resolved.yaml").write_text(resolved_yaml(swept), encoding="utf-8")
        (tmp / "table.md").write_text("\n".join(table(metrics, metric, base.sweep, model=base.model_label())
                                                for metric in shown), encoding="utf-8")
        if claims:
            (tmp / "claims.md").write_text(claims_markdown(exp, claims, where="group", title=f"sweep of {config.name}"),
                                           encoding="utf-8")
        if mapped:
            own = {p: tuning(base, p) for p in params}
            (tmp / "claims.md").write_text(grid_claims_markdown(exp, mapped, own), encoding="utf-8")
        (tmp / "figures").mkdir()
        figure(metrics, shown, base, tmp / "figures" / sweep_figure_file(grid))
        (tmp / "manifest.json").write_text(manifest(
            experiment=exp.name, model=exp.model_label(), inputs_key=inputs_key(exp), config_files={"experiment": str(config)},
            seed=exp.seed, seeds=exp.seeds, runs=len(exp.variants) * exp.seeds, params=params, grid=grid,
            horizon=exp.scenario.horizon, dt=exp.scenario.dt, **run_info,
            total_time_s=round(time.perf_counter() - started, 3),
            assumptions=model_assumptions({"": exp.scenario}, exp.variants) + list(base.assumptions),
            claims=manifest_entries(claims), **({"grid_claims": grid_manifest_entries(mapped)} if grid else {})),
            encoding="utf-8")
    return claims, mapped
