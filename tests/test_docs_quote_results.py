"""The README and docs quote the committed results; each quote here is recomputed from them: means and intervals
from `results/*/metrics.csv`, a sweep's paired changes from its `table.md`, timings from its `manifest.json`.

A rerun that moves a committed number, or an edit of the prose that changes a quoted one, fails here and names the
sentence to update. A quote is a literal piece of the document with ``{}`` where a number stands; each number must
equal its recomputed value to the precision it is printed with (half a unit of its last digit).
"""

from __future__ import annotations

import importlib.util
import json
import re
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from marinebench.metrics.stats import mean_ci

ROOT = Path(__file__).resolve().parents[1]
NUMBER = r"[−+-]?\d+(?:\.\d+)?(?:e[−+-]?\d+)?"


@cache
def _metrics(experiment: str) -> pd.DataFrame:
    return pd.read_csv(ROOT / "results" / experiment / "metrics.csv")


def values(experiment: str, variant: str, signal: str, metric: str, scenario: str | None = None) -> np.ndarray:
    """One cell's values over the seeds of a committed experiment (runs that diverged left out, as the tables do)."""
    m = _metrics(experiment)
    sel = (m.variant == variant) & (m.signal == signal) & (m.metric == metric) & (m.status == "ok")
    if scenario is not None:
        sel &= m.scenario == scenario
    v = m.loc[sel, "value"].to_numpy()
    assert v.size, f"results/{experiment}: no cell {scenario}/{variant}/{signal}/{metric}"
    return v


def mean(*cell, scale: float = 1.0) -> float:
    return float(values(*cell).mean()) * scale


def change(a: tuple, b: tuple) -> float:
    """a vs b in %, on the means (the tables' relative rows)."""
    return 100 * (mean(*a) / mean(*b) - 1)


def noise_part(experiment: str, variant: str, signal: str) -> float:
    """The noise's share of a noisy-world std, sqrt(noisy^2 - noise-free^2) of the means (independent parts)."""
    noisy, free = (mean(experiment, variant, signal, "std", scen) for scen in ("noisy", "noise_free"))
    return float(np.sqrt(noisy**2 - free**2))


@cache
def manifest(experiment: str) -> dict:
    """A committed result's ``manifest.json`` (read once)."""
    return json.loads((ROOT / "results" / experiment / "manifest.json").read_text())


def design(experiment: str, variant: str, key: str, scenario: str = "noisy") -> float:
    """A value of a variant's observer design as the manifest records it."""
    return manifest(experiment)["designs"][scenario][variant][key]


def table_row(path: str, start: str) -> list[float]:
    """The numbers of the row of a generated ``table.md`` that starts with ``start`` (those after it)."""
    for line in (ROOT / "results" / path).read_text().splitlines():
        if line.startswith(start):
            return [float(x) for x in re.findall(NUMBER, line[len(start):])]
    raise AssertionError(f"results/{path}: no row starting {start!r}")


@dataclass(frozen=True)
class Quote:
    doc: str
    text: str  # literal, with {} for each checked number
    computed: Callable[[], list[float]]

    def __str__(self) -> str:
        return f"{self.doc}: {self.text}"


T4 = "bejarano_table4"
T3B = "bejarano_table3"
F45, F7, KW = "bejarano_fig4_5", "bejarano_fig7", ("0.1", "1", "10", "100")
SIX = "| {} | {} | {} | {} | {} | {} |"  # a table row's six numbers
T3 = "tijjani_table3"
OBS = "tijjani_observers"
OBS0 = "tijjani_observers_no_initial_error"
TUNED = "tijjani_tuned"
cm, e2 = 100.0, 100.0  # metres -> cm; the docs' e-2 m / e-2 rad


def _paper(experiment: str) -> dict[str, dict[str, float]]:
    """The paper's values of a committed config's table (labelled as the paper's there), per variant and signal."""
    return yaml.safe_load((ROOT / "configs" / f"{experiment}.yaml").read_text())["table"]["paper"]["values"]


def _fig2_ratios(experiment: str) -> list[float]:
    """CDO over EO, ratios of the means, as Fig. 2's claims check them: RMSE against the truth and against the
    samples, then the rate-estimate and the depth/yaw-estimate peaks (depth, yaw each)."""
    cells = [("depth", "rmse"), ("yaw", "rmse"), ("depth_meas", "rmse"), ("yaw_meas", "rmse"), ("depth_rate", "peak"),
             ("yaw_rate", "peak"), ("depth", "peak_output"), ("yaw", "peak_output")]
    return [mean(experiment, "cdo", s, m) / mean(experiment, "eo", s, m) for s, m in cells]


def _sweep_ratios(sweep: str, param: str) -> list[float]:
    """CDO over EO along a committed observer sweep's parameter (both observers' RMSE against the truth in every run):
    the lowest and highest ratio of the means over the points, depth then yaw."""
    m = _metrics(sweep)
    m = m[(m.metric == "rmse_each") & (m.param == param) & (m.status == "ok")]
    means = m.groupby(["param_value", "signal"])["value"].mean().unstack("signal")
    depth, yaw = (means[f"{s}_cdo"] / means[f"{s}_eo"] for s in ("depth", "yaw"))
    return [depth.min(), depth.max(), yaw.min(), yaw.max()]


def _depth_noise_but_the_cycle() -> list[float]:
    """CDO over EO in depth along the depth noise from the assumed initial error: the lowest and highest ratio apart from
    the one point below 1 (where the EO-watched loop is in the depth limit cycle: the EO's RMSE jumps), that point's
    ratio and its noise in mm."""
    m = _metrics(f"{OBS}_sweep_5seeds")
    m = m[(m.metric == "rmse_each") & (m.param == "depth_noise") & (m.status == "ok")]
    means = m.groupby(["param_value", "signal"])["value"].mean().unstack("signal")
    ratio = means["depth_cdo"] / means["depth_eo"]
    below = ratio[ratio < 1]
    assert len(below) == 1 and means["depth_eo"].idxmax() == below.index[0], "not one point, nor the EO's jump"
    rest = ratio.drop(below.index)
    return [rest.min(), rest.max(), below.iloc[0], below.index[0] * 1000]


def _reaches(x: np.ndarray, y: np.ndarray, level: float, what: str) -> float:
    """Where the curve ``y(x)`` first reaches ``level``, linear between its points (not at the first point)."""
    i = int(np.argmax(y >= level))
    assert 0 < i and y[i] >= level, f"{what}: the ratio never crosses {level}"
    return float(np.interp(level, y[i - 1:i + 1], x[i - 1:i + 1]))


def _crossings(sweep: str, param: str, dof: str, levels=(0.8, 1.0)) -> list[float]:
    """Where CDO over EO (ratio of the mean RMSE against the truth) first reaches each of ``levels`` along a committed
    observer sweep's parameter, linear between its points."""
    m = _metrics(sweep)
    m = m[(m.metric == "rmse_each") & (m.param == param) & (m.status == "ok")]
    means = m.groupby(["param_value", "signal"])["value"].mean().unstack("signal")
    ratio = (means[f"{dof}_cdo"] / means[f"{dof}_eo"]).to_numpy()
    x = means.index.to_numpy()
    return [_reaches(x, ratio, level, f"{sweep}: {dof}") for level in levels]


def _noise_grid(signal: str, sweep: str = "bejarano_fig4_5_sweep_grid_delta_p1_noise_scale_5seeds",
                at: float = 3.0, vs: float = 0.5) -> list[float]:
    """A Bejarano tuning x position-noise grid: the error at tuning ``at`` over that at ``vs`` without noise and at
    the full noise (scale 1), and the noise scale at which the ratio is 1 (linear between the grid's slices)."""
    m = _metrics(sweep)
    m = m[(m.metric == "std") & (m.signal == signal) & (m.status == "ok")]
    means = m.groupby(["param2_value", "param_value"])["value"].mean().unstack("param_value")
    column = {c: means.columns[np.argmin(np.abs(np.log(means.columns / c)))] for c in (at, vs)}
    assert all(np.isclose(column[c], c) for c in column), f"{sweep}: {at} or {vs} is not on the grid"
    ratio = means[column[at]] / means[column[vs]]
    x, y = ratio.index.to_numpy(), ratio.to_numpy()
    assert np.all(np.diff(y) > 0), f"{signal}: the ratio does not rise along the noise"
    return [y[0], float(ratio.loc[np.isclose(x, 1.0)].iloc[0]), _reaches(x, y, 1.0, f"{sweep}: {signal}")]


FIG7_GRID = "bejarano_fig7_sweep_grid_k_omega_noise_scale_n13_5seeds"
TABLE4_NOISE = "bejarano_table4_sweep_noise_scale_liu_eps0.1+proposed_d1.2+proposed_d2.2_n11_5seeds"
TABLE3_YAW_NOISE = "tijjani_table3_sweep_yaw_noise_rise+srise+cdo_srise_5seeds"


def _curves(sweep: str, metric: str, signal: str) -> pd.DataFrame:
    """A sweep of several variants side by side: the mean over seeds at each point (rows), per variant (columns)."""
    m = _metrics(sweep)
    m = m[(m.metric == metric) & (m.signal == signal) & (m.status == "ok")]
    return m.groupby(["param_value", "sweep_variant"])["value"].mean().unstack("sweep_variant")


def _side_by_side(sweep: str, metric: str, signal: str, top: str, bottom: str) -> pd.Series:
    """The mean curve of ``top`` over that of ``bottom``, point by point."""
    means = _curves(sweep, metric, signal)
    return means[top] / means[bottom]


FIG1_GNSS = "torben_fig1_sweep_npo+resetting_5seeds"


def _fig1_over_gnss() -> dict[str, float]:
    """Torben Figs 1-2 along the GNSS noise: the transient ratio's range, the last noise level where the steady
    ratio is 1 (to 1e-6) before it rises, the resetting observer's jumps at the third level and where the steady ratio
    is highest, that highest (and where) and the steady ratio at 3 m."""
    transient, steady = (_side_by_side(FIG1_GNSS, m, "z", "resetting", "npo") for m in ("J_tot_transient", "J_tot_steady"))
    jumps = _curves(FIG1_GNSS, "n_jumps", "z")["resetting"]
    x = steady.index.to_numpy()
    on = np.abs(steady.to_numpy() - 1) <= 1e-6
    assert on[0] and not on[int(np.argmin(on))] and not on[int(np.argmin(on)):].any(), "steady ratio: not one stretch at 1"
    return {"transient": [transient.min(), transient.max()], "equal_to": x[int(np.argmin(on)) - 1],
            "jumps": [jumps.iloc[2], x[2], jumps.iloc[int(np.argmax(steady.to_numpy()))], x[int(np.argmax(steady.to_numpy()))]],
            "steady": [steady.max(), x[int(np.argmax(steady.to_numpy()))], steady.iloc[-1]]}


FIG1_GRID = "torben_fig1_sweep_grid_c_eps_gnss_sigma_set-b9193cf0_5seeds"
FIG1_NPO = "torben_fig1_sweep_n11_sweep.variant=npo_5seeds"


def _fig1_grid_over_npo(metric: str) -> pd.DataFrame:
    """The resetting observer's c_ε x GNSS-noise grid on Figs 1-2's world over the NPO on the same σ points and seeds:
    rows c_ε, columns σ, ratio of the means."""
    grid, npo = _metrics(FIG1_GRID), _metrics(FIG1_NPO)
    ours = grid[grid.metric == metric].groupby(["param_value", "param2_value"])["value"].mean().unstack()
    theirs = npo[npo.metric == metric].groupby("param_value")["value"].mean()
    assert np.allclose(ours.columns, theirs.index), "the NPO sweep's σ points are not the grid's"
    return ours / theirs.to_numpy()


def _fig1_eps_needed() -> list[float]:
    """The transient ratio's highest on the grid; the last σ up to which the steady ratio is 1 (to 0.1 %) at c_ε = 3.98
    and at 6.31, the latter's ratio at 1.99 m, and the steady ratio's range for c_ε <= 1."""
    steady = _fig1_grid_over_npo("J_tot_steady")

    def equal_up_to(row: pd.Series) -> float:
        on = np.abs(row.to_numpy() - 1) <= 1e-3
        return float(row.index[int(np.argmin(on)) - 1]) if not on.all() else float(row.index[-1])

    c398, c631 = (steady.iloc[int(np.argmin(np.abs(np.log(steady.index / c))))] for c in (3.98, 6.31))
    low = steady[steady.index <= 1.0]
    return [_fig1_grid_over_npo("J_tot_transient").max().max(), equal_up_to(c398), equal_up_to(c631),
            c631.iloc[int(np.argmin(np.abs(c631.index - 1.99)))], low.min().min(), low.max().max()]


def _fig1_eps_claim() -> list[float]:
    """J(c_ε = 0.1)/J(c_ε = 5) on Figs 1-2's world (5 interpolated in log, per seed): the ratio of the means and the
    per-seed range at σ = 0.113, 1.32 and 1.99 m; then the steady and transient ratios at 0.113 m."""
    m = _metrics(FIG1_GRID)

    def at(metric: str, sigma: float) -> np.ndarray:
        part = m[(m.metric == metric) & np.isclose(m.param2_value, sigma, rtol=1e-3)]
        t = part.pivot_table(index="param_value", columns="seed", values="value")
        five = np.array([np.interp(np.log(5.0), np.log(t.index.to_numpy()), t[c].to_numpy()) for c in t.columns])
        return t.iloc[0].to_numpy(), five

    out = []
    for sigma in (0.113397, 1.32279, 1.992077):
        low, five = at("J_tot", sigma)
        out.append([low.mean() / five.mean(), (low / five).min(), (low / five).max()])
    (a, b, c), (d, e, f), (g, h, i) = out
    steady, transient = (np.divide(*(x.mean() for x in at(k, 0.113397))) for k in ("J_tot_steady", "J_tot_transient"))
    return [a, b, c, d, g, e, f, h, i, steady, transient]


def _cross_over_gnss() -> pd.Series:
    """Liu ε = 0.1's steady-state sway RMSE in the DP world along the GNSS noise level (mean over seeds)."""
    m = _metrics("cross_dp_impulse_sweep_5seeds")
    m = m[(m.param == "gnss_sigma") & (m.signal == "v") & (m.metric == "rmse_steady") & (m.status == "ok")]
    return m.groupby("param_value")["value"].mean()


def _table4_over_noise() -> list[float]:
    """e_u of δ = 2.2 over Liu ε = 0.1 without noise and at twice it (never below 1), and over δ = 1.2: where it
    reaches 1, and at 0.2 and 0.4 of the noise."""
    liu, d12 = (_side_by_side(TABLE4_NOISE, "std", "u", "proposed_d2.2", v) for v in ("liu_eps0.1", "proposed_d1.2"))
    assert liu.min() > 1, "δ = 2.2 beats Liu ε = 0.1 at some noise level"
    x = d12.index.to_numpy()
    return [liu.iloc[0], liu.iloc[-1], _reaches(x, d12.to_numpy(), 1.0, "δ = 2.2 / δ = 1.2"),
            d12.loc[np.isclose(x, 0.2)].iloc[0], d12.loc[np.isclose(x, 0.4)].iloc[0]]


def _yaw_noise_int() -> list[float]:
    """S+RISE's S1 yaw INT over RISE's along the yaw-sample noise: at the lowest noise, where it reaches 1 and 1.5
    (linear in the log of the noise, as the sweep is log-spaced), its highest and where, and at the highest noise."""
    r = _side_by_side(TABLE3_YAW_NOISE, "int", "yaw", "srise", "rise")
    x, y = np.log(r.index.to_numpy()), r.to_numpy()
    return [y[0], *(np.exp(_reaches(x, y, level, "yaw INT")) for level in (1.0, 1.5)), y.max(), np.exp(x[y.argmax()]), y[-1]]


def _eps_over_noise() -> list[float]:
    """Torben's c_ε x GNSS-noise grid: J(c_ε = 5) / J(c_ε = 0.1) on each noise slice (5 interpolated in log, as the
    sweep's probes are), lowest and highest."""
    m = _metrics("torben_fig3_sweep_grid_eps_gnss_sigma_dgnss_set-991959b4_5seeds")
    m = m[(m.metric == "J_tot") & (m.status == "ok")]
    means = m.groupby(["param2_value", "param_value"])["value"].mean().unstack("param_value")
    ratios = [np.interp(np.log(5.0), np.log(means.columns.to_numpy()), row) / row[0] for row in means.to_numpy()]
    return [min(ratios), max(ratios)]


def _table3() -> dict[str, list[float]]:
    """Table III: our Liu rows over the paper's (lowest, highest ratio over their twelve cells), and the proposed
    d = 0.05 row over our Liu eps = 0.1's (lowest, highest over the six errors)."""
    paper = _paper(T3B)
    liu = [mean(T3B, v, sig, "std") / value for v, row in paper.items() if v.startswith("liu") for sig, value in row.items()]
    slow = [mean(T3B, "proposed_d0.05", sig, "std") / mean(T3B, "liu_eps0.1", sig, "std") for sig in paper["liu_eps0.1"]]
    return {"liu": [min(liu), max(liu)], "slow": [min(slow), max(slow)]}


def _table4_ratios() -> list[float]:
    """Table IV's ours / paper over its 16 cells: the largest factor either way, then the lowest and highest ratio
    (the paper's values from the config, where they are labelled as the paper's)."""
    paper = _paper(T4)
    ratios = [mean(T4, v, sig, "std") / value for v, row in paper.items() for sig, value in row.items()]
    return [max(max(ratios), 1 / min(ratios)), min(ratios), max(ratios)]


def _fig1() -> list[float]:
    m, lo, hi = mean_ci(values("torben_fig1", "resetting", "z", "J_tot_transient"))
    npo = mean("torben_fig1", "npo", "z", "J_tot_transient")
    return [m, lo, hi, npo, 100 * (m / npo - 1)]


def _eps_changes() -> list[float]:
    """J(c_eps = 0.1) vs J(c_eps = 5) in % with its interval, differential then dual-band (the 20-seed sweep)."""
    rows = [table_row("torben_fig3_sweep_eps_20seeds/table.md", f"| eps | {g} | z | 0.1 |") for g in ("dgnss", "dualband")]
    return [x for row in rows for x in row[3:]]


def _fig3_change(sweep: str, param: str, gnss: str, value: str) -> list[float]:
    """A Fig. 3 sweep's change at a probe value against the first probe (with its interval over several seeds)."""
    row = table_row(f"{sweep}/table.md", f"| {param} | {gnss} | z | {value} |")
    return row[1:] if len(row) == 2 else row[3:]


def _fig3_trend(param: str, value: str, *, rho: bool = False) -> list[float]:
    """docs/torben.md's Fig. 3 table row: per GNSS model, the 1-seed then the 5-seed change (with the Spearman
    rho over the trend range first, for delta)."""
    out = []
    for gnss in ("dgnss", "dualband"):
        for sweep in ("torben_fig3_sweep", "torben_fig3_sweep_5seeds"):
            if rho:
                out.append(table_row(f"{sweep}/table.md", f"| {param} | {gnss} | z | [2.5, 10] |")[-1])
            out += _fig3_change(sweep, param, gnss, value)
    return out


SEA = "torben_fig3_sweep_npo+resetting_n9_world.hs=0..4_5seeds"


@cache
def _sea_state() -> list[float]:
    """docs/torben.md, the sea state: J_tot of each observer at Hs 0 and 4 m, then J_resetting/J_NPO per seed (mean,
    95 % Student-t interval) at 0 and 4 m, differential GNSS first."""
    m = _metrics(SEA)
    m = m[m.metric == "J_tot"]
    at = {(g, h): m[(m.gnss == g) & (m.param_value == h)].pivot(index="seed", columns="sweep_variant", values="value")
          for g in ("dgnss", "dualband") for h in (0.0, 4.0)}
    means = [at[g, h][v].mean() for v in ("npo", "resetting") for g in ("dgnss", "dualband") for h in (0.0, 4.0)]
    ratios = []
    for g in ("dgnss", "dualband"):
        for h in (0.0, 4.0):
            ratios += mean_ci((at[g, h]["resetting"] / at[g, h]["npo"]).to_numpy())
    return means + ratios


PEAK = "torben_fig3_sweep_npo+resetting_n7_world.waves.tp=4..10_5seeds"


@cache
def _peak_period() -> list[float]:
    """docs/torben.md, the peak period: the NPO's J_tot range (differential), J_resetting/J_NPO's range from Tp 6 s up
    (differential), then its mean and interval at 5 s (differential) and at 4 s (differential, dual-band)."""
    m = _metrics(PEAK)
    m = m[m.metric == "J_tot"]

    def ratio(gnss: str, tp: float) -> tuple[float, float, float]:
        at = m[(m.gnss == gnss) & (m.param_value == tp)].pivot(index="seed", columns="sweep_variant", values="value")
        return mean_ci((at["resetting"] / at["npo"]).to_numpy())

    npo = m[(m.gnss == "dgnss") & (m.sweep_variant == "npo")].groupby("param_value")["value"].mean()
    long = [ratio("dgnss", tp)[0] for tp in (6.0, 7.0, 8.0, 9.0, 10.0)]
    return [npo.min(), npo.max(), min(long), max(long), *ratio("dgnss", 5.0), *ratio("dgnss", 4.0), *ratio("dualband", 4.0)]


def _cross_dp(signal: str, metric: str) -> list[float]:
    """A row of docs/cross.md's table: the six observers on Torben's sway impulse."""
    variants = ("npo", "resetting", "liu_eps0.2", "liu_eps0.1", "proposed_d1.2", "proposed_d2.2")
    return [mean("cross_dp_impulse", v, signal, metric) for v in variants]


def _tuned_yaw(scenario: str) -> list[float]:
    variants = ("rise_tuned", "srise_tuned", "cdo_srise_tuned", "rise", "srise", "cdo_srise")
    return [mean(TUNED, v, "yaw", "rmse", scenario, scale=e2) for v in variants]


def _claim_check(experiment: str, text: str, signal: str, scenario: str | None = None) -> list[float]:
    """A committed experiment's claim rechecked on its metrics: the statistic and 95 % interval of one signal's check
    (in ``scenario``, for a claim checked in several)."""
    from marinebench.loading import load_experiment
    from marinebench.results.claims import evaluate

    exp, _ = load_experiment(ROOT / "configs" / f"{experiment}.yaml")
    (res,) = (r for r in evaluate(exp, _metrics(experiment)) if r.claim.text.startswith(text))
    (check,) = (c for c in res.checks if c.signal == signal and scenario in (None, c.where))
    return [check.statistic, *check.ci]


def _grid_claim(sweep: str, text: str, slices: list[tuple[float, str]]) -> list[float]:
    """A committed grid sweep's claim rechecked on its metrics: the statistic and 95 % interval at each (slice value,
    group)."""
    from marinebench.experiments.grid import grid_claims
    from marinebench.loading import load_experiment

    exp, _ = load_experiment(ROOT / "results" / sweep / "config.resolved.yaml")
    (res,) = (r for r in grid_claims(_metrics(sweep), exp.sweep) if r.claim.text.startswith(text))
    out = []
    for value, group in slices:
        (check,) = (c for v, checks in res.slices.items() if np.isclose(v, value) for c in checks if c.where == group)
        out += [check.statistic, *check.ci]
    return out


@cache
def _coverage(seeds: int) -> tuple[float, float]:
    """The claims' 95 % interval's coverage of a ratio of means, and the percentile interval's (tests/test_claims.py)."""
    from .test_claims import coverage

    return coverage(seeds)


def _sweep_claim(sweep: str, text: str) -> list[float]:
    """A committed sweep's claim rechecked on its metrics: each group's statistic and 95 % interval; the claim's
    checks must be narrow (their interval across the bound) for the 5-seed sweep and firm for more seeds."""
    from marinebench.experiments.curves import sweep_claims
    from marinebench.loading import load_experiment

    exp, _ = load_experiment(ROOT / "results" / sweep / "config.resolved.yaml")
    (res,) = (r for r in sweep_claims(_metrics(sweep), exp.sweep) if r.claim.text.startswith(text))
    assert res.narrow == (exp.seeds == 5), f"{sweep}: '{text}' is {'' if res.narrow else 'not '}narrow"
    return [x for c in res.checks for x in (c.statistic, *c.ci)]


@cache
def _analysis(name: str):
    """A script of docs/analysis/ as a module (run here, from the designs, not read from a file)."""
    spec = importlib.util.spec_from_file_location(name, ROOT / "docs" / "analysis" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@cache
def _table4_orderings() -> dict[str, float]:
    """docs/analysis/table4_orderings.py's linear programme."""
    return _analysis("table4_orderings").analysis()


def _frontier_gain(k_star: tuple[float, float, float]) -> list[float]:
    """g and r in depth of the CDO with a quoted K* (the frontier point docs/tijjani.md names)."""
    from marinebench.design.cdo import sample_noise_gains
    from marinebench.observers.cdo import CdoParams

    cdo = CdoParams(k_star=k_star)
    (r,), (g,) = sample_noise_gains(cdo.injection(), _analysis("cdo_noise_frontier").H_DEPTH, cdo.k_w)
    return [g, r]


QUOTES = [
    Quote("docs/torben.md", "its J_tot moves from {} to {} (differential) and {} to {} (dual-band)\n  between 0 and 4 m. "
          "The resetting observer's grows from {} to {} (differential) and from {} to {}\n  (dual-band)",
          lambda: _sea_state()[:8]),
    Quote("docs/torben.md", "interval) is {} [{}, {}] in calm water and {} [{}, {}] at 4 m with differential GNSS, {}\n  "
          "[{}, {}] and {} [{}, {}] with dual-band", lambda: _sea_state()[8:]),
    Quote("README.md", "From calm water to Hs 4 m the NPO's J_tot does not move ({} → {},\n  differential GNSS), while "
          "the resetting observer's grows by {} % (differential) and {} % (dual-band)",
          lambda: [*_sea_state()[:2], *(100 * (_sea_state()[i + 1] / _sea_state()[i] - 1) for i in (4, 6))]),
    Quote("README.md", "shrinks from J ratio {} to {} (differential) and from {} to {} [{}, {}]",
          lambda: [_sea_state()[8], _sea_state()[11], _sea_state()[14], *_sea_state()[17:]]),
    Quote("docs/torben.md", "The NPO's J_tot stays within\n  {}–{} (differential); J_resetting/J_NPO is {}–{} (differential) "
          "from Tp 6 s up, {} [{}, {}]\n  at 5 s", lambda: _peak_period()[:7]),
    Quote("docs/torben.md", "advantage: {} [{}, {}] differential, {} [{}, {}] dual-band.", lambda: _peak_period()[7:]),
    Quote("README.md", "the resetting observer's J_tot is {}× [{}, {}] the NPO's", lambda: _peak_period()[7:10]),
    Quote("README.md", "Our Liu rows land on the paper's (ratios {}–{})", lambda: _table3()["liu"]),
    Quote("docs/bejarano.md", "(ratios ours/paper {}–{} over the twelve cells)", lambda: _table3()["liu"]),
    Quote("README.md", "far above the paper's (e_u {} vs 3.9e-6) and {}–{}× our Liu ε = 0.1's",
          lambda: [mean(T3B, "proposed_d0.05", "u", "std"), *_table3()["slow"]]),
    Quote("docs/bejarano.md", "far above the paper's (e_u {} vs 3.9e-6, e_σr {} vs 0.0088) and {}–{}× above our Liu",
          lambda: [mean(T3B, "proposed_d0.05", "u", "std"), mean(T3B, "proposed_d0.05", "sigma_r", "std"),
                   *_table3()["slow"]]),
    Quote("README.md", "every number within {}× of the paper's; Fig. 6", lambda: _table4_ratios()[:1]),
    Quote("README.md", "Every number within {}× of the paper's; δ = 1.2", lambda: _table4_ratios()[:1]),
    Quote("docs/bejarano.md", "Every number is within a factor {} of the paper's (ratios {}–{})", _table4_ratios),
    Quote("README.md", "Table IV: δ = 2.2 vs Liu ε = 0.1 on velocity ({} vs {})",
          lambda: [mean(T4, "proposed_d2.2", "u", "std"), mean(T4, "liu_eps0.1", "u", "std")]),
    Quote("README.md", "velocity (e_u {} vs {}; paper 0.0713 vs 0.073)",
          lambda: [mean(T4, "proposed_d2.2", "u", "std"), mean(T4, "liu_eps0.1", "u", "std")]),
    Quote("README.md", "nor lower the velocity errors against δ = 1.2\n  ({})",
          lambda: [mean(T4, "proposed_d1.2", "u", "std")]),
    Quote("docs/bejarano.md", "over 0.1–0.45 Hz ({} % less at the band's upper edge, 0.5 Hz;",
          lambda: [100 * (1 - _table4_orderings()["committed_noise_vs_liu0.1_min"])]),
    Quote("docs/bejarano.md", "e_u(δ = 2.2)/e_u(δ = 1.2) from below by {} with our design, so no such world",
          lambda: [_table4_orderings()["committed_best"]]),
    Quote("docs/bejarano.md", "problem (28) as printed) the bound is {}, reached only",
          lambda: [_table4_orderings()["no_disk_best"]]),
    Quote("docs/bejarano.md", "against simulated e_u of {} / {} / {} / {}",
          lambda: [mean(T4, v, "u", "std") for v in ("liu_eps0.2", "liu_eps0.1", "proposed_d1.2", "proposed_d2.2")]),
    Quote("docs/bejarano.md", "δp 0.5 → 3 cuts e_u from\n  {} to {} and e_v from {} to {};",
          lambda: [mean(F45, v, s, "std", "noise_free") for s in ("u", "v") for v in ("proposed_dp0.5", "proposed_dp3")]),
    Quote("docs/bejarano.md", "(kn = 1) gives e_v {} / {} /\n  {} / {} (",
          lambda: [mean(F7, f"kw{k}", "v", "std", "noise_free") for k in KW]),
    Quote("docs/bejarano.md", "(δp = 3: e_σu {} → {}; kω = 100: e_σv {} → {})",
          lambda: [*(mean(F45, v, "sigma_u", "std", "noisy") for v in ("proposed_dp0.5", "proposed_dp3")),
                   *(mean(F7, f"kw{k}", "sigma_v", "std", "noisy") for k in (KW[0], KW[-1]))]),
    Quote("docs/bejarano.md", "(δp: e_u {} → {}; kω 0.1 → 100: e_v {} → {})",
          lambda: [*(mean(F45, v, "u", "std", "noisy") for v in ("proposed_dp0.5", "proposed_dp3")),
                   *(mean(F7, f"kw{k}", "v", "std", "noisy") for k in (KW[0], KW[-1]))]),
    Quote("docs/bejarano.md", "e_v's noise\n  part ≈ {} / {} / {} / {} for kω",
          lambda: [noise_part(F7, f"kw{k}", "v") for k in KW]),
    Quote("docs/bejarano.md", "and e_u's ≈ {} → {} for δp 0.5 → 3",
          lambda: [noise_part(F45, v, "u") for v in ("proposed_dp0.5", "proposed_dp3")]),
    Quote("docs/bejarano.md", "`noise_part_std_*` predicts {} / {} / {} / {} and {} → {} from the designed gains",
          lambda: [*(design(F7, f"kw{k}", "noise_part_std_v") for k in KW),
                   *(design(F45, v, "noise_part_std_u") for v in ("proposed_dp0.5", "proposed_dp3"))]),
    Quote("README.md", "J_tot_transient {} [{}, {}] resetting vs {} NPO ({} %", _fig1),
    Quote("docs/torben.md", "J_tot_transient {} [{}, {}] resetting vs {}", lambda: _fig1()[:4]),
    Quote("README.md", "J_tot_steady {} vs {} (no steady-state penalty), {} jumps per run",
          lambda: [mean("torben_fig1", "resetting", "z", "J_tot_steady"), mean("torben_fig1", "npo", "z", "J_tot_steady"),
                   mean("torben_fig1", "resetting", "z", "n_jumps")]),
    Quote("docs/torben.md", "vs J(c_ε = 5) is {} % [{}, {}] differential and {} % [{}, {}] dual-band",
          _eps_changes),
    Quote("README.md", "6 % *better* for both GNSS models ({} % [{}, {}],\n  {} % [{}, {}])",
          _eps_changes),
    Quote("docs/bejarano.md", "ratio of δ = 2.2 to Liu ε = 0.1 on e_u is {} [{}, {}] and to δ = 1.2 {} [{}, {}] (95 %",
          lambda: _claim_check(T4, "the proposed δ = 2.2 beats", "u") + _claim_check(T4, "proposed: faster tuning", "u")),
    Quote("README.md", "(paired ratio {} [{}, {}])", lambda: _claim_check(T4, "the proposed δ = 2.2 beats", "u")),
    Quote("docs/tijjani.md", "S+RISE/RISE in yaw is\n  {} [{}, {}] in S1, paired over seeds",
          lambda: _claim_check(T3, "yaw RMSE of S+RISE below", "yaw", "S1")),
    Quote("docs/tijjani.md", "(S+RISE/RISE {} [{}, {}], CDO-S+RISE/S+RISE\n  {} [{}, {}];",
          lambda: _claim_check(TUNED, "yaw RMSE of S+RISE below", "yaw", "S1")
          + _claim_check(TUNED, "yaw RMSE of CDO-S+RISE", "yaw", "S1")),
    Quote("docs/tijjani.md", "the tuned S+RISE falls behind the tuned RISE ({}× [{}, {}])",
          lambda: _claim_check(TUNED, "yaw RMSE of S+RISE below", "yaw", "S2-C2")),
    Quote("docs/tijjani.md", "EO's 0.64 cm ({}× [{}, {}]) and 0.108 against 0.035 rad\n  ({}× [{}, {}])",
          lambda: _claim_check(OBS, "no peaking larger than the EO's in the transient (depth", "depth")
          + _claim_check(OBS, "no peaking larger than the EO's in the transient (depth", "yaw")),
    Quote("docs/torben.md", "J(5)/J(0.1) is {} [{}, {}] differential and {} [{}, {}] dual-band at k = 0.7, both narrowly",
          lambda: _grid_claim("torben_fig3_sweep_grid_k_eps_5seeds", "c_ε = 0.1 is worse", [(0.7, "dgnss"), (0.7, "dualband")])),
    Quote("docs/torben.md", "at k = 0.8, narrowly ({} [{}, {}]), and at 0.9 and 1 ({} [{}, {}]; {} [{}, {}]), and for "
          "dual-band only at k = 1, narrowly ({} [{}, {}])",
          lambda: _grid_claim("torben_fig3_sweep_grid_k_eps_5seeds", "c_ε = 0.1 is worse",
                              [(0.8, "dgnss"), (0.9, "dgnss"), (1.0, "dgnss"), (1.0, "dualband")])),
    Quote("docs/torben.md", "5 seeds J(c_ε = 5)/J(c_ε = 0.1) is {} [{}, {}] differential and {} [{}, {}] dual-band",
          lambda: _sweep_claim("torben_fig3_sweep_5seeds", "c_ε = 0.1 is worse")),
    Quote("docs/commands.md", "covers a ratio of means in {} % of\n  draws at 3 seeds and {} % at 5, where this one covers {} % and {} %",
          lambda: [100 * x for x in (_coverage(3)[1], _coverage(5)[1], _coverage(3)[0], _coverage(5)[0])]),
    Quote("docs/commands.md", "c_ε claim is (J_tot ratio {} [{}, {}]\n  differential, {} [{}, {}] dual-band)",
          lambda: _sweep_claim("torben_fig3_sweep_5seeds", "c_ε = 0.1 is worse")),
    Quote("docs/commands.md", "20 seeds decide it ({} [{}, {}] and {} [{}, {}],",
          lambda: _sweep_claim("torben_fig3_sweep_eps_20seeds", "c_ε = 0.1 is worse")),
    Quote("docs/torben.md", "records {} s of simulation ({} s summed over the two batches), {} s for the command",
          lambda: [manifest("torben_fig3_sweep")[k] for k in ("wall_time_s", "batch_time_s", "total_time_s")]),
    Quote("README.md", "J(k = 0.7) vs J(k = 0): {} % differential, {} % dual-band",
          lambda: [_fig3_change("torben_fig3_sweep", "k", g, "0.7")[0] for g in ("dgnss", "dualband")]),
    Quote("README.md", "[2.5, 10] s (Spearman ρ {}–{})",
          lambda: [f(table_row(f"{sweep}/table.md", f"| delta | {g} | z | [2.5, 10] |")[-1]
                     for sweep in ("torben_fig3_sweep", "torben_fig3_sweep_5seeds") for g in ("dgnss", "dualband"))
                   for f in (min, max)]),
    Quote("docs/torben.md", "| J(k = 0.7) vs J(k = 0) | {} % / {} % [{}, {}] | {} % / {} % [{}, {}] |",
          lambda: _fig3_trend("k", "0.7")),
    Quote("docs/torben.md", "[2.5, 10] s: Spearman ρ; J(10) vs J(2.5) | {}, {} % / {}, {} % [{}, {}] | {}, {} % / {}, {} % [{}, {}] |",
          lambda: _fig3_trend("delta", "10", rho=True)),
    Quote("docs/torben.md", "| J(c_ε = 0.1) vs J(c_ε = 5) | {} % / {} % [{}, {}] | {} % / {} % [{}, {}] |",
          lambda: _fig3_trend("eps", "0.1")),
    Quote("docs/cross.md", f"| transient, 50–150 s {SIX}", lambda: _cross_dp("v", "rmse_transient")),
    Quote("docs/cross.md", f"| final half, 300–600 s {SIX}", lambda: _cross_dp("v", "rmse_steady")),
    Quote("docs/cross.md", f"| **σ_v RMSE [m/s²]**, transient {SIX}", lambda: _cross_dp("sigma_v", "rmse_transient")),
    Quote("docs/cross.md", f"| σ_v, final half {SIX}", lambda: _cross_dp("sigma_v", "rmse_steady")),
    Quote("README.md", "(S1: {} > {} > {}\n  e-2 m; paper 1.22 > 0.72 > 0.35)",
          lambda: [mean(T3, v, "depth", "rmse", "S1", scale=e2) for v in ("rise", "srise", "cdo_srise")]),
    Quote("docs/tijjani.md", "S2-C1 ({} > {} > {}) and S2-C2 ({} > {} > {})",
          lambda: [mean(T3, v, "depth", "rmse", scen, scale=e2)
                   for scen in ("S2-C1", "S2-C2") for v in ("rise", "srise", "cdo_srise")]),
    Quote("docs/tijjani.md", "(S1 {} vs {}; S2-C1 the same; S2-C2 {} vs\n  {} e-2 rad; paper 2.21 vs 2.22",
          lambda: [mean(T3, v, "yaw", "rmse", scen, scale=e2) for scen in ("S1", "S2-C2") for v in ("cdo_srise", "srise")]),
    Quote("docs/tijjani.md", "S1 depth {} (RISE) vs {} / {} N²s (the 9 N of net buoyancy held\n  for 40 s are 3.2e3 of "
          "each); yaw {} vs {} / {} N²m²s",
          lambda: [mean(T3, v, s, "int", "S1") for s in ("depth", "yaw") for v in ("rise", "srise", "cdo_srise")]),
    Quote("README.md", "S+RISE < RISE does not (S1 {} vs {} e-2 rad",
          lambda: [mean(T3, v, "yaw", "rmse", "S1", scale=e2) for v in ("srise", "rise")]),
    Quote("README.md", "(depth {} vs {} / {} N²s; yaw {} / {} / {} N²m²s, paper 22.5 /",
          lambda: [mean(T3, v, s, "int", "S1") for s in ("depth", "yaw") for v in ("rise", "srise", "cdo_srise")]),
    Quote("README.md", "RISE {} > S+RISE {} > CDO-S+RISE {} e-2 rad",
          lambda: [mean(TUNED, f"{v}_tuned", "yaw", "rmse", "S1", scale=e2) for v in ("rise", "srise", "cdo_srise")]),
    Quote("README.md", "S+RISE is still behind RISE\n  ({} vs {}; Table II's gains: {} vs {})",
          lambda: [mean(TUNED, v, "yaw", "rmse", "S2-C2", scale=e2)
                   for v in ("srise_tuned", "rise_tuned", "srise", "rise")]),
    Quote("docs/tijjani.md", "| S1 | {} | {} | {} | {} / {} / {} |", lambda: _tuned_yaw("S1")),
    Quote("docs/tijjani.md", "| S2-C2 | {} | **{}** | {} | {} / {} / {} |", lambda: _tuned_yaw("S2-C2")),
    Quote("README.md", "Yaw INT {} / {} / {} N²m²s",
          lambda: [mean(TUNED, f"{v}_tuned", "yaw", "int", "S1") for v in ("rise", "srise", "cdo_srise")]),
    Quote("docs/tijjani.md", "goes without the pushes in at most {} s (depth) and {} s (yaw) over the 5 seeds",
          lambda: [values(T3, "cdo_srise", s, "recovery", "S3").max() for s in ("depth", "yaw")]),
    Quote("README.md", "pushes in at most {} s (paper: < 2 s)",
          lambda: [max(values(T3, "cdo_srise", s, "recovery", "S3").max() for s in ("depth", "yaw"))]),
    Quote("README.md", "the CDO's yaw error is {} % below the EO's and its depth error {} % below",
          lambda: [-change((OBS, "cdo", s, "rmse_steady"), (OBS, "eo", s, "rmse_steady")) for s in ("yaw", "depth")]),
    Quote("docs/tijjani.md", "the CDO's error is below\n  the EO's in both DOFs: depth −{} % and yaw −{} % against the truth (−{} % and −{} % against the samples)",
          lambda: [-change((OBS, "cdo", s, "rmse_steady"), (OBS, "eo", s, "rmse_steady"))
                   for s in ("depth", "yaw", "depth_meas", "yaw_meas")]),
    Quote("docs/tijjani.md", "{} against {} m/s² in depth (−{} %) and {} against {} rad/s² in yaw (−{} %)",
          lambda: [x for s in ("depth", "yaw") for x in
                   (mean(OBS, "cdo", f"{s}_disturbance", "rmse_disturbance"), mean(OBS, "eo", f"{s}_disturbance", "rmse_disturbance"),
                    -change((OBS, "cdo", f"{s}_disturbance", "rmse_disturbance"),
                            (OBS, "eo", f"{s}_disturbance", "rmse_disturbance")))]),
    Quote("docs/tijjani.md", "started at the truth\n  (`tijjani_observers_no_initial_error`), −{} % and −{} %",
          lambda: [-change((OBS0, "cdo", f"{s}_disturbance", "rmse_disturbance"),
                           (OBS0, "eo", f"{s}_disturbance", "rmse_disturbance")) for s in ("depth", "yaw")]),
    Quote("README.md", "the CDO's disturbance error is {} m/s² in depth and {}\nrad/s² in yaw, {} % and {} % below the EO's",
          lambda: [mean(OBS, "cdo", f"{s}_disturbance", "rmse_disturbance") for s in ("depth", "yaw")]
          + [-change((OBS, "cdo", f"{s}_disturbance", "rmse_disturbance"), (OBS, "eo", f"{s}_disturbance", "rmse_disturbance"))
             for s in ("depth", "yaw")]),
    Quote("docs/tijjani.md", "(CDO +{} % depth, +{} %\n  yaw; against the samples +{} % and −{} %;",
          lambda: [change((OBS, "cdo", s, "rmse"), (OBS, "eo", s, "rmse")) for s in ("depth", "yaw", "depth_meas")]
          + [-change((OBS, "cdo", "yaw_meas", "rmse"), (OBS, "eo", "yaw_meas", "rmse"))]),
    Quote("README.md", "(CDO {} % depth, {} % yaw; paper −45 %, −25 %)",
          lambda: [change((OBS, "cdo", s, "rmse"), (OBS, "eo", s, "rmse")) for s in ("depth", "yaw")]),
    Quote("README.md", "the CDO's error is {} % below the EO's in depth and\n  {} % in yaw against the truth ({} % and {} % "
          "against the samples;", lambda: [-change((OBS0, "cdo", s, "rmse"), (OBS0, "eo", s, "rmse"))
                                           for s in ("depth", "yaw", "depth_meas", "yaw_meas")]),
    Quote("README.md", "CDO {} % below the EO in depth, {} % in yaw, no larger peaking",
          lambda: [-change((OBS0, "cdo", s, "rmse"), (OBS0, "eo", s, "rmse")) for s in ("depth", "yaw")]),
    Quote("docs/tijjani.md", "| 0, 0° (`tijjani_observers_no_initial_error`) | {} / {} | {} / {} | {} / {} | {} / {} | 4 of 4 |",
          lambda: _fig2_ratios(OBS0)),
    Quote("docs/tijjani.md", "| 5 cm, 10° (`tijjani_observers`) | **{} / {}** | **{} / {}** | {} / {} | **{} / {}** | 1 of 4 |",
          lambda: _fig2_ratios(OBS)),
    Quote("docs/tijjani.md", "for every EO ε in [0.02, 0.3] s (CDO over EO {}–{} in depth, {}–{} in yaw)",
          lambda: _sweep_ratios(f"{OBS0}_sweep_5seeds", "eo_eps")),
    Quote("docs/bejarano.md", "goes, from no noise to the full noise, from {} to {} in e_u (1 at {} of the noise)",
          lambda: _noise_grid("u")),
    Quote("docs/bejarano.md", "from {} to\n  {} in e_v (1 at {})", lambda: _noise_grid("v")),
    Quote("README.md", "a faster δp lowers e_u below\n  {} of the noise and raises e_σu only above {}",
          lambda: [_noise_grid("u")[2], _noise_grid("sigma_u")[2]]),
    Quote("README.md", "Fig. 7's best sway at kω = 100 needs at most {} of it", lambda: [_noise_grid("v", FIG7_GRID, 100.0, 10.0)[2]]),
    Quote("docs/bejarano.md", "from {} to {} in e_σu (1 at {})", lambda: _noise_grid("sigma_u")),
    Quote("docs/bejarano.md", "from {} to {} in e_σv (1 at {}; linear", lambda: _noise_grid("sigma_v")),
    Quote("docs/bejarano.md", "its e_v is below kω = 10's up to {} of our noise, below kω = 1's up to {} and below\n  kω = 0.1's up to {}",
          lambda: [_noise_grid("v", FIG7_GRID, 100.0, vs)[2] for vs in (10.0, 1.0, 0.1)]),
    Quote("docs/bejarano.md", "(over kω = 10's: {} without noise, {} at the full noise)",
          lambda: _noise_grid("v", FIG7_GRID, 100.0, 10.0)[:2]),
    Quote("docs/bejarano.md", "Fig. 5's σ half needs at least {} of our noise, Fig. 7's best kω = 100 at most {}",
          lambda: [_noise_grid("sigma_u")[2], _noise_grid("v", FIG7_GRID, 100.0, 10.0)[2]]),
    Quote("docs/torben.md", "from 0.05 to 3 m: J(5)/J(0.1) stays between {} and {}, so", _eps_over_noise),
    Quote("docs/torben.md", "J_tot_transient\n  {}–{} of the NPO's. The steady state does not: up to {} m the two observers' "
          "J_tot_steady are equal", lambda: [*(q := _fig1_over_gnss())["transient"], q["equal_to"]]),
    Quote("docs/torben.md", "(jumps per run {} at {} m, {} at {} m) and the resetting observer's J_tot_steady is\n  {}× the "
          "NPO's at {} m, near the dual-band 1.5 m ({}× at 3 m)", lambda: [*(q := _fig1_over_gnss())["jumps"], *q["steady"]]),
    Quote("README.md", "but above {} m the noise reaches Table I's ε and fires resets in the steady\n  state: {}× the NPO's "
          "J_tot_steady at {} m", lambda: [(q := _fig1_over_gnss())["equal_to"], *q["steady"][:2]]),
    Quote("docs/cross.md", "along which Liu ε = 0.1's steady sway error grows from {} to {} m/s",
          lambda: _cross_over_gnss().iloc[[0, -1]].tolist()),
    Quote("docs/tijjani.md", "the CDO's depth RMSE over the EO's reaches 0.8 at {} mm and 1\n  at {} mm of depth noise",
          lambda: [x * 1000 for x in _crossings(f"{OBS0}_sweep_5seeds", "depth_noise", "depth")]),
    Quote("README.md", "The depth RMSE claim needs the depth-sample\n  noise below {} mm",
          lambda: [_crossings(f"{OBS0}_sweep_5seeds", "depth_noise", "depth", (0.8,))[0] * 1000]),
    Quote("docs/tijjani.md", "while in yaw the ratio stays between {} and {} up to 0.2°",
          lambda: _sweep_ratios(f"{OBS0}_sweep_5seeds", "yaw_noise")[2:]),
    Quote("docs/tijjani.md", "the ratio is above 1 at every level: {}–{} in yaw, and in depth {}–{}\n  but for one point "
          "({} at {} mm", lambda: _sweep_ratios(f"{OBS}_sweep_5seeds", "yaw_noise")[2:] + _depth_noise_but_the_cycle()),
    Quote("docs/torben.md", "(J_tot_transient at most {}× the NPO's). J_tot_steady equals the NPO's (to 0.1 %) up to {} m with "
          "c_ε = 3.98, up\n  to {} m with c_ε = 6.31 ({}× at 1.99 m), while c_ε ≤ 1 costs {}–{}× at every level",
          _fig1_eps_needed),
    Quote("docs/torben.md", "is {} at σ = 0.113 m,\n  the grid point nearest differential's 0.1 m (per seed {}–{}), but {} at "
          "1.32 m and {} at 1.99 m around\n  dual-band's 1.5 m (per seed {}–{} and {}–{}, a tie). Constant resetting costs "
          "in the steady state (J_tot_steady\n  {}× that at c_ε = 5, at 0.113 m) and gains in the transient ({}×)",
          _fig1_eps_claim),
    Quote("README.md", "(J(c_ε = 0.1)/J(c_ε = 5) = {} at\n  0.113 m) and ties for dual-band ({} at 1.32 m)",
          lambda: [(q := _fig1_eps_claim())[0], q[3]]),
    Quote("docs/bejarano.md", "0.1) is {} without noise and falls to {} at twice the noise, never below 1, while δ = 2.2 beats "
          "δ = 1.2 on e_u\n  only below {} of the noise ({} at 0.2, {} at 0.4)", _table4_over_noise),
    Quote("docs/tijjani.md", "S+RISE's yaw RMSE is {}–{}× RISE's at\n  every level ({}–{} against {}–{} e-2 rad",
          lambda: [f(_side_by_side(TABLE3_YAW_NOISE, "rmse", "yaw", "srise", "rise")) for f in (min, max)]
          + [f(_curves(TABLE3_YAW_NOISE, "rmse", "yaw")[v]) * 100 for v in ("srise", "rise") for f in (min, max)]),
    Quote("README.md", "δ = 2.2 stays above Liu ε = 0.1 on e_u at every level ({} at twice the noise)\n  and beats δ = 1.2 "
          "only below {} of it", lambda: [(q := _table4_over_noise())[1], q[2]]),
    Quote("README.md", "(S+RISE {}–{}× RISE's; `sweep yaw_noise",
          lambda: [f(_side_by_side(TABLE3_YAW_NOISE, "rmse", "yaw", "srise", "rise")) for f in (min, max)]),
    Quote("docs/tijjani.md", "while CDO-S+RISE's stays\n  {}–{} of S+RISE's",
          lambda: [f(_side_by_side(TABLE3_YAW_NOISE, "rmse", "yaw", "cdo_srise", "srise")) for f in (min, max)]),
    Quote("docs/tijjani.md", "S+RISE's yaw INT over RISE's is {} at\n  {}° and equal at {}°, reaches 1.5 at {}° and {} at {}°, "
          "and is back to {} at 0.2°", lambda: [(q := _yaw_noise_int())[0], 0.005, *q[1:]]),
    Quote("docs/tijjani.md", "the truth reaches 0.8 at {} cm and 1 at {} cm in depth, 0.8 at {}° and 1 at {}° in yaw",
          lambda: [x * cm for x in _crossings(f"{OBS0}_sweep_5seeds", "offset_depth", "depth")]
          + _crossings(f"{OBS0}_sweep_5seeds", "offset_yaw", "yaw")),
    Quote("README.md", "(CDO over EO reaches 1 at {} cm and {}°)",
          lambda: [_crossings(f"{OBS0}_sweep_5seeds", "offset_depth", "depth", (1.0,))[0] * cm,
                   _crossings(f"{OBS0}_sweep_5seeds", "offset_yaw", "yaw", (1.0,))[0]]),
    Quote("README.md", "(largest error over 0.1–2 s: {} vs {} cm, {} vs {} rad)",
          lambda: [mean(OBS, "cdo", "depth", "peak_output", scale=cm), mean(OBS, "eo", "depth", "peak_output", scale=cm),
                   mean(OBS, "cdo", "yaw", "peak_output"), mean(OBS, "eo", "yaw", "peak_output")]),
    Quote("docs/tijjani.md", "The defaults: EO r = {}, g = {}; CDO r = {}, g = {}; 20 % below the EO\n  needs g ≤ {}.",
          lambda: [_analysis("cdo_noise_frontier").defaults()[k] for k in
                   ("eo_default_radius", "eo_default_gain", "cdo_default_radius", "cdo_default_gain", "needed_gain")]),
    Quote("docs/tijjani.md", "K* = [0.7129, 0.1352, 0.0089] (g = {}, r = {} after rounding)",
          lambda: _frontier_gain((0.7129, 0.1352, 0.0089))),
    Quote("docs/tijjani.md", "(default K*: {} and {}; EO {} and {})",
          lambda: [mean(OBS, v, "depth", m, scale=100) for v in ("cdo", "eo") for m in ("rmse", "rmse_steady")]),
    Quote("README.md", "at r ≤ 0.78: {} σ against the EO's 0.659 σ", lambda: _frontier_gain((0.7129, 0.1352, 0.0089))[:1]),
]


def quoted_numbers(quote: Quote) -> list[str]:
    """The numbers standing at the quote's ``{}`` in its document (line breaks and indents as the text has them)."""
    doc = (ROOT / quote.doc).read_text()
    pattern = f"({NUMBER})".join(re.escape(part) for part in quote.text.split("{}"))
    found = re.search(pattern, doc)
    assert found, f"{quote}: not found in {quote.doc} (reworded? update the quote here)"
    return list(found.groups())


def agrees(printed: str, value: float) -> bool:
    """``value`` rounds to ``printed`` (half a unit of its last digit; 4.1e3 has a unit of 100)."""
    text = printed.replace("−", "-")
    mantissa, _, exponent = text.partition("e")
    decimals = len(mantissa.partition(".")[2])
    unit = 10.0 ** (int(exponent or 0) - decimals)
    return abs(float(text) - value) <= unit / 2 * (1 + 1e-9)


def assert_quote_holds(quote: Quote) -> None:
    """Every number the quote stands for in its document rounds from the value computed now."""
    printed, computed = quoted_numbers(quote), quote.computed()
    assert len(printed) == len(computed), f"{quote}: {len(printed)} numbers quoted, {len(computed)} computed"
    wrong = [f"{p} (recomputed {c:.6g})" for p, c in zip(printed, computed) if not agrees(p, c)]
    assert not wrong, f"{quote}: " + "; ".join(wrong)


@pytest.mark.parametrize("quote", QUOTES, ids=str)
def test_the_docs_quote_the_committed_results(quote):
    assert_quote_holds(quote)


def test_no_verdict_of_the_committed_experiments_is_narrow():
    """docs/commands.md and the README: every claim of the 16 experiments, rechecked on its committed metrics, has a firm verdict
    (the 95 % interval of each deciding check on the verdict's side of its bound)."""
    from marinebench.loading import load_experiment
    from marinebench.results.claims import evaluate

    configs = sorted((ROOT / "configs").glob("*.yaml"))
    assert len(configs) == 16 and "No verdict\n  of the 16 experiments is narrow." in (ROOT / "docs" / "commands.md").read_text()
    assert "and no verdict is *narrow*" in (ROOT / "README.md").read_text()
    narrow = [f"{c.stem}: {r.claim.text}" for c in configs for r in evaluate(load_experiment(c)[0], _metrics(c.stem))
              if r.narrow]
    assert not narrow, narrow


def test_a_misquoted_number_is_caught():
    assert agrees("0.0783", 0.07834) and agrees("4.1e3", 4070.0) and agrees("−64", -63.6)
    assert not agrees("0.0783", 0.07836) and not agrees("4.1e3", 4160.0) and not agrees("−64", -64.6)


def test_the_papers_table4_velocity_ratios_are_out_of_reach_of_the_lmi_gains():
    """docs/bejarano.md: no noise spectrum in 0.1–0.5 Hz with any disturbance spectrum up to 1 Hz gives the paper's
    e_u ratios of δ = 2.2 to Liu ε = 0.1 (0.977) and to δ = 1.2 (0.867) together, with the disk or without it."""
    result = _table4_orderings()
    assert result["committed_paper_pair"] == 0 and result["no_disk_paper_pair"] == 0
