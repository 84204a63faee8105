"""Claims (``claims:``): verdicts and statistics on planted metrics, config errors, claims.md through the CLI."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from marinebench.cli import app
from marinebench.loading import load_experiment
from marinebench.metrics.stats import mean_ci
from marinebench.results.claims import (
    NARROW_NOTE,
    Check,
    Region,
    bootstrap_ci,
    evaluate,
    manifest_entries,
    markdown,
    ratio_of_means,
    summary_line,
)

from .conftest import ROOT, md_row, tidy_metrics, write_tiny

runner = CliRunner()


def tiny_with_claims(tmp_path, claims: list[dict], edit=None):
    """The tiny experiment with ``claims``; ``edit(doc)`` may change the rest of its YAML first."""
    path = write_tiny(tmp_path)
    doc = yaml.safe_load(path.read_text())
    doc["claims"] = claims
    if edit is not None:
        edit(doc)
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def planted(values: dict[tuple[str, str], list[float]], scenario: str = "cs2_noisy") -> pd.DataFrame:
    """Tidy metrics: values[(variant, signal)] -> per-seed std values."""
    return tidy_metrics(values, "tiny", scenario)


A, B = "proposed_d1.2", "liu_eps0.2"
METRICS = planted({(A, "u"): [1.0, 1.2, 1.1], (B, "u"): [2.0, 2.2, 2.1],
                   (A, "sigma_u"): [3.0, 3.3, 3.0], (B, "sigma_u"): [3.0, 3.0, 3.3]})


def test_less_within_and_at_most_on_planted_means(tmp_path):
    exp, _ = load_experiment(tiny_with_claims(tmp_path, [
        {"kind": "less", "a": A, "b": B, "signals": ["u"], "text": "a below b"},
        {"kind": "less", "a": A, "b": B, "factor": 0.5, "signals": ["u"], "text": "a halves b"},
        {"kind": "less", "a": B, "b": A, "signals": ["u"], "text": "reversed"},
        {"kind": "within", "variants": [B, A], "rtol": 0.05, "signals": ["sigma_u"], "text": "sigma equal"},
        {"kind": "within", "variants": [A, B], "factor": 1.5, "signals": ["u"], "text": "u within 1.5x"},
        {"kind": "at_most", "a": A, "value": 1.15, "signals": ["u"], "text": "every seed <= 1.15"},
        {"kind": "order", "variants": [A, B], "signals": ["u", "sigma_u"], "text": "order on both"},
    ]))
    res = evaluate(exp, METRICS)
    assert [r.holds for r in res] == [True, False, False, True, False, False, False]
    less = res[0].checks[0]
    assert less.statistic == pytest.approx(1.1 / 2.1) and less.means == {A: pytest.approx(1.1), B: pytest.approx(2.1)}
    assert res[1].checks[0].statistic == pytest.approx(1.1 / 2.1)  # 0.524 is not below 0.5
    assert res[3].checks[0].statistic == pytest.approx(1.0)  # equal means: within any tolerance
    assert res[4].checks[0].statistic == pytest.approx(2.1 / 1.1)
    assert res[5].checks[0].statistic == pytest.approx(1.2)  # the largest seed, not the mean
    assert [c.holds for c in res[6].checks] == [True, False]  # u ordered, sigma_u tied


def test_a_zero_mean_fails_its_check_instead_of_the_run(tmp_path):
    exp, _ = load_experiment(tiny_with_claims(tmp_path, [
        {"kind": "less", "a": A, "b": B, "signals": ["u"], "text": "a below b"},
        {"kind": "within", "variants": [A, B], "factor": 1.5, "signals": ["u"], "text": "u within 1.5x"}]))
    res = evaluate(exp, planted({(A, "u"): [1.0, 1.0], (B, "u"): [0.0, 0.0]}))
    assert [r.fails for r in res] == [True, True]
    assert [r.checks[0].statistic for r in res] == [np.inf, np.inf]
    assert np.isnan(evaluate(exp, planted({(A, "u"): [0.0, 0.0], (B, "u"): [0.0, 0.0]}))[0].checks[0].statistic)


def test_near_paper_uses_the_tables_values_both_ways(tmp_path):
    exp, _ = load_experiment(tiny_with_claims(tmp_path, [
        {"kind": "near_paper", "factor": 2, "signals": ["u"], "text": "within 2x of the paper"}]))
    ok = evaluate(exp, planted({(B, "u"): [0.1, 0.1]}))[0]  # the tiny table's paper value for liu_eps0.2/u is 0.09
    assert ok.holds and ok.checks[0].statistic == pytest.approx(0.1 / 0.09)
    assert not evaluate(exp, planted({(B, "u"): [0.2, 0.2]}))[0].holds
    assert not evaluate(exp, planted({(B, "u"): [0.04, 0.04]}))[0].holds


def _in_cm(doc):
    """The tiny table shows std/u in cm/s, and the paper's value for liu_eps0.2/u is 9 cm/s."""
    doc["table"]["display"] = {"std/u": {"scale": 100.0, "unit": "cm/s"}}
    doc["table"]["paper"]["values"]["liu_eps0.2"]["u"] = 9.0


def test_near_paper_compares_in_the_tables_display_units(tmp_path):
    """A paper value given in the table's displayed unit (here std/u x 100) is compared with our mean x 100."""
    exp, _ = load_experiment(tiny_with_claims(tmp_path, [{"kind": "near_paper", "factor": 2, "signals": ["u"],
                                                          "text": "near"}], _in_cm))
    (res,) = evaluate(exp, planted({(B, "u"): [0.1, 0.1]}))
    assert res.holds and res.checks[0].statistic == pytest.approx(10.0 / 9.0)
    assert res.checks[0].means == {B: pytest.approx(0.1), "paper": pytest.approx(0.09)}


def test_order_checks_every_consecutive_pair(tmp_path):
    """``order: [a, c, b]`` means a < c < b: with c above b it fails, though a is below b."""
    def third_variant(doc):
        doc["variants"].append({"name": "liu_eps0.1", "observer": {"kind": "liu_eso", "eps": 0.1}})

    exp, _ = load_experiment(tiny_with_claims(tmp_path, [{"kind": "order", "variants": [A, "liu_eps0.1", B],
                                                          "signals": ["u"], "text": "a < c < b"}], third_variant))
    (res,) = evaluate(exp, planted({(A, "u"): [1.0, 1.0], ("liu_eps0.1", "u"): [3.0, 3.0], (B, "u"): [2.0, 2.0]}))
    assert [(c.means, c.holds) for c in res.checks] == [({A: 1.0, "liu_eps0.1": 3.0}, True),
                                                          ({"liu_eps0.1": 3.0, B: 2.0}, False)]
    assert res.fails


def test_a_claim_with_nothing_to_check_fails(tmp_path):
    """Metrics with no rows for one of the claim's variants: no check can be made, and the claim does not hold."""
    exp, _ = load_experiment(tiny_with_claims(tmp_path, [{"kind": "less", "a": A, "b": B, "signals": ["u"],
                                                          "text": "a below b"}]))
    (res,) = evaluate(exp, planted({(A, "u"): [1.0, 1.0]}))
    assert res.checks == [] and res.not_checked is None
    assert not res.holds and res.fails


def test_multi_scenario_claims_check_where_their_variants_run():
    exp, _ = load_experiment(ROOT / "configs" / "tijjani_table3.yaml")
    rows = []
    for scen, present in (("S1", ("rise", "srise", "cdo_srise")), ("S3", ("cdo_srise",))):
        for v in present:
            for seed in range(2):
                rows.append(("t", scen, v, seed, "depth", "rmse", {"rise": 3.0, "srise": 2.0, "cdo_srise": 1.0}[v], "ok"))
                rows.append(("t", scen, v, seed, "depth", "recovery", 1.5 + seed, "ok"))
    metrics = pd.DataFrame(rows, columns=["experiment", "scenario", "variant", "seed", "signal", "metric", "value", "status"])
    order = next(r for r in evaluate(exp, metrics) if r.claim.kind == "order")
    assert order.holds and {c.where for c in order.checks} == {"S1"}  # S3 runs CDO-S+RISE alone
    recovery = next(r for r in evaluate(exp, metrics) if r.claim.kind == "at_most")
    assert {c.where for c in recovery.checks} == {"S3"} and recovery.checks[0].statistic == 2.5
    assert not recovery.holds  # seed 1 takes 2.5 s > 2 s
    every = order.claim.model_copy(update={"scenarios": exp.scenario_names})
    assert exp.claim_problem(every) is None  # a claim may name every scenario of the experiment


def test_bootstrap_interval_covers_the_ratio_and_needs_two_seeds():
    rng = np.random.default_rng(3)
    a, b = 1 + 0.1 * rng.standard_normal(30), 2 + 0.1 * rng.standard_normal(30)
    lo, hi = bootstrap_ci([a, b], ratio_of_means)
    assert lo < a.mean() / b.mean() < hi and hi - lo < 0.05
    assert bootstrap_ci([a[:1], b[:1]], ratio_of_means) is None


def test_the_interval_of_a_mean_is_students_and_of_a_ratio_stays_positive():
    """For a mean the interval is Student's t interval (the bootstrap standard error of a mean is the plug-in
    s / sqrt(n), scaled back by sqrt(n / (n - 1))), from 2 seeds on and at any level; a ratio's, taken in log, is
    positive and asymmetric about it; Spearman's rho is clipped to [-1, 1]."""
    rng = np.random.default_rng(5)
    for n in (2, 5, 400):
        x = rng.normal(1.0, 0.2, n)
        for level in (0.95, 0.5):
            _, lo_t, hi_t = mean_ci(x, level)
            lo, hi = bootstrap_ci([x], lambda v: v.mean(axis=1), level=level, n_boot=4000)
            assert (hi - lo) / (hi_t - lo_t) == pytest.approx(1.0, abs=0.08 if n > 2 else 0.35), (n, level)
            assert (hi + lo) / 2 == pytest.approx(x.mean())
    a, b = np.array([0.3, 0.1, 0.2]), np.array([1.0, 0.2, 0.6])
    lo, hi = bootstrap_ci([a, b], ratio_of_means, scale="log")
    ratio = a.mean() / b.mean()
    assert 0 < lo < ratio < hi and hi / ratio == pytest.approx(ratio / lo)  # symmetric in log
    assert bootstrap_ci([np.array([0.9, 0.95, 1.0])], lambda v: v.mean(axis=1), bounds=(-1.0, 1.0))[1] == 1.0


def _percentile_ci(values, stat, n_boot, seed):
    """The plain percentile interval of the same resamples, for comparison."""
    n = len(values[0])
    idx = np.random.default_rng(seed).integers(0, n, size=(n_boot, n))
    return tuple(np.quantile(stat(*(v[idx] for v in values)), (0.025, 0.975)))


def coverage(seeds: int, draws: int = 600) -> tuple[float, float]:
    """How often the 95 % interval of a ratio of means, and the percentile interval of the same resamples, cover
    the true ratio 0.9, over ``draws`` draws of paired seeds with a shared world effect and skewed (log-normal)
    errors (docs/commands.md quotes it)."""
    rng = np.random.default_rng(seeds)
    hits = percentile_hits = 0
    for draw in range(draws):
        world = rng.normal(0.0, 0.5, seeds)
        a, b = 0.9 * np.exp(world + rng.normal(0.0, 0.3, seeds)), np.exp(world + rng.normal(0.0, 0.3, seeds))
        lo, hi = bootstrap_ci([a, b], ratio_of_means, n_boot=300, seed=draw, scale="log")
        hits += lo <= 0.9 <= hi
        p_lo, p_hi = _percentile_ci([a, b], ratio_of_means, 300, draw)
        percentile_hits += p_lo <= 0.9 <= p_hi
    return hits / draws, percentile_hits / draws


@pytest.mark.parametrize(("seeds", "percentile_at_most"), [(3, 0.85), (5, 0.9)])
def test_the_95_interval_covers_a_ratio_of_means_95_percent_of_the_time(seeds, percentile_at_most):
    """The interval covers the ratio in 91-98 % of 600 draws (4 standard errors of a 600-draw share around 95 %),
    where the percentile interval of the same resamples covers far less: it only recombines the seeds drawn."""
    ours, percentile = coverage(seeds)
    assert 0.91 <= ours <= 0.98
    assert percentile <= percentile_at_most


def test_checks_at_their_bounds_hold_and_their_intervals_are_of_the_claimed_statistic(tmp_path):
    """Equality holds for the <= checks (at_most at the value, within at the factor or at 1 + rtol, near_paper at
    either end of [1/factor, factor]); each interval is the bootstrap of the check's own statistic, here constant
    over seeds, so it is that value exactly; ``within`` with rtol compares the others with the first listed."""
    exp, _ = load_experiment(tiny_with_claims(tmp_path, [
        {"kind": "at_most", "a": A, "value": 3.0, "signals": ["u"], "text": "at most 3"},
        {"kind": "within", "variants": [A, B], "factor": 2.0, "signals": ["u"], "text": "within 2x"},
        {"kind": "within", "variants": [B, A], "rtol": 0.5, "signals": ["u"], "text": "within 50 % of B"},
        {"kind": "less", "a": A, "b": B, "factor": 0.6, "signals": ["u"], "text": "A is half of B"},
        {"kind": "near_paper", "factor": 2, "signals": ["u"], "text": "near"}], _in_cm))
    res = evaluate(exp, planted({(A, "u"): [1.5, 3.0], (B, "u"): [3.0, 6.0]}))
    assert [r.holds for r in res] == [True, True, True, True, False]
    assert [(c.statistic, c.ci) for r in res[1:4] for c in r.checks] == [(2.0, (2.0, 2.0)), (0.5, (0.5, 0.5)),
                                                                           (0.5, (0.5, 0.5))]
    assert res[2].checks[0].means == {B: 4.5, A: 2.25}  # the first listed is the reference
    near = evaluate(exp, planted({(B, "u"): [0.18, 0.18]}))[4].checks[0]  # 18 cm/s against the paper's 9
    assert near.holds and (near.statistic, near.ci) == (2.0, (2.0, 2.0))
    near = evaluate(exp, planted({(B, "u"): [0.045, 0.045]}))[4].checks[0]
    assert near.holds and near.statistic == 0.5 and near.needs == "in [0.5, 2]"
    assert evaluate(exp, planted({(B, "u"): [0.06, 0.06]}))[4].holds  # 0.67 of the paper's: not only above 1


def test_a_pairs_interval_is_over_the_seeds_both_ran_either_side_diverged(tmp_path):
    """The means are over each variant's own ok seeds; the interval resamples the seeds both have, whichever side
    lost one (here B = 2 A on the common seeds, so the interval is 0.5 exactly)."""
    exp, _ = load_experiment(tiny_with_claims(tmp_path, [{"kind": "less", "a": A, "b": B, "signals": ["u"],
                                                          "text": "a below b"}]))
    values = {(A, "u"): [1.0, 50.0, 3.0], (B, "u"): [2.0, 100.0, 6.0]}
    for lost in ((A, "u", 1), (B, "u", 1)):
        (check,) = evaluate(exp, tidy_metrics(values, "tiny", "cs2_noisy", {lost: "diverged"}))[0].checks
        assert check.ci == (0.5, 0.5)
        assert check.statistic == pytest.approx(2.0 / 36.0 if lost[0] == A else 18.0 / 4.0)


def test_claims_md_gives_each_verdict_and_check_row(tmp_path):
    """claims.md: the preamble says what the checks ran on (2 seeds: means and a bootstrap interval; 1 seed: no
    interval), the summary counts claims holding and not checked, the verdict table has one row per claim, and
    the checks table one row per check, '–' for a statistic that is not finite and a 'no data' row for a claim
    whose variants have no rows."""
    exp, _ = load_experiment(tiny_with_claims(tmp_path, [
        {"kind": "less", "a": A, "b": B, "signals": ["u", "v"], "text": "a below b", "source": "Table IV"},
        {"kind": "less", "a": B, "b": A, "signals": ["u"], "text": "b below a"},
        {"kind": "less", "a": A, "b": B, "metric": "nope", "text": "unknown metric"},
        {"kind": "less", "a": A, "b": "liu_eps0.1", "signals": ["u"], "text": "no rows"}],
        lambda doc: (doc["variants"].append({"name": "liu_eps0.1", "observer": {"kind": "liu_eso", "eps": 0.1}}),
                     doc["table"].update(title="Table IV, tiny"))))
    res = evaluate(exp, planted({(A, "u"): [1.0, 1.2], (B, "u"): [0.5, 0.5], (A, "v"): [1.0, 1.0], (B, "v"): [0.0, 0.0]}))
    md = markdown(exp, res).splitlines()
    assert md[0] == "## Claims checked: Table IV, tiny"
    assert md[2].startswith(f"Checked on our means over 2 seeds, root seed {exp.seed}, per scenario and signal.")
    assert "with a 95% interval over seeds: Student's t on its bootstrap standard error" in md[2]
    assert md[2].endswith(NARROW_NOTE)  # two seeds decide little: t with 1 degree of freedom
    assert "**1 of 4 claims hold, 1 not checked; 1 narrowly (a 95% interval across the bound).**" in md
    assert md[md.index("| # | verdict | claim | source | metric |") + 2:][:4] == [
        "| 1 | **fails** | a below b | Table IV | std |", "| 2 | holds (narrowly) | b below a |  | std |",
        f"| 3 | not checked: {res[2].not_checked} | unknown metric |  | nope |", "| 4 | **fails** | no rows |  | std |"]
    checks = md[md.index("| # | scenario | signal | means | statistic [95% CI] | needs | check |") + 2:]
    assert checks == [f"| 1 | cs2_noisy | u | {A} 1.1, {B} 0.5 | 2.2 [0.705, 6.87] | < 1 | **fails** (narrowly) |",
                      f"| 1 | cs2_noisy | v | {A} 1, {B} 0 | – | < 1 | **fails** |",  # no interval: firm, and so claim 1
                      f"| 2 | cs2_noisy | u | {B} 0.5, {A} 1.1 | 0.455 [0.146, 1.42] | < 1 | holds (narrowly) |",
                      "| 4 | – | – | no data | – | – | **fails** |"]
    one = markdown(exp.model_copy(update={"seeds": 1}), res).splitlines()[2]
    assert one.startswith("Checked on one seed,") and "; one seed gives no interval." in one
    assert manifest_entries(res)[2] == {"text": "unknown metric", "source": "", "holds": False,
                                        "not_checked": res[2].not_checked}
    assert manifest_entries(res)[0] == {"text": "a below b", "source": "Table IV", "holds": False}


@pytest.mark.parametrize(("region", "ci", "holds", "firm"), [
    (Region(-np.inf, 1.0), (0.8, 0.95), True, True),  # wholly below the bound
    (Region(-np.inf, 1.0), (0.8, 1.05), True, False),  # holds on the means, the interval reaches across
    (Region(-np.inf, 1.0), (0.98, 1.2), False, False),
    (Region(-np.inf, 1.0), (1.02, 1.2), False, True),
    (Region(-np.inf, 1.0), (1.0, 1.0), False, True),  # equal: fails '< 1' on every draw
    (Region(-np.inf, 1.0, closed=True), (1.0, 1.0), True, True),  # ... and holds '≤ 1'
    (Region(0.9, 1.1, closed=True), (0.95, 1.05), True, True),  # a two-sided bound (within, near_paper)
    (Region(0.9, 1.1, closed=True), (0.95, 1.15), True, False),
    (Region(0.9, 1.1, closed=True), (0.5, 1.5), False, False),  # fails on the means; the interval spans the band
    (Region(0.9, 1.1, closed=True), (1.15, 1.3), False, True),
    (Region(0.5, np.inf), (0.6, 0.7), True, True),  # a lower bound (trends, groups)
    (Region(0.5, np.inf), None, True, None),  # no interval (one seed): not judged
])
def test_a_check_is_firm_when_its_interval_is_on_the_verdicts_side(region, ci, holds, firm):
    assert Check("s", "u", {}, 1.0, ci, "", holds, region).firm is firm


def test_a_verdict_whose_interval_crosses_the_bound_is_marked_narrow(tmp_path):
    """Means 0.967 : 1 hold, but the seeds scatter across 1: claims.md, the summary and the manifest say
    'narrowly'; a failing claim is narrow only when all its failing checks are."""
    exp, _ = load_experiment(tiny_with_claims(tmp_path, [
        {"kind": "less", "a": A, "b": B, "signals": ["u"], "text": "a below b"},
        {"kind": "less", "a": B, "b": A, "signals": ["u"], "text": "b below a"},
        {"kind": "less", "a": A, "b": B, "signals": ["u", "sigma_u"], "text": "a below b on both"}]))
    res = evaluate(exp, planted({(A, "u"): [0.5, 1.5, 0.9], (B, "u"): [1.0, 1.0, 1.0],
                                 (A, "sigma_u"): [3.0, 3.1, 3.2], (B, "sigma_u"): [1.0, 1.1, 1.2]}))
    assert [r.holds for r in res] == [True, False, False]
    u = res[0].checks[0]
    assert u.statistic == pytest.approx(2.9 / 3) and u.ci[0] < 1 < u.ci[1] and u.firm is False
    assert [r.narrow for r in res] == [True, True, False]  # the third fails firmly on sigma_u
    assert summary_line(res) == "1 of 3 claims hold; 2 narrowly (a 95% interval across the bound)"
    md = markdown(exp, res).splitlines()
    assert md[2].endswith(NARROW_NOTE)
    assert "| 1 | holds (narrowly) | a below b |  | std |" in md and "| 3 | **fails** | a below b on both |  | std |" in md
    assert [row.removesuffix(" |").rsplit(" | ", 1)[1] for row in md[-4:]] == [
        "holds (narrowly)", "**fails** (narrowly)", "holds (narrowly)", "**fails**"]  # claims 1, 2; 3 on u, sigma_u
    assert [e.get("narrowly", False) for e in manifest_entries(res)] == [True, True, False]
    firm = evaluate(exp, METRICS)[0]
    assert firm.holds and firm.checks[0].firm and not firm.narrow and NARROW_NOTE not in markdown(exp, [firm])


def test_malformed_claim_is_a_config_error(tmp_path):
    res = runner.invoke(app, ["validate", str(tiny_with_claims(tmp_path, [{"kind": "within", "variants": [A, B], "text": "x"}]))])
    assert res.exit_code == 2 and "claims.0" in res.output and "exactly one of 'factor' or 'rtol'" in res.output
    assert len(res.output.strip().splitlines()) == 1


def _no_table(doc):
    doc.pop("table")


def _two_metrics(doc):
    doc["metrics"].append({"kind": "rmse", "name": "rmse", "t_start": 1.0, "signals": ["u"]})


@pytest.mark.parametrize(("claim", "edit", "reason"), [
    ({"kind": "less", "a": "nope", "b": B, "text": "x"}, None, "unknown variants ['nope']"),
    ({"kind": "less", "a": A, "b": B, "signals": ["depth"], "text": "x"}, None, "signals ['depth'] are not recorded"),
    ({"kind": "less", "a": A, "b": B, "metric": "rmse", "text": "x"}, None, "metric 'rmse' is not among"),
    ({"kind": "less", "a": A, "b": B, "signals": ["u"], "text": "x"}, _no_table, "no metric (give one"),
    ({"kind": "less", "a": A, "b": B, "metric": "std", "text": "x"}, _no_table, "no signals (give them; there is no table"),
    ({"kind": "less", "a": A, "b": B, "signals": ["u"], "scenarios": ["S9"], "text": "x"}, None,
     "unknown scenarios ['S9']"),
    ({"kind": "near_paper", "factor": 2, "metric": "std", "signals": ["u"], "text": "x"}, _no_table,
     "near_paper needs the table's paper values"),
    ({"kind": "near_paper", "factor": 2, "metric": "rmse", "signals": ["u"], "text": "x"}, _two_metrics,
     "near_paper: the paper's values (table.paper) are of the table's first metric 'std'"),
])
def test_claims_naming_what_the_experiment_lacks_are_reported_not_checked(tmp_path, claim, edit, reason):
    """An override may drop what a claim names: validate warns, run reports it, neither fails on it."""
    cfg = tiny_with_claims(tmp_path, [claim], edit)
    res = runner.invoke(app, ["validate", str(cfg)])
    assert res.exit_code == 0 and f"claims.0 cannot be checked: {reason}" in res.output, res.output
    exp, _ = load_experiment(cfg)
    (result,) = evaluate(exp, METRICS)
    assert result.not_checked is not None and reason in result.not_checked and not result.holds and not result.fails


def test_committed_configs_have_only_checkable_claims():
    for path in sorted((ROOT / "configs").glob("*.yaml")):
        exp, _ = load_experiment(path)
        assert [exp.claim_problem(c) for c in exp.claims] == [None] * len(exp.claims), path


def test_run_writes_claims_and_require_claims_gates(tmp_path):
    """A claim that holds and one that does not (a 1000x below b): claims.md, manifest, summary line, exit codes."""
    cfg = tiny_with_claims(tmp_path, [
        {"kind": "less", "a": A, "b": B, "factor": 100, "signals": ["u"], "text": "holds"},
        {"kind": "less", "a": A, "b": B, "factor": 0.001, "signals": ["u"], "text": "cannot hold"},
    ])
    res = runner.invoke(app, ["run", str(cfg), "--out", str(tmp_path / "out"), "--quiet"])
    assert res.exit_code == 0, res.output
    out = tmp_path / "out" / "tiny"
    text = (out / "claims.md").read_text()
    assert "**1 of 2 claims hold.**" in text and "| 2 | **fails** | cannot hold |" in text
    manifest = json.loads((out / "manifest.json").read_text())
    assert [c["holds"] for c in manifest["claims"]] == [True, False]
    gated = runner.invoke(app, ["run", str(cfg), "--out", str(tmp_path / "out2"), "--require-claims"])
    assert gated.exit_code == 1 and "1 claim(s) fail" in gated.output
    assert "1 of 2 claims hold" in gated.output and (tmp_path / "out2" / "tiny" / "claims.md").exists()
    resumed = runner.invoke(app, ["run", str(cfg), "--out", str(tmp_path / "out2"), "--require-claims", "--resume"])
    assert resumed.exit_code == 1 and "up to date" in resumed.output  # not rerun, and its failing claim still counts
    report = runner.invoke(app, ["report", str(tmp_path / "out"), "--out", str(tmp_path / "r.html")])
    html = (tmp_path / "r.html").read_text()
    assert report.exit_code == 0 and "Claims checked: tiny" in html and "<b>fails</b> | cannot hold" not in html
    assert "<td><b>fails</b></td><td>cannot hold</td>" in html
    assert "<tr><td>tiny</td><td>1\u00a0of\u00a02</td><td>cannot hold</td></tr>" in html  # the overview (no wrap)


def test_with_several_table_metrics_the_papers_values_sit_beside_the_first(tmp_path):
    """A single-scenario table's paper values are per variant and signal, of the table's first metric: with several
    metrics their column follows each of that metric's columns only, and a near_paper claim about another metric
    is reported not checked."""
    from marinebench.experiments.runner import summarise
    from marinebench.results.tables import markdown_table

    def two_metrics(doc):
        doc["metrics"].append({"kind": "rmse", "t_start": 1.0})
        doc["table"]["metrics"] = ["std", "rmse"]

    exp, _ = load_experiment(tiny_with_claims(tmp_path, [], two_metrics))
    metrics = pd.concat([planted({(v, s): [0.1, 0.1] for v in (A, B) for s in ("u", "sigma_u")}).assign(metric=m)
                         for m in ("std", "rmse")])
    table = markdown_table(exp, summarise(metrics))
    assert md_row(table, "variant") == ["variant", "std (e_u)", "std (e_u) paper", "std (e_sigma_u)",
                                        "std (e_sigma_u) paper", "rmse (e_u)", "rmse (e_sigma_u)"]
    assert md_row(table, B)[2] == "0.09"
    other, _ = load_experiment(tiny_with_claims(tmp_path, [{"kind": "near_paper", "metric": "rmse", "factor": 2,
                                                            "signals": ["u"], "text": "near"}], two_metrics))
    (res,) = evaluate(other, metrics)
    assert res.not_checked == "near_paper: the paper's values (table.paper) are of the table's first metric 'std'"
