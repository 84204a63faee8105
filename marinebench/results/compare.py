"""Paired comparison of result directories: the CI gate for observer variants.

Cells are (experiment, scenario, variant, signal, metric), paired on seed. For each cell: baseline and
candidate means over their common seeds, the relative change, a paired bootstrap 95% CI of the mean
change (or, ``interval="t"`` and by default between two variants, the paired Student t interval), and a verdict:

- ``same``: |change| <= atol + rtol * |baseline| (or the CI contains zero);
- ``worse`` / ``better``: outside the tolerance *and* the CI excludes zero (with a single seed, the
  tolerance alone decides); direction from :data:`HIGHER_IS_BETTER` (lower is better by default);
- ``changed``: the same for a metric with no better side, the DP observers' per-run diagnostics
  (:data:`~marinebench.config.DIAGNOSTICS`: how often the resetting observer reset or jumped, the condition of
  its reset): listed, never failing the gate;
- ``missing``: in the baseline only; ``new``: in the candidate only.

A run that diverged in the candidate but not in the baseline is ``worse``, and so is a claim of the paper
(``claims.md``, listed in the manifest) that held in the baseline and fails in the candidate. Two result sets with no cell
in common are refused (:func:`require_pairs`): a gate that pairs nothing must not pass.

*Unpaired* (``paired=False``, ``compare --unpaired``): the two sides are independent samples, e.g. a candidate
run on another root seed to see whether a change holds on fresh noise. Every run of a cell counts, the CI is
Welch's t interval of the difference of the means (:func:`welch_ci`; wider than a paired one, which cancels the
noise both sides share), and only the root seed may differ between the worlds.
"""

from __future__ import annotations

import os
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd
from pydantic import TypeAdapter, ValidationError
from scipy.stats import t as student_t

from marinebench.config import DIAGNOSTICS, AnyScenario, Metric
from marinebench.errors import MarinebenchError
from marinebench.metrics.stats import mean_ci
from marinebench.results.stored import read_manifest, read_metrics, read_resolved
from marinebench.results.tables import md_row

Interval = Literal["bootstrap", "t"]  # the CI of a paired comparison (compare --interval)
HIGHER_IS_BETTER: set[str] = set()  # every metric so far (std, rmse, max_abs, J_tot, INT) is a cost: lower is better
NO_BETTER_SIDE = frozenset(DIAGNOSTICS)  # counts and conditions the observer reports: a change is neither
KEYS = ["experiment", "scenario", "variant", "signal", "metric"]
SEVERITY = {"worse": 0, "missing": 1, "new": 2, "changed": 3, "better": 4, "same": 5}
COUNTED = ("worse", "better", "same")  # verdicts of cells on both sides the headline always counts


class CompareInputError(MarinebenchError):
    """Unusable comparison input (missing files, mismatched configs)."""


@dataclass(frozen=True)
class Tolerance:
    rtol: float = 0.02
    atol: float = 0.0
    level: float = 0.95
    n_boot: int = 2000


def find_results(root: Path) -> dict[str, Path]:
    """Experiment name -> result directory, for a single result directory or a tree of them."""
    root = Path(root)
    if not root.exists():
        raise CompareInputError(f"{root}: no such directory")
    found: dict[str, Path] = {}
    for csv in _metrics_files(root):
        d = csv.parent
        first = read_metrics(csv, usecols=["experiment"], nrows=1)
        name = first["experiment"].iloc[0]
        if name in found:
            raise CompareInputError(f"{root}: experiment '{name}' appears twice ({found[name]} and {d})")
        found[name] = d
    if not found:
        raise CompareInputError(f"{root}: no metrics.csv found")
    return found


def _metrics_files(root: Path) -> list[Path]:
    """Every ``metrics.csv`` under ``root``, in sorted order, not looking into dot-folders (the temporary folders of a
    write under way or interrupted). A folder that cannot be listed, or vanishes while the tree is read (a
    ``run`` renaming its finished temporary folder into place), is passed over, not a traceback."""
    files = []
    for folder, subfolders, names in os.walk(root):
        subfolders[:] = [s for s in subfolders if not s.startswith(".")]
        files += [Path(folder) / "metrics.csv"] if "metrics.csv" in names else []
    return sorted(files)


def load_metrics(dirs: dict[str, Path]) -> pd.DataFrame:
    frames = [read_metrics(d / "metrics.csv") for d in dirs.values()]
    return pd.concat(frames, ignore_index=True)


def select_metrics(frames: list[pd.DataFrame], metrics: list[str] | None, claims: bool = True) -> list[pd.DataFrame]:
    """The rows of ``metrics`` (all without), refusing a name no frame has: a mistyped ``--metric`` would
    otherwise leave nothing to compare, and a gate that compares nothing passes. ``claims``: ``claim`` names the
    papers' claims, compared besides (not between variants: a claim is the experiment's)."""
    if not metrics:
        return frames
    have = set().union(*(set(f["metric"]) for f in frames)) | ({"claim"} if claims else set())
    unknown = [m for m in metrics if m not in have]
    if unknown:
        raise CompareInputError(f"--metric: no cell has metric {', '.join(map(repr, unknown))} "
                                f"(have: {', '.join(sorted(have))})")
    return [f[f["metric"].isin(metrics)] for f in frames]


def _world(d: Path) -> dict:
    """The parts of a resolved config that must agree for a comparison to be paired."""
    doc = read_resolved(d)
    if not doc:
        return {}
    scenarios = doc.get("scenarios")
    return {"scenario": _normalised(AnyScenario, doc.get("scenario")),
            "scenarios": {k: _normalised(AnyScenario, v) for k, v in scenarios.items()} if scenarios else scenarios,
            "seed": doc.get("seed"), "metrics": [_normalised(Metric, m) for m in doc.get("metrics") or []]}


def _normalised(kind, value):
    """A resolved config's section re-validated by this marinebench, so that an option added since the
    reference was written (absent there, at its default here) does not count as a difference; a section this
    version cannot read (a removed option) stays as written and so differs."""
    if value is None:
        return None
    try:
        return TypeAdapter(kind).validate_python(value).model_dump(mode="json")
    except ValidationError:
        return value


def _diff_keys(a, b, prefix: str = "") -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            out += _diff_keys(a.get(k), b.get(k), f"{prefix}.{k}" if prefix else str(k))
        return out
    return [] if a == b else [prefix]


def check_compatible(base: dict[str, Path], cand: dict[str, Path], paired: bool = True) -> None:
    """Refuse experiments whose worlds differ (scenario, root seed, metric windows): their seeds are not pairs.
    Unpaired, the root seed may differ (that is what the mode is for), the rest may not: other worlds are not
    samples of the same thing. One line: the first such experiment with the keys that differ, the names of the
    others, and, when the root seed is among the keys, the option that compares such runs."""
    mismatched = {}
    for name in sorted(set(base) & set(cand)):
        diff = [k for k in _diff_keys(_world(base[name]), _world(cand[name])) if paired or k != "seed"]
        if diff:
            mismatched[name] = diff
    if not mismatched:
        return
    name, diff = next(iter(mismatched.items()))
    others = list(mismatched)[1:]
    seeds_differ = any("seed" in d for d in mismatched.values())
    raise CompareInputError(
        f"mismatched configs for experiment '{name}' ({base[name]} vs {cand[name]}): "
        + ", ".join(diff[:5]) + (" ..." if len(diff) > 5 else "")
        + (f"; and for {len(others)} more: {', '.join(others[:5])}{' ...' if len(others) > 5 else ''}" if others else "")
        + (" (other root seeds are not pairs: --unpaired compares them as independent samples)" if seeds_differ else "")
    )


def _percentile_ci(stats: np.ndarray, level: float) -> tuple[float, float]:
    alpha = (1 - level) / 2
    return float(np.quantile(stats, alpha)), float(np.quantile(stats, 1 - alpha))


def _resamples(n: int, n_boot: int, seed: int) -> np.ndarray:
    """``(n_boot, n)`` seed indices drawn with replacement: the pairs resampled together."""
    return np.random.default_rng(seed).integers(0, n, size=(n_boot, n))


def paired_bootstrap_ci(diff: np.ndarray, level: float = 0.95, n_boot: int = 2000, seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap CI of the mean of paired differences (resampling seeds)."""
    diff = np.asarray(diff, dtype=float)
    if diff.size < 2:
        return float("nan"), float("nan")
    return _percentile_ci(diff[_resamples(diff.size, n_boot, seed)].mean(axis=1), level)


def paired_t_ci(diff: np.ndarray, level: float = 0.95) -> tuple[float, float]:
    """Student's t interval of the mean of paired differences, ``mean ± t(n − 1) · s / sqrt(n)``: for differences
    that are noise (two variants over the same seeds), it holds its level at any number of seeds, where the
    percentile bootstrap excludes zero in 16 % of such cases at 5 seeds (nominal 5 %; docs/commands.md)."""
    return mean_ci(diff, level)[1:]


def welch_ci(base: np.ndarray, cand: np.ndarray, level: float = 0.95) -> tuple[float, float]:
    """Welch's t interval of ``mean(cand) − mean(base)`` for independent samples (the sizes may differ). Used
    unpaired rather than a bootstrap: with the few seeds of a run (2–5 per side) a percentile bootstrap of two
    independent means is far too narrow (2 against 2, it excludes zero whenever both candidate values lie on the
    same side of both baseline values: one case in three under no change at all), where Welch's degrees of
    freedom widen the interval as they should."""
    base, cand = np.asarray(base, dtype=float), np.asarray(cand, dtype=float)
    if min(base.size, cand.size) < 2:
        return float("nan"), float("nan")
    d = float(cand.mean() - base.mean())
    vb, vc = base.var(ddof=1) / base.size, cand.var(ddof=1) / cand.size
    if vb + vc == 0:
        return d, d
    dof = (vb + vc) ** 2 / (vb**2 / (base.size - 1) + vc**2 / (cand.size - 1))
    half = float(student_t.ppf(0.5 + level / 2, dof) * np.sqrt(vb + vc))
    return d - half, d + half


def relative_change_ci(base: np.ndarray, cand: np.ndarray, level: float = 0.95, n_boot: int = 2000,
                       seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap CI of the relative change of the means, ``mean(cand) / mean(base) − 1``, resampling the
    pairs (the same draws as :func:`paired_bootstrap_ci`, so the same share of them is below zero when the
    baseline is positive; the verdict stays with that one). For an error metric it stays above −100 %, where
    the CI of the difference divided by the baseline's mean need not: a resample that repeats the seed with the
    largest error changes the difference more than the mean."""
    base, cand = np.asarray(base, dtype=float), np.asarray(cand, dtype=float)
    if base.size < 2:
        return float("nan"), float("nan")
    idx = _resamples(base.size, n_boot, seed)
    mb, mc = base[idx].mean(axis=1), cand[idx].mean(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = (mc - mb) / np.abs(mb)
    if not np.isfinite(rel).all():
        return float("nan"), float("nan")
    return _percentile_ci(rel, level)


COLUMNS = ["baseline", "candidate", "change", "rel_change", "ci_low", "ci_high", "rel_ci_low", "rel_ci_high", "n",
           "n_candidate", "unpaired", "diverged", "verdict", "narrow"]
"""After the cell's keys: the means over the compared runs, change, its CI, the relative change and its CI, ``n``
baseline runs compared (the pairs, when paired) and ``n_candidate`` candidate runs (= ``n`` when paired),
``unpaired`` seeds that only one side ran (left out of the pairing), ``diverged`` candidate runs that diverged
(paired: of the seeds that finished in the baseline), verdict; for a claim, ``narrow``: the side(s)
whose verdict was narrow (``baseline``, ``candidate`` or ``both``; its 95 % interval across the bound), else ''."""


def _one_sided_row(row: dict, b: pd.DataFrame | None, c: pd.DataFrame | None) -> dict:
    """A cell on one side only: its mean there, ``missing`` (baseline only) or ``new`` (candidate only)."""
    def mean(g):
        return np.nan if g is None else g[g["status"] == "ok"]["value"].mean()
    row.update(baseline=mean(b), candidate=mean(c), change=np.nan, rel_change=np.nan, ci_low=np.nan, ci_high=np.nan,
               rel_ci_low=np.nan, rel_ci_high=np.nan, n=0, n_candidate=0, unpaired=0, diverged=0,
               verdict="missing" if c is None else "new", narrow="")
    return row


def _samples(b: pd.DataFrame, c: pd.DataFrame, paired: bool) -> tuple[np.ndarray, np.ndarray, bool, int, int]:
    """The values compared, ``(base, cand, newly_diverged, unpaired, diverged)``. Paired: the seeds both sides ran
    and finished (a seed that diverged only in the candidate makes it worse). Unpaired: every finished run of each
    side (a larger share of diverged runs in the candidate makes it worse). ``diverged``: the candidate's diverged
    runs (paired: of the seeds that finished in the baseline)."""
    if not paired:
        b_ok, c_ok = b["status"] == "ok", c["status"] == "ok"
        return (b["value"][b_ok].to_numpy(), c["value"][c_ok].to_numpy(), bool((~c_ok).mean() > (~b_ok).mean()), 0,
                int((~c_ok).sum()))
    b, c = b.set_index("seed"), c.set_index("seed")
    seeds = b.index.intersection(c.index)
    unpaired = len(b.index.union(c.index)) - len(seeds)
    b, c = b.loc[seeds], c.loc[seeds]
    b_ok, c_ok = b["status"] == "ok", c["status"] == "ok"
    both = b_ok & c_ok
    newly = int((b_ok & ~c_ok).sum())
    return b["value"][both].to_numpy(), c["value"][both].to_numpy(), newly > 0, unpaired, newly


def compare_frames(base: pd.DataFrame, cand: pd.DataFrame, tol: Tolerance = Tolerance(), keys: list[str] = KEYS,
                   paired: bool = True, interval: Interval = "bootstrap") -> pd.DataFrame:
    """One row per cell with baseline, candidate, change, CI and verdict, sorted by severity. Paired, the CI is
    the percentile bootstrap of the differences (the gate's consistency check) or, with ``interval="t"``, their
    Student t interval (:func:`paired_t_ci`: a test of differences that are noise, e.g. two variants)."""
    rows = []
    bg = dict(list(base.groupby(keys, sort=True)))
    cg = dict(list(cand.groupby(keys, sort=True)))
    for cell in sorted(set(bg) | set(cg)):
        row = dict(zip(keys, cell))
        if cell not in cg or cell not in bg:
            rows.append(_one_sided_row(row, bg.get(cell), cg.get(cell)))
            continue
        bv, cv, newly_diverged, unpaired, diverged = _samples(bg[cell], cg[cell], paired)
        bm, cm = float(bv.mean()) if bv.size else np.nan, float(cv.mean()) if cv.size else np.nan
        change = cm - bm
        if paired and interval == "bootstrap":
            lo, hi = paired_bootstrap_ci(cv - bv, tol.level, tol.n_boot)
            rel_lo, rel_hi = relative_change_ci(bv, cv, tol.level, tol.n_boot)
        else:  # the same interval in % of the baseline, so that the markdown's CI and the verdict agree
            lo, hi = paired_t_ci(cv - bv, tol.level) if paired else welch_ci(bv, cv, tol.level)
            rel_lo, rel_hi = (lo / abs(bm), hi / abs(bm)) if bm else (np.nan, np.nan)
        sign = -1.0 if row["metric"] in HIGHER_IS_BETTER else 1.0
        within = abs(change) <= tol.atol + tol.rtol * abs(bm)
        if min(bv.size, cv.size) < 2:  # no interval: paired, the same seeds, so the tolerance decides; unpaired,
            significant = paired      # one fresh run cannot tell a change from the noise
        else:
            significant = not (lo <= 0.0 <= hi)
        if newly_diverged:
            verdict = "worse"
        elif within or not significant or np.isnan(change):
            verdict = "same"
        else:
            verdict = "changed" if row["metric"] in NO_BETTER_SIDE else "worse" if sign * change > 0 else "better"
        row.update(baseline=bm, candidate=cm, change=change, rel_change=change / abs(bm) if bm else np.nan,
                   ci_low=lo, ci_high=hi, rel_ci_low=rel_lo, rel_ci_high=rel_hi, n=bv.size, n_candidate=cv.size,
                   unpaired=unpaired, diverged=diverged, verdict=verdict, narrow="")
        rows.append(row)
    out = pd.DataFrame(rows, columns=keys + COLUMNS)
    out["_sev"] = out["verdict"].map(SEVERITY)
    out["_mag"] = -out["rel_change"].abs().fillna(0)
    return out.sort_values(["_sev", "_mag"] + keys).drop(columns=["_sev", "_mag"]).reset_index(drop=True)


def require_pairs(table: pd.DataFrame, message: str = "baseline and candidate have no cell in common (experiment, "
                  "scenario, variant, signal, metric) and no claim: are these the right directories?") -> None:
    """Refuse a comparison in which no cell and no claim is in both (``message``): a wrong directory or two variants
    never run side by side, not a passing gate."""
    if not table["verdict"].isin((*COUNTED, "changed")).any():
        raise CompareInputError(message)


def load_claims(manifests: dict[str, dict]) -> dict[tuple[str, str], tuple[bool, bool]]:
    """(experiment, claim text) -> (holds, narrowly), from the manifests (claims that could not be checked left
    out)."""
    out = {}
    for name, manifest in manifests.items():
        for c in manifest.get("claims", []):
            if not c.get("not_checked"):
                out[name, c["text"]] = bool(c["holds"]), bool(c.get("narrowly"))
    return out


def machines(manifests: dict[str, dict]) -> set[str]:
    """The CPUs (with numpy's SIMD level) the manifests say the results were computed on."""
    out = set()
    for manifest in manifests.values():
        m = manifest.get("machine")
        if isinstance(m, dict):
            out.add(f"{m.get('cpu', '?')}, numpy {'+'.join(m.get('numpy_simd') or ['baseline'])}")
    return out


def machine_note(base: set[str], cand: set[str]) -> str:
    """One line under the table when the two sides were computed on different hardware, else ''."""
    if not base or not cand or base == cand:
        return ""
    return (f"Computed on different machines (baseline: {'; '.join(sorted(base))}; candidate: "
            f"{'; '.join(sorted(cand))}): numpy and OpenBLAS choose their kernels by CPU, so values can differ in "
            "the last digits without any change of code.")


def compare_claims(base: dict[tuple[str, str], tuple[bool, bool]],
                   cand: dict[tuple[str, str], tuple[bool, bool]]) -> pd.DataFrame:
    """A row per claim (metric ``claim``, the text as signal, 1 = holds): ``worse`` when a claim that held no
    longer does, ``better`` the other way; ``missing``/``new`` as for cells. ``narrow`` names the sides whose verdict
    was narrow: a flip there may be the draw of seeds, not the change."""
    rows = []
    for key in sorted(set(base) | set(cand)):
        (b, b_narrow), (c, c_narrow) = base.get(key, (None, False)), cand.get(key, (None, False))
        verdict = ("missing" if c is None else "new" if b is None else "same" if b == c else "worse" if b else "better")
        narrow = {(True, True): "both", (True, False): "baseline", (False, True): "candidate"}.get((b_narrow, c_narrow), "")
        rows.append({"experiment": key[0], "scenario": "–", "variant": "–", "signal": key[1], "metric": "claim",
                     "baseline": np.nan if b is None else float(b), "candidate": np.nan if c is None else float(c),
                     "change": np.nan, "rel_change": np.nan, "ci_low": np.nan, "ci_high": np.nan, "n": 0,
                     "n_candidate": 0, "unpaired": 0, "diverged": 0, "verdict": verdict, "narrow": narrow})
    return pd.DataFrame(rows, columns=KEYS + COLUMNS)


def _config_name(manifest: dict) -> str | None:
    """The file name of the experiment config a result was run from (its manifest's ``config_files``)."""
    files = manifest.get("config_files")
    path = files.get("experiment") if isinstance(files, dict) else None
    return Path(path).name if isinstance(path, str) else None


# the arguments of compare_error, as the command spells them
CLI_NAMES = {"tol": "--rtol/--atol", "interval": "--interval", "unpaired": "--unpaired", "candidate": "CANDIDATE",
             "variants": "--variants", "pair": "--variants A B"}


def compare_error(candidate: Path | None, variants: tuple[str, str] | None, tol: Tolerance, interval: str | None,
                  paired: bool, names: dict[str, str] = CLI_NAMES) -> str | None:
    """What is wrong with a comparison as asked of ``marinebench compare`` or :func:`marinebench.compare`, in the
    words of ``names`` (the arguments as the caller spells them, :data:`CLI_NAMES`), or None: a tolerance below
    zero (or nan), an interval other than the two, an interval with an unpaired comparison, neither or both of a
    candidate and a pair of variants, or a pair whose two variants are the same (every cell would be 'same')."""
    if not (tol.rtol >= 0 and tol.atol >= 0):  # nan fails too
        return f"{names['tol']}: tolerances must be non-negative numbers"
    if interval not in (None, "bootstrap", "t"):
        return f"{names['interval']}: 'bootstrap' or 't', not '{interval}'"
    if interval is not None and not paired:
        return (f"{names['interval']}: chooses the CI of a paired comparison; {names['unpaired']} always uses "
                "Welch's t interval")
    if variants is None:
        return None if candidate is not None else f"missing {names['candidate']} (or use {names['pair']})"
    if candidate is not None:
        return f"give either {names['candidate']} or {names['pair']}, not both"
    if variants[0] == variants[1]:
        return f"{names['variants']}: A and B are both '{variants[0]}'; name two different variants"
    return None


def comparison(baseline: Path, candidate: Path | None, variants: tuple[str, str] | None, metrics: list[str] | None,
               tol: Tolerance, paired: bool = True, interval: Interval | None = None) -> pd.DataFrame:
    """The comparison :func:`compare_error` found nothing wrong with: ``candidate`` against ``baseline``
    (:func:`compare_dirs`, by default with the bootstrap interval), or the second of ``variants`` against the first
    inside ``baseline`` (:func:`compare_variants`, by default with the t interval)."""
    if variants is not None:
        return compare_variants(baseline, *variants, metrics, tol, paired=paired, interval=interval or "t")
    return compare_dirs(baseline, candidate, metrics, tol, paired=paired, interval=interval or "bootstrap")


def compare_dirs(baseline: Path, candidate: Path, metrics: list[str] | None = None, tol: Tolerance = Tolerance(),
                 paired: bool = True, interval: Interval = "bootstrap") -> pd.DataFrame:
    """Every cell and every claim (from the manifests; with ``metrics``, only if ``claim`` is among them),
    most severe first. ``interval``: of a paired comparison, as in :func:`compare_frames`."""
    bdirs, cdirs = find_results(baseline), find_results(candidate)
    bman, cman = ({name: read_manifest(d) for name, d in dirs.items()} for dirs in (bdirs, cdirs))
    bframe, cframe = load_metrics(bdirs), load_metrics(cdirs)
    renamed = ""
    if len(bdirs) == len(cdirs) == 1 and bdirs.keys() != cdirs.keys():
        (name,), (other,) = bdirs, cdirs
        if (config := _config_name(bman[name])) is not None and config == _config_name(cman[other]):
            # One config's results under two names: a sweep is named for its command-line overrides and seeds
            # (``sweep k delta eps --seed 7 --seeds 5`` writes torben_fig3_sweep_seed=7_5seeds, beside the
            # committed torben_fig3_sweep_5seeds). Compared as one experiment; check_compatible still refuses
            # another world, cells pair only by variant (a sweep's by point), and a line under the table names both.
            cdirs, cman, cframe["experiment"] = {name: cdirs[other]}, {name: cman[other]}, name
            renamed = f"Compared as one experiment: '{other}' (candidate) as '{name}' (baseline), results of one config."
            if _side_by_side(bframe).any() or _side_by_side(cframe).any():  # e.g. a sweep of one of its variants
                bframe, cframe = _sweep_variant_named(bframe, bman), _sweep_variant_named(cframe, cman)
    check_compatible(bdirs, cdirs, paired)
    table = compare_frames(*select_metrics([by_point(bframe), by_point(cframe)], metrics), tol, paired=paired,
                           interval=interval)
    if metrics is None or "claim" in metrics:
        claims = compare_claims(load_claims(bman), load_claims(cman))
        if len(claims):
            table = pd.concat([table, claims], ignore_index=True) if len(table) else claims
            table = table.iloc[table["verdict"].map(SEVERITY).argsort(kind="stable")].reset_index(drop=True)
    require_pairs(table)
    table.attrs["machine_note"] = machine_note(machines(bman), machines(cman))
    table.attrs["renamed"] = renamed
    table.attrs["interval_note"] = T_NOTE if paired and interval == "t" else ""
    return table


T_NOTE = ("The CI is the paired Student t interval of the per-seed differences (in % of the baseline's mean), which "
          "holds its level when they are noise, not the gate's bootstrap.")  # under a table with --interval t


def compare_variants(results: Path, a: str, b: str, metrics: list[str] | None = None, tol: Tolerance = Tolerance(),
                     paired: bool = True, interval: Interval = "t") -> pd.DataFrame:
    """Variant ``b`` (candidate) against variant ``a`` (baseline) inside the same run(s), paired on seed, by default
    with the paired t interval (:func:`paired_t_ci`: their differences are noise); unpaired: as independent samples.
    In a sweep of several variants side by side (``sweep --variants``), point by point: the cells are the sweep's
    points (``variant``: ``<point>: b vs a``, e.g. ``noise=0.6: proposed_d2.2 vs liu_eps0.1``); a tree (``results/``)
    may hold both kinds of folder. Two variants that share no cell are refused (:func:`require_pairs`)."""
    [df] = select_metrics([load_metrics(find_results(results))], metrics, claims=False)
    swept = _side_by_side(df)
    names = df["sweep_variant"].where(swept, df["variant"]) if swept.any() else df["variant"]  # a tree may hold both
    for v in (a, b):
        if v not in set(names):
            raise CompareInputError(f"{results}: no variant '{v}' (have: {_variant_names(df, names, swept)})")
    df = df.assign(point="")
    if swept.any():
        df.loc[swept, "point"] = _points(df[swept])
    keys = ["experiment", "scenario", "point", "signal", "metric"]
    out = compare_frames(df[names == a], df[names == b], tol, keys, paired, interval)
    out.insert(2, "variant", [f"{p}: {b} vs {a}" if p else f"{b} vs {a}" for p in out.pop("point")])
    require_pairs(out, f"{results}: variants '{a}' and '{b}' have no cell in common (experiment, scenario, signal, "
                  "metric; a sweep's point): neither was run beside the other")  # e.g. in other experiments of a tree
    if paired and interval == "t":
        out.attrs["interval_note"] = T_NOTE
    return out


def _variant_names(df: pd.DataFrame, names: pd.Series, swept: pd.Series, most: int = 20) -> str:
    """The variants to name in a refusal: those of runs and of sweeps of several variants, not the points of a
    one-variant sweep (``k_042_dgnss``: hundreds in a tree) unless there is nothing else; at most ``most``."""
    of_runs = df["param"].isna() | swept if "param" in df.columns else pd.Series(True, index=df.index)
    have = sorted(set(names[of_runs])) or sorted(set(names))
    return ", ".join(have[:most]) + (f", … ({len(have)} in all)" if len(have) > most else "")


def _side_by_side(df: pd.DataFrame) -> pd.Series:
    """The rows of sweeps of several variants side by side (``sweep --variants``): those naming their ``sweep_variant``."""
    return df["sweep_variant"].notna() if "sweep_variant" in df.columns else pd.Series(False, index=df.index)


def _sweep_variant_named(df: pd.DataFrame, manifests: dict[str, dict]) -> pd.DataFrame:
    """A frame whose one-variant sweeps' rows name their variant (the manifest's one ``variants``) in ``sweep_variant``
    as a sweep of several variants side by side does, so that the two kinds of folder pair by variant and point
    (``proposed_d2.2: noise=0``), when :func:`compare_dirs` compares two folders of one config. Without a side by side
    sweep on either side, points pair whatever their variant (two one-variant sweeps of two variants)."""
    swept = df["param"].notna() if "param" in df.columns else pd.Series(False, index=df.index)
    one = {name: m["variants"][0] for name, m in manifests.items() if len(m.get("variants") or []) == 1}
    named = df["experiment"].map(one).where(swept & ~_side_by_side(df))
    if named.isna().all():
        return df
    return df.assign(sweep_variant=df["sweep_variant"].fillna(named) if "sweep_variant" in df.columns else named)


def by_point(df: pd.DataFrame) -> pd.DataFrame:
    """A frame whose sweep runs are named by their point (``k=0.5, dgnss``; side by side, ``proposed_d2.2:
    noise_scale=0.6``; :func:`_points`) instead of their variant, which numbers the points (``k_001_dgnss``): between
    two folders, cells pair by what was run, so two sweeps of one config with other ``--n`` pair their common values
    and no others. Runs (no ``param``) keep their variant; points of one experiment that metrics.csv's 7 digits cannot
    tell apart add it (``x=1000 (x_001_default)``)."""
    swept = df["param"].notna() if "param" in df.columns else pd.Series(False, index=df.index)
    if not swept.any():
        return df
    labels = pd.Series(_points(df[swept]), index=df.index[swept])
    if "sweep_variant" in df.columns:
        side = df.loc[swept, "sweep_variant"]
        labels = labels.where(side.isna(), side + ": " + labels)
    runs = df.loc[swept, ["experiment", "variant"]].assign(label=labels)
    # points 7 digits cannot tell apart: one label for several variants of one experiment
    clash = runs.groupby(["experiment", "label"])["variant"].transform("nunique") > 1
    labels = labels.where(~clash, labels + " (" + runs["variant"] + ")")
    return df.assign(variant=df["variant"].where(~swept, labels))


def _points(df: pd.DataFrame) -> list[str]:
    """Each sweep run's point: its parameter value(s) to metrics.csv's 7 digits, and its world group unless that is
    the only ``default`` (``noise=0.6``, ``k=0.3, dgnss``, ``k=0.3, eps=2``; in a tree, a one-at-a-time sweep's rows
    have no ``param2``)."""
    labels = df["param"] + "=" + df["param_value"].map("{:.7g}".format)
    if "param2" in df.columns:
        second = ", " + df["param2"].astype(str) + "=" + df["param2_value"].map("{:.7g}".format)
        labels += np.where(df["param2"].notna(), second, "")
    return list(labels + np.where(df["gnss"] == "default", "", ", " + df["gnss"]))


def headline(table: pd.DataFrame) -> str:
    counts = table["verdict"].value_counts()
    parts = [f"{counts.get(v, 0)} {v}" for v in COUNTED]
    if counts.get("changed", 0):
        parts.insert(2, f"{counts['changed']} changed")
    whole = Counter(one_sided_experiments(table).values())
    for v in ("missing", "new"):
        if counts.get(v, 0):
            n = whole[v]
            parts.append(f"{counts[v]} {v}" + (f" ({n} whole experiment(s) only in the {ONLY_IN[v]})" if n else ""))
    return ", ".join(parts)


def _fmt(x) -> str:
    return "–" if x is None or (isinstance(x, float) and np.isnan(x)) else f"{x:.4g}"


#: How compare's md, json and csv outputs start: ``--output`` replaces a file only when it starts so (a comparison
#: written before).
OUTPUT_HEADS = ("### marinebench compare:", '{\n  "summary":', ",".join(KEYS) + ",")
QUIET = ("same", "new")  # verdicts the markdown summary counts but does not list unless asked
ONLY_IN = {"missing": "baseline", "new": "candidate"}  # the side a one-sided cell or experiment is on
UNPAIRED_NOTE = ("Unpaired: each side's runs are an independent sample (its own seeds and noise); the CI is Welch's t "
                 "interval of the difference of the means, in % of the baseline's, wider than a paired comparison's. "
                 "`seeds`: baseline/candidate runs.")  # under an unpaired comparison's table


def one_sided_experiments(table: pd.DataFrame) -> dict[str, str]:
    """Experiments whose every cell and claim is on one side only -> ``missing`` or ``new``.

    A baseline tree gated against a candidate that ran a subset of the configs (or the other way round)
    differs by whole experiments; the markdown lists each as one row instead of each of its cells.
    """
    per = table.groupby("experiment")["verdict"].agg(lambda v: v.iloc[0] if v.nunique() == 1 else "")
    return {e: v for e, v in per.items() if v in ("missing", "new")}


ICONS = {"worse": "**WORSE**", "better": "**better**", "changed": "changed", "same": "same", "missing": "**missing**",
         "new": "new"}


def _row(r, paired: bool) -> str:
    """One cell of the comparison as a markdown row; a claim (``metric == "claim"``) shows holds/fails per side."""
    if r.metric == "claim":
        held = {1.0: "holds", 0.0: "fails"}
        base, cand = (held.get(v, "–") + (" (narrowly)" if r.narrow in (side, "both") else "")
                      for v, side in ((r.baseline, "baseline"), (r.candidate, "candidate")))
        # a claim's row holds its text in the signal column
        return md_row([ICONS[r.verdict], r.experiment, "–", "–", r.signal, "claim", base, cand, "–", "–", "–"])
    rel = "–" if np.isnan(r.rel_change) else f"{r.rel_change:+.1%}"
    if np.isnan(r.ci_low):
        ci = "–"
    elif not np.isnan(r.rel_ci_low):  # in the units of the change column
        ci = f"[{r.rel_ci_low:+.1%}, {r.rel_ci_high:+.1%}]"
    else:
        ci = f"[{_fmt(r.ci_low)}, {_fmt(r.ci_high)}]"
    seeds = r.n if paired else f"{r.n}/{r.n_candidate}"
    seeds = f"{seeds}, {r.diverged} diverged" if r.diverged else seeds  # the candidate's, left out of the means
    return (f"| {ICONS[r.verdict]} | {r.experiment} | {r.scenario} | {r.variant} | {r.signal} | {r.metric} | "
            f"{_fmt(r.baseline)} | {_fmt(r.candidate)} | {rel} | {ci} | {seeds} |")


def _footnotes(table: pd.DataFrame, shown: pd.DataFrame, whole: dict[str, str], paired: bool) -> list[str]:
    """The lines under the table: the cells not listed, seeds only one side ran, the unpaired caveats."""
    lines = []
    rest = table[~table["experiment"].isin(list(whole))]
    if len(rest) > len(shown):
        counts = rest["verdict"].value_counts()
        what = " and ".join(f"{counts[v]} {v}" for v in QUIET if counts.get(v, 0))
        lines += ["", f"{what} cell(s) not listed (`--all` lists every cell)."]
    unpaired = table[table["unpaired"] > 0]
    if len(unpaired):  # e.g. a candidate run with more (or fewer) seeds than the baseline
        note = (f"{len(unpaired)} cell(s) have seeds that only one side ran (up to {unpaired['unpaired'].max()} per "
                "cell): they are left out, each cell is compared on the seeds both ran (`seeds`).")
        lines += ["", note]
    if not paired:
        lines += ["", UNPAIRED_NOTE]
        single = int(((table[["n", "n_candidate"]].min(axis=1) == 1) & (table["metric"] != "claim")).sum())
        if single:
            note = (f"{single} cell(s) have a single run on a side: unpaired, one run cannot tell a change from the "
                    "noise, so they count as same (run 2 or more --seeds).")
            lines += ["", note]
    return lines


def to_markdown(table: pd.DataFrame, title: str = "marinebench compare", all_cells: bool = False,
                paired: bool = True) -> str:
    """A markdown table of the cells, most severe first (for a PR comment or a CI log).

    ``same`` and ``new`` cells are only counted, in a line under the table, unless ``all_cells``: a full
    reference holds thousands of them, and a gate's reader needs the changed ones. An experiment present on
    one side only is one row (``all_cells`` lists its cells). Unpaired, ``seeds`` is ``baseline/candidate`` runs.
    """
    whole = {} if all_cells else one_sided_experiments(table)
    shown = table if all_cells else table[~table["verdict"].isin(QUIET) & ~table["experiment"].isin(list(whole))]
    lines = [f"### {title}: {headline(table)}", ""]
    lines.append("| verdict | experiment | scenario | variant | signal | metric | baseline | candidate | change | 95% CI of change | seeds |")
    lines.append("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, verdict in sorted(whole.items(), key=lambda kv: (SEVERITY[kv[1]], kv[0])):
        rows = table[table["experiment"] == name]
        n_claims = int((rows["metric"] == "claim").sum())
        what = f"whole experiment, only in the {ONLY_IN[verdict]}: {len(rows) - n_claims} cell(s), {n_claims} claim(s)"
        lines.append(f"| {ICONS[verdict]} | {name} | – | – | {what} | – | – | – | – | – | – |")
    lines += [_row(r, paired) for r in shown.itertuples(index=False)]
    lines += _footnotes(table, shown, whole, paired)
    for attr in ("renamed", "machine_note", "interval_note"):
        if table.attrs.get(attr):
            lines += ["", table.attrs[attr]]
    return "\n".join(lines) + "\n"

