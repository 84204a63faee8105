"""The traces the figures draw, as a tidy table: ``RunResult.trace_frame()`` and ``traces.csv.gz``.

The engine keeps, every ``engine.trace_dt`` seconds, the true signals and the estimates of seed 0 of each variant
(``sim.recorders.Traces``); the figures are drawn from them. Here they become one row per (scenario, variant,
seed, t, signal) with the ``truth`` and the ``estimate``, so a figure can be redrawn in another style, or another
signal plotted, without simulating again. ``engine.write_traces: true`` (``run --traces``) writes the table beside
the metrics.

``estimate`` is what the metrics compare with the truth (their error is ``estimate - truth``): an observer's
estimate. In a tracking world (Tijjani), for ``depth`` and ``yaw`` (and their rates): the reference for a variant
with no ``observer:`` (the error is then the tracking error, as in Table III), the estimate for a variant observed
through the CDO or the EO (Fig. 2); for ``*_meas`` the same just before the last sample instant, against the
sample as truth; ``depth_cdo``, ``yaw_eo``, ...: each observer's estimate in every run. It is empty where nothing
is compared with the signal (a controller's command, ``tau_depth``).
"""

from __future__ import annotations

import gzip
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

if TYPE_CHECKING:
    from marinebench.experiments.runner import RunResult

#: Columns of the trace table, in order.
COLUMNS = ["scenario", "variant", "seed", "t", "signal", "truth", "estimate"]
#: File name of the written table (gzip, deterministic bytes: no time stamp or file name in its header).
FILE = "traces.csv.gz"


def trace_frame(result: RunResult) -> pd.DataFrame:
    """The decimated traces of ``result`` (every scenario of a multi-scenario experiment) as a tidy DataFrame with
    :data:`COLUMNS`; rows by scenario, variant, seed, signal, then time. Raises ValueError when the result kept
    no traces (``run(..., traces=False)``, a sweep)."""
    frames = [_part_frame(part) for part in (result.parts.values() or [result])]
    if not frames or all(f.empty for f in frames):
        raise ValueError("this result kept no traces (run with traces=True)")
    return pd.concat(frames, ignore_index=True)


def _part_frame(part: RunResult) -> pd.DataFrame:
    t, truth, est = part.traces
    if t.size == 0 or part.traced.size == 0:
        return pd.DataFrame(columns=COLUMNS)
    variants = np.asarray([v.name for v in part.experiment.variants])[part.run_variant[part.traced]]
    seeds = part.run_seed[part.traced]
    signals = sorted(truth)
    n_t, n_runs = len(t), len(part.traced)
    # (signal, run, time) order: each run's signal is one contiguous block of times
    truth_values = np.stack([truth[s].T for s in signals])  # (S, R, T)
    est_values = np.stack([est[s].T if s in est else np.full((n_runs, n_t), np.nan) for s in signals])
    frame = pd.DataFrame({
        "scenario": part.experiment.scenario.name,
        "variant": np.tile(np.repeat(variants, n_t), len(signals)),
        "seed": np.tile(np.repeat(seeds, n_t), len(signals)),
        "t": np.tile(t, len(signals) * n_runs),
        "signal": np.repeat(signals, n_runs * n_t),
        "truth": truth_values.ravel(),
        "estimate": est_values.ravel(),
    })
    return frame.sort_values(["variant", "seed", "signal", "t"], kind="stable", key=_variant_order(part)).reset_index(drop=True)


def _variant_order(part: RunResult):
    """Sort key: variants in the config's order, the other columns as they are."""
    order = {v.name: i for i, v in enumerate(part.experiment.variants)}
    return lambda col: col.map(order) if col.name == "variant" else col


def write_traces(result: RunResult, path: Path) -> None:
    """Write :func:`trace_frame` to ``path`` as gzip-compressed CSV (10 significant digits), byte for byte the same
    for the same numbers."""
    text = trace_frame(result).to_csv(index=False, float_format="%.10g")
    Path(path).write_bytes(gzip.compress(text.encode(), mtime=0))


def read_traces(path: Path) -> pd.DataFrame:
    """A written ``traces.csv.gz`` as the DataFrame :func:`trace_frame` gave (names as text: a variant may be named
    "1e3"); a damaged or foreign file (not gzip, cut short, columns missing or not numbers, a row without its keys)
    is a :class:`~marinebench.results.stored.StoredResultError` naming it."""
    from marinebench.results.stored import read_columns, require_keys

    frame = read_columns(path, COLUMNS, ("seed", "t", "truth", "estimate"))
    require_keys(frame, COLUMNS[:5], path)
    return frame


def traced_arrays(frame: pd.DataFrame, part) -> tuple:
    """The inverse of :func:`trace_frame` for one scenario's ``part`` of an experiment (``Experiment.part``): the
    arrays the figures draw, ``(t, truth, est, variant, seed)``: times ``(T,)``, ``{signal: (T, R)}`` for the truth
    and for the signals that have an estimate, and each of the R traced runs' variant index and seed. Raises
    ValueError when the frame names a variant the experiment does not have, or lacks a signal of a run."""
    rows = frame[frame["scenario"] == part.scenario.name]
    index = {v.name: i for i, v in enumerate(part.variants)}
    unknown = sorted(set(rows["variant"]) - set(index))
    if unknown:
        raise ValueError(f"variants {unknown} are not in the config (have: {', '.join(index)})")
    runs = list(dict.fromkeys(zip(rows["variant"], rows["seed"])))
    t = np.sort(rows["t"].unique())
    truth, est = {}, {}
    for signal, block in rows.groupby("signal", sort=True):
        if lacking := sorted(set(runs) - set(zip(block["variant"], block["seed"]))):
            raise ValueError(f"no rows of signal '{signal}' for variant {lacking[0][0]}, seed {lacking[0][1]} (a truncated file?)")
        wide = block.pivot_table(index="t", columns=["variant", "seed"], values=["truth", "estimate"], dropna=False)
        truth[signal] = np.column_stack([wide["truth"][run].reindex(t).to_numpy() for run in runs])
        values = np.column_stack([wide["estimate"][run].reindex(t).to_numpy() for run in runs])
        if not np.isnan(values).all():
            est[signal] = values
    variant = np.array([index[name] for name, _ in runs], dtype=int)
    seed = np.array([s for _, s in runs], dtype=int)
    return t, truth, est, variant, seed
