"""A sweep's runs in chunks (``sweep --chunk-size``), each kept on disk as it finishes, so that an interrupted
sweep resumes.

:func:`run_chunked` cuts the sweep's points into chunks of whole variants, runs the unfinished ones (in this
process, or on a pool of :mod:`marinebench.experiments.cluster`: local workers or Dask) and keeps each
chunk's metrics in ``.<folder>.partial/`` beside the sweep's folder until the results are written
(:func:`discard_partial`). The chunks on disk are reused only for the same inputs (``provenance.inputs_key``),
and runs are seeded per run, so neither chunking nor resuming changes a number; the rows are put in one order
(:func:`sweep_order`), so neither changes ``metrics.csv`` either.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd

from marinebench.config import Experiment, Variant
from marinebench.errors import ClusterError, ConfigError
from marinebench.results.stored import read_tidy

CHUNK_FILE = "chunk-{:04d}.csv"  # a finished chunk's metrics in partial_dir(target)


def run_chunk(exp: Experiment, variants: list[Variant], progress=None) -> tuple[str, float]:
    """Simulate one chunk of a sweep (in this process, a local worker process or a Dask worker): its tidy
    metrics as CSV text (full precision) and its simulation wall time."""
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
    seeding), so chunking does not change any number. With a ``pool`` (``experiments.cluster``: local worker
    processes or Dask) the unfinished chunks are submitted at once and each is saved here as it arrives, so the
    numbers are the same as in one process and an interrupted parallel sweep resumes the same way.
    Returns (metrics in :func:`sweep_order`, simulation wall time summed over the chunks run, chunks run).
    """
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
    chunk_steps = [steps(exp.model_copy(update={"variants": chunk})) for chunk in chunks]  # more where worlds differ
    if on_start is not None:
        on_start(sum(chunk_steps))
    kept = {c: frame for c, path in enumerate(paths) if (frame := _kept_chunk(path, chunks[c])) is not None}
    pending = [c for c in range(len(chunks)) if c not in kept]
    if progress is not None:
        progress(sum(chunk_steps[c] for c in kept))
    if pool is None:
        finished = ((c, run_chunk(exp, chunks[c], progress)) for c in pending)
    else:
        finished = pool.results(run_chunk, {c: (exp, chunks[c]) for c in pending}, progress,
                                {c: chunk_steps[c] for c in pending}, key[:12])
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
    return sweep_order(pd.concat(frames, ignore_index=True), exp), wall, len(pending)


def sweep_order(metrics: pd.DataFrame, exp: Experiment) -> pd.DataFrame:
    """A sweep's metrics rows in one order whatever its batches (``--chunk-size``, ``--jobs``): metric by metric
    (signal and metric in order of first appearance), each metric's rows variant by variant in the order of
    ``exp.variants``, a variant's rows in seed order as it ran them. That is the layout of the sweep run in one
    batch, except that a diagnostic two observer kinds share (``n_resets``) lists both kinds' runs in one block.
    Before, each batch listed its own rows metric by metric, so the same numbers came in another order for
    another chunk size."""
    block = metrics.groupby(["scenario", "signal", "metric"], sort=False, dropna=False).ngroup().to_numpy()
    variant = metrics["variant"].map({v.name: i for i, v in enumerate(exp.variants)}).to_numpy()
    return metrics.iloc[np.lexsort((variant, block))].reset_index(drop=True)  # stable: a variant's seeds keep order


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
    """Remove the kept chunks of the sweep that writes ``target``, once its results are written."""
    shutil.rmtree(partial_dir(target), ignore_errors=True)
