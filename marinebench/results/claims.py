"""The paper's claims about an experiment (``claims:`` in its config), checked on our runs: ``claims.md``.

A claim is checked per scenario and signal on the means over seeds, the numbers the table shows. Beside
the verdict, its statistic (a ratio of means, or the largest value over seeds) gets a 95 % interval over seeds
from its bootstrap standard error (:func:`bootstrap_ci`), the same seed draws resampled for every variant (the
variants of one seed share its world), so a claim that holds on these means but would not on another draw of
seeds is visible: its verdict is marked *narrowly* when the interval reaches across the claim's bound
(:attr:`Check.firm`). Paper values enter only ``near_paper`` claims, and only as the yardstick.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

import numpy as np
import pandas as pd
from scipy.stats import t as student_t

from marinebench.claims import LessClaim, NearPaperClaim, OrderClaim, WithinClaim
from marinebench.config import Experiment
from marinebench.results.tables import md_row, simulated_on


@dataclass(frozen=True)
class Region:
    """The values of a check's statistic that hold (its ``needs`` in numbers): from ``lo`` to ``hi``, the ends
    included when ``closed`` (``≤``, ``within``, ``in [..]``) and not for the strict ``<`` and ``>``."""

    lo: float
    hi: float
    closed: bool = False

    def __contains__(self, x: float) -> bool:
        return self.lo <= x <= self.hi if self.closed else self.lo < x < self.hi


@dataclass
class Check:
    """One scenario (or sweep group) and signal of a claim. ``region``: the values of the statistic that hold,
    to tell whether its interval decides the verdict (:attr:`firm`)."""

    where: str
    signal: str
    means: dict[str, float]
    statistic: float
    ci: tuple[float, float] | None
    needs: str
    holds: bool
    region: Region | None = None

    @property
    def firm(self) -> bool | None:
        """Whether the 95 % interval lies wholly on the verdict's side of the bound: inside ``region`` for a check
        that holds, outside it for one that fails. False: another draw of seeds could give the other verdict (the
        check is *narrow*). None without an interval (one seed, or a largest value over seeds)."""
        if self.ci is None or self.region is None:
            return None
        (a, b), region = self.ci, self.region
        if self.holds:
            return a in region and b in region
        return a not in region and b not in region and not (a < region.lo and b > region.hi)


@dataclass
class ClaimResult:
    claim: object
    metric: str | None
    checks: list[Check] = field(default_factory=list)
    not_checked: str | None = None  # why the claim could not be checked on this experiment

    @property
    def holds(self) -> bool:
        return self.not_checked is None and bool(self.checks) and all(c.holds for c in self.checks)

    @property
    def fails(self) -> bool:
        return self.not_checked is None and not self.holds

    @property
    def narrow(self) -> bool:
        """The verdict rests on narrow checks (:attr:`Check.firm` False): a claim that holds with any of them, a
        claim that fails by them alone. More seeds decide it."""
        if self.not_checked is not None or not self.checks:
            return False
        if self.holds:
            return any(c.firm is False for c in self.checks)
        return all(c.firm is False for c in self.checks if not c.holds)


def _per_seed(metrics: pd.DataFrame, scenario: str, variant: str, signal: str, metric: str) -> pd.Series:
    sel = metrics[(metrics["scenario"] == scenario) & (metrics["variant"] == variant) & (metrics["signal"] == signal)
                  & (metrics["metric"] == metric) & (metrics["status"] == "ok")]
    return sel.set_index("seed")["value"].astype(float)


def bootstrap_ci(values: list[np.ndarray], stat: Callable[..., np.ndarray], level: float = 0.95, n_boot: int = 2000,
                 seed: int = 0, scale: Literal["linear", "log"] = "linear",
                 bounds: tuple[float, float] = (-math.inf, math.inf)) -> tuple[float, float] | None:
    """Interval of the statistic ``stat`` over seeds: the statistic ± the Student-t quantile (n − 1 degrees of
    freedom) times its bootstrap standard error, the seeds (rows, aligned across ``values``) resampled together and
    the spread of the resampled statistic scaled by sqrt(n / (n − 1)) (a resample's plug-in bias).

    ``stat`` takes every resample at once: each of ``values`` with a leading axis of resamples (``(n_boot, n, ...)``
    for a value of shape ``(n, ...)``; the statistic itself is that of the one "resample" ``values[None]``), and
    returns one statistic per resample (``(n_boot,)``), e.g. ``lambda x, y: x.mean(axis=1) / y.mean(axis=1)``. A
    reduction over the seeds of one resample is the same floating-point sum as over the seeds themselves, so the
    interval is that of a statistic taken resample by resample, at a small fraction of the cost (the claims of a
    sweep check thousands of resamples at each of hundreds of points).

    ``scale="log"`` (a ratio of means): the interval of the statistic's log, mapped back, so that it stays positive
    and is as asymmetric as a ratio's (linear when the statistic or a resample is not positive). ``bounds`` clips
    the interval to the statistic's range (Spearman's ρ: [−1, 1]).

    Why not the percentiles of the resampled statistic: with a run's few seeds they are too narrow (the resamples
    only recombine the seeds drawn). Their nominal 95 % covers a ratio of means in 74 % of draws at 3 seeds and
    82 % at 5, where this interval covers 94 % and 92 % (``coverage`` in tests/test_claims.py measures both)."""
    n = len(values[0])
    if n < 2:
        return None
    with np.errstate(divide="ignore", invalid="ignore"):  # a zero mean makes the statistic infinite or nan
        estimate = float(stat(*(v[None] for v in values))[0])
        idx = np.random.default_rng(seed).integers(0, n, size=(n_boot, n))
        draws = np.asarray(stat(*(v[idx] for v in values)), dtype=float)
    draws = draws[np.isfinite(draws)]
    if not math.isfinite(estimate) or draws.size < 2:
        return None
    if np.ptp(draws) <= 1e-12 * abs(estimate):  # the same value on every seed (to rounding)
        return estimate, estimate
    log = scale == "log" and estimate > 0 and bool((draws > 0).all())
    centre, spread = (math.log(estimate), np.log(draws).std()) if log else (estimate, draws.std())
    half = float(student_t.ppf(0.5 + level / 2, n - 1) * spread * math.sqrt(n / (n - 1)))
    lo, hi = (math.exp(centre - half), math.exp(centre + half)) if log else (centre - half, centre + half)
    return max(lo, bounds[0]), min(hi, bounds[1])


def ratio_of_means(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """:func:`bootstrap_ci`'s statistic for ``less``, ``order`` and ``within`` (rtol): mean(x) / mean(y) per resample."""
    return x.mean(axis=1) / y.mean(axis=1)


def _largest_over_smallest_mean(*xs: np.ndarray) -> np.ndarray:
    """:func:`bootstrap_ci`'s statistic for ``within`` (factor): the largest variant mean over the smallest."""
    means = np.stack([x.mean(axis=1) for x in xs])
    return means.max(axis=0) / means.min(axis=0)


def _ratio(a: float, b: float) -> float:
    """``a / b`` as a claim's statistic: nan for 0/0 and +-inf for x/0, so such a check fails, not the run."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return float(np.float64(a) / np.float64(b))


def _aligned(series: list[pd.Series]) -> list[np.ndarray]:
    common = series[0].index
    for s in series[1:]:
        common = common.intersection(s.index)
    return [s.loc[common].to_numpy() for s in series]


def _scenarios(exp: Experiment, metrics: pd.DataFrame, claim, variants: list[str], metric: str) -> list[str]:
    if claim.scenarios is not None:
        return list(claim.scenarios)
    have = metrics[metrics["metric"] == metric].groupby("scenario")["variant"].agg(set)
    return [s for s in exp.scenario_names if s in have.index and set(variants) <= have[s]]


def _paper_value(exp: Experiment, variant: str, scenario: str, metric: str, signal: str) -> float | None:
    values = exp.table.paper.values.get(variant, {})
    key = signal if exp.scenarios is None else f"{scenario}/{metric}/{signal}"
    return values.get(key)


def evaluate(exp: Experiment, metrics: pd.DataFrame) -> list[ClaimResult]:
    """Check every claim of ``exp`` on its tidy metrics (``metrics.csv``)."""
    results = []
    for claim in exp.claims:
        metric = exp.claim_metric(claim)
        res = ClaimResult(claim, metric, not_checked=exp.claim_problem(claim))
        if res.not_checked is not None:
            results.append(res)
            continue
        if isinstance(claim, NearPaperClaim):
            variants = claim.variants or [v.name for v in exp.variants if v.name in exp.table.paper.values]
        else:
            variants = claim.variant_names
        for scenario in _scenarios(exp, metrics, claim, variants, metric):
            for signal in exp.claim_signals(claim):
                res.checks += _checks(exp, metrics, claim, variants, scenario, signal, metric)
        results.append(res)
    return results


@dataclass
class _Cell:
    """One scenario and signal of a claim: each variant's values over seeds, and their means."""

    scenario: str
    signal: str
    series: dict[str, pd.Series]

    @cached_property
    def means(self) -> dict[str, float]:
        """Each variant's mean over seeds (computed once per cell, shared by its checks)."""
        return {v: float(s.mean()) if len(s) else math.nan for v, s in self.series.items()}

    def check(self, stat: float, ci, needs: str, region: Region, shown: list[str]) -> Check:
        """The check of ``stat``: it holds when it is finite and in ``region`` (``needs`` says it in words)."""
        return Check(self.scenario, self.signal, {v: self.means[v] for v in shown}, stat, ci, needs,
                     math.isfinite(stat) and stat in region, region)


def _checks(exp, metrics, claim, variants, scenario, signal, metric) -> list[Check]:
    cell = _Cell(scenario, signal, {v: _per_seed(metrics, scenario, v, signal, metric) for v in variants})
    if isinstance(claim, LessClaim):
        return _ratio_checks(cell, [(claim.a, other) for other in claim.others], claim.factor)
    if isinstance(claim, OrderClaim):  # consecutive pairs of the listed order
        return _ratio_checks(cell, list(zip(claim.variants[:-1], claim.variants[1:], strict=True)), 1.0)
    if isinstance(claim, WithinClaim):
        return _within_checks(cell, claim, variants)
    if isinstance(claim, NearPaperClaim):
        return _near_paper_checks(exp, cell, claim, variants, metric)
    worst = float(cell.series[claim.a].max()) if len(cell.series[claim.a]) else math.nan  # AtMostClaim
    return [cell.check(worst, None, f"≤ {claim.value:g}", Region(-math.inf, claim.value, closed=True), variants)]


def _ratio_checks(cell: _Cell, pairs: list[tuple[str, str]], factor: float) -> list[Check]:
    """``less`` and ``order``: mean(lo) / mean(hi) < factor for each pair."""
    out, means = [], cell.means
    for lo, hi in pairs:
        a, b = _aligned([cell.series[lo], cell.series[hi]])
        ratio = _ratio(means[lo], means[hi])
        ci = bootstrap_ci([a, b], ratio_of_means, scale="log")
        out.append(cell.check(ratio, ci, f"< {factor:g}", Region(-math.inf, factor), [lo, hi]))
    return out


def _within_checks(cell: _Cell, claim: WithinClaim, variants: list[str]) -> list[Check]:
    """``within``: the largest over the smallest mean at most ``factor`` (one check), or each variant within
    ``1 ± rtol`` of the first."""
    means = cell.means
    if claim.factor is not None:
        ratio = _ratio(max(means.values()), min(means.values()))
        ci = bootstrap_ci(_aligned(list(cell.series.values())), _largest_over_smallest_mean, scale="log")
        return [cell.check(ratio, ci, f"≤ {claim.factor:g}", Region(-math.inf, claim.factor, closed=True), variants)]
    first, out = variants[0], []
    for other in variants[1:]:
        x, y = _aligned([cell.series[other], cell.series[first]])
        ratio = _ratio(means[other], means[first])
        ci = bootstrap_ci([x, y], ratio_of_means, scale="log")
        out.append(cell.check(ratio, ci, f"within 1 ± {claim.rtol:g}", Region(1 - claim.rtol, 1 + claim.rtol, closed=True),
                              [first, other]))
    return out


def _near_paper_checks(exp, cell: _Cell, claim: NearPaperClaim, variants: list[str], metric: str) -> list[Check]:
    """``near_paper``: each variant's mean (in the table's display scale) within a factor of the paper's value."""
    out, means = [], cell.means
    for v in variants:
        paper = _paper_value(exp, v, cell.scenario, metric, cell.signal)
        if paper is None:
            continue
        d = exp.table.display.get(f"{metric}/{cell.signal}")
        scale = d.scale if d is not None else 1.0
        ratio = means[v] * scale / paper
        ci = bootstrap_ci([cell.series[v].to_numpy()], lambda x, p=paper, k=scale: x.mean(axis=1) * k / p,
                          scale="log")
        region = Region(1 / claim.factor, claim.factor, closed=True)
        out.append(Check(cell.scenario, cell.signal, {v: means[v], "paper": paper / scale}, ratio, ci,
                         f"in [{region.lo:.3g}, {region.hi:g}]", ratio in region, region))
    return out


def _num(x: float) -> str:
    return "–" if x is None or not math.isfinite(x) else f"{x:.3g}"


def summary_line(results: list[ClaimResult]) -> str:
    skipped, narrow = sum(r.not_checked is not None for r in results), sum(r.narrow for r in results)
    return (f"{sum(r.holds for r in results)} of {len(results)} claims hold" + (f", {skipped} not checked" if skipped else "")
            + (f"; {narrow} narrowly (a 95% interval across the bound)" if narrow else ""))


#: claims.md's note on narrow verdicts, when it has any.
NARROW_NOTE = ("*Narrowly*: the 95% interval of the check reaches across the bound, so another draw of seeds could "
               "give the other verdict; more seeds (`--seeds N`) decide it.")


def _verdict(holds: bool, narrow: bool) -> str:
    return ("holds" if holds else "**fails**") + (" (narrowly)" if narrow else "")


def on_seeds(seeds: int) -> str:
    """What a claims.md's checks ran on, for its preamble."""
    return f"our means over {seeds} seeds" if seeds > 1 else "one seed"


def statistic_note(seeds: int) -> str:
    """The sentence of a claims.md's preamble on the statistic and its interval (none from one seed)."""
    return ("The statistic is what the claim bounds (a ratio of means; the largest value over seeds for `≤` claims; "
            "Spearman's ρ for trends)" + (", with a 95% interval over seeds: Student's t on its bootstrap standard "
                                          "error (the same seeds resampled for every variant; in log for ratios)."
                                          if seeds > 1 else "; one seed gives no interval."))


def markdown(exp: Experiment, results: list[ClaimResult], where: str = "scenario", title: str | None = None) -> str:
    """``claims.md``: the verdict per claim, then every check with its numbers (``where``: the heading of
    the column of scenarios, or of groups for a sweep)."""
    title = title or (exp.table.title if exp.table is not None else exp.name)
    lines = [f"## Claims checked: {title}", "",
             (f"Checked on {on_seeds(exp.seeds)}, root seed {exp.seed}, per {where} and signal."
              f"{simulated_on(exp.model_label())} "
              f"{statistic_note(exp.seeds)} A claim holds when every check holds on the means."
              + (f" {NARROW_NOTE}" if any(r.narrow for r in results) else "")), "",
             f"**{summary_line(results)}.**", "",
             "| # | verdict | claim | source | metric |", "|---|---|---|---|---|"]
    for i, r in enumerate(results, 1):
        verdict = _verdict(r.holds, r.narrow) if r.not_checked is None else f"not checked: {r.not_checked}"
        lines.append(md_row([i, verdict, r.claim.text, r.claim.source, r.metric or "–"]))
    lines += ["", f"| # | {where} | signal | means | statistic [95% CI] | needs | check |", "|---|---|---|---|---|---|---|"]
    for i, r in enumerate(results, 1):
        if not r.checks and r.not_checked is None:
            lines.append(f"| {i} | – | – | no data | – | – | **fails** |")
        lines += [format_check(i, c) for c in r.checks]
    return "\n".join(lines) + "\n"


def format_check(i: int, c: Check, where: str | None = None) -> str:
    """One row of the checks table of claim ``i`` (``where``: the first column, default the check's own)."""
    means = ", ".join(f"{v} {_num(m)}" for v, m in c.means.items())
    stat = _num(c.statistic) + (f" [{_num(c.ci[0])}, {_num(c.ci[1])}]" if c.ci else "")
    return md_row([i, where or c.where, c.signal, means, stat, c.needs, _verdict(c.holds, c.firm is False)])


def manifest_entries(results: list[ClaimResult]) -> list[dict]:
    return [{"text": r.claim.text, "source": r.claim.source, "holds": r.holds}
            | ({"not_checked": r.not_checked} if r.not_checked else {}) | ({"narrowly": True} if r.narrow else {})
            for r in results]
