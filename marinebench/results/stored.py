"""Reading a result directory back (``compare``, ``report``): its ``metrics.csv``, ``manifest.json`` and
``config.resolved.yaml``, each checked on the way in, so that a damaged or foreign file is one line naming
it (:class:`StoredResultError`, exit code 2), not a traceback from pandas, json or yaml."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from marinebench.errors import ConfigError, MarinebenchError

#: Columns every ``metrics.csv`` written by ``run`` or ``sweep`` has (``status`` is optional: older files; see
#: :func:`_check_status`).
METRICS_COLUMNS = ["experiment", "scenario", "variant", "seed", "signal", "metric", "value"]
#: The columns of names, read as text: a config, scenario or variant may be named "1", "1e3" or "NA" (config.NAME),
#: and must keep that name rather than become a number or a blank.
NAME_COLUMNS = ("experiment", "scenario", "variant", "signal", "metric", "status", "gnss", "param", "param2")
#: What a number column reads as NaN (a diverged run's value is written blank).
MISSING = ["", "nan", "NaN", "-nan", "NA", "N/A", "null"]


class StoredResultError(MarinebenchError):
    """A result file that cannot be read back."""


def read_text(path: Path) -> str:
    """A result's text file (``table.md``, ``claims.md``), UTF-8."""
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise StoredResultError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    except OSError as exc:
        raise StoredResultError(f"{path}: cannot read ({exc.strerror})") from None


def read_tidy(path: Path, nrows: int | None = None) -> pd.DataFrame:
    """A tidy CSV as ``run`` and ``sweep`` write it: :data:`NAME_COLUMNS` as text, blanks (:data:`MISSING`) as NaN
    in the other columns only."""
    columns = pd.read_csv(path, nrows=0).columns
    return pd.read_csv(path, nrows=nrows, dtype={c: str for c in NAME_COLUMNS if c in columns}, keep_default_na=False,
                       na_values={c: MISSING for c in columns if c not in NAME_COLUMNS})


def read_columns(path: Path, need: list[str], numeric: tuple[str, ...], nrows: int | None = None) -> pd.DataFrame:
    """A tidy CSV (:func:`read_tidy`; gzipped by its name's ``.gz``) with at least the columns ``need``, those of
    them in ``numeric`` numbers; else one line naming the file."""
    try:
        df = read_tidy(path, nrows=nrows)
    except (OSError, EOFError, ValueError, pd.errors.ParserError) as exc:  # EmptyDataError and decoding errors are
        # ValueErrors; a gzip cut short is an EOFError (which the command line would take for Ctrl-D), a bad one an OSError
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise StoredResultError(f"{path}: not a readable CSV ({first})") from None
    missing = [c for c in need if c not in df.columns]
    if missing:
        raise StoredResultError(f"{path}: missing column(s) {missing}; is this a marinebench {Path(path).name}?")
    if df.empty:
        raise StoredResultError(f"{path}: no rows")
    for col in numeric:
        if col in need and not pd.api.types.is_numeric_dtype(df[col]):
            raise StoredResultError(f"{path}: column '{col}' is not numeric")
    return df


def require_keys(df: pd.DataFrame, keys: list[str], path: Path) -> None:
    """Every row of a tidy file has its ``keys`` (neither blank nor NaN): a file cut short mid-row is one line."""
    if (blank := df[keys].isna().any(axis=1) | df[keys].eq("").any(axis=1)).any():
        raise StoredResultError(f"{path}: line {int(blank.to_numpy().argmax()) + 2}: a row without its "
                                f"{', '.join(keys)} (a truncated file?)")


def read_metrics(path: Path, usecols: list[str] | None = None, nrows: int | None = None) -> pd.DataFrame:
    """A ``metrics.csv`` with at least :data:`METRICS_COLUMNS` (or ``usecols``) and numeric ``seed``/``value``."""
    df = read_columns(path, usecols or METRICS_COLUMNS, ("seed", "value"), nrows)
    if usecols is None:  # one value per cell and seed, or the paired comparison has nothing to pair
        require_keys(df, METRICS_COLUMNS[:-1], path)  # a value may be nan (a diverged run), a key may not
        twice = df[df.duplicated(METRICS_COLUMNS[:-1], keep=False)]
        if len(twice):
            first = ", ".join(f"{k}={twice.iloc[0][k]}" for k in METRICS_COLUMNS[:-1])
            raise StoredResultError(f"{path}: {len(twice)} rows share their experiment, scenario, variant, seed, "
                                    f"signal and metric (first: {first})")
        _check_status(df, path)
    return df[usecols] if usecols else df


def _check_status(df: pd.DataFrame, path: Path) -> None:
    """``run`` and ``sweep`` write a finished run's value as a finite number with status ``ok``, and a diverged
    run's as NaN with status ``diverged``. A file without ``status`` (older files) gets it from its values; in one
    with it, an ``ok`` row whose value is NaN or infinite is refused: a comparison would average it into a NaN
    (and call the cell the same) or an infinity."""
    finite = np.isfinite(df["value"].to_numpy(dtype=float))
    if "status" not in df:
        df["status"] = np.where(finite, "ok", "diverged")
    elif (bad := (df["status"] == "ok").to_numpy() & ~finite).any():
        line = int(bad.argmax())
        raise StoredResultError(f"{path}: line {line + 2}: value {df['value'].iloc[line]} with status ok (a finished "
                                f"run's value is a finite number; a diverged run's has status diverged)")


def read_manifest(d: Path) -> dict:
    """``d/manifest.json`` as a mapping ({} when there is none)."""
    path = d / "manifest.json"
    if not path.exists():
        return {}
    try:
        doc = json.loads(read_text(path))
    except json.JSONDecodeError as exc:
        raise StoredResultError(f"{path}: invalid JSON: line {exc.lineno}, column {exc.colno}: {exc.msg}") from None
    if not isinstance(doc, dict):
        raise StoredResultError(f"{path}: expected a JSON object at the top level")
    claims = doc.get("claims", [])
    if not isinstance(claims, list) or not all(isinstance(c, dict) and {"text", "holds"} <= set(c) for c in claims):
        raise StoredResultError(f"{path}: claims: expected a list of objects with 'text' and 'holds'")
    return doc


def read_resolved(d: Path) -> dict:
    """``d/config.resolved.yaml`` as a mapping ({} when there is none), read like a config file."""
    from marinebench.loading import read_yaml

    path = d / "config.resolved.yaml"
    if not path.exists():
        return {}
    try:
        return read_yaml(path)
    except ConfigError as exc:
        raise StoredResultError(str(exc)) from None
