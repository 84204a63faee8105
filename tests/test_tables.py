"""table.md (results/tables.py): cells with their CI and diverged runs, display units, the preamble's seed count,
and the study layout's default signals, on summaries written out by hand."""

import pandas as pd

from marinebench.experiments.runner import summarise
from marinebench.loading import load_experiment
from marinebench.results.tables import markdown_table, study_table

from .conftest import ROOT, md_row, tidy_metrics


def tiny(tiny_config, *sets):
    return load_experiment(tiny_config, list(sets))[0]


def test_a_cell_is_the_mean_with_its_interval_and_the_diverged_count(tiny_config):
    """Two seeds: '0.2 [lo, hi]' with Student's t interval; one finished seed of two: its value, no interval, and
    '(1 diverged)'; a signal no run finished: '–'."""
    values = {("liu_eps0.2", "u"): [0.1, 0.3], ("liu_eps0.2", "sigma_u"): [0.5, 0.6],
              ("proposed_d1.2", "u"): [0.04, 0.05], ("proposed_d1.2", "sigma_u"): [0.7, 0.8]}
    status = {("proposed_d1.2", "u", 1): "diverged", ("proposed_d1.2", "sigma_u", 0): "diverged",
              ("proposed_d1.2", "sigma_u", 1): "diverged"}
    summary = summarise(tidy_metrics(values, status=status))
    table = markdown_table(tiny(tiny_config), summary)
    lo, hi = summary.iloc[0][["ci_low", "ci_high"]]
    assert md_row(table, "liu_eps0.2")[1] == f"0.2 [{lo:.3g}, {hi:.3g}]" and lo < 0.1 and hi > 0.3
    assert md_row(table, "proposed_d1.2")[1:] == ["0.04 (1 diverged)", "–", "– (2 diverged)", "–"]  # ours, paper, ...


def test_display_scales_the_mean_and_its_interval_and_names_the_unit(tiny_config):
    """``table.display``: 'std/u' shown x100 in cm; the other signal as computed."""
    exp = tiny(tiny_config, "table.display={std/u: {scale: 100, unit: cm}}")
    values = {("liu_eps0.2", "u"): [0.01, 0.03], ("liu_eps0.2", "sigma_u"): [0.5, 0.7],
              ("proposed_d1.2", "u"): [0.02, 0.02], ("proposed_d1.2", "sigma_u"): [0.1, 0.1]}
    summary = summarise(tidy_metrics(values))
    table = markdown_table(exp, summary)
    assert md_row(table, "variant")[1:4] == ["e_u [cm] ours", "e_u [cm] paper", "e_sigma_u ours"]
    lo, hi = summary.iloc[0][["ci_low", "ci_high"]]
    assert md_row(table, "liu_eps0.2")[1] == f"2 [{100 * lo:.3g}, {100 * hi:.3g}]"
    assert md_row(table, "liu_eps0.2")[3].startswith("0.6 [")
    assert md_row(table, "proposed_d1.2")[1] == "2 [2, 2]"


def test_the_preamble_says_how_many_seeds_and_whether_there_is_an_interval(tiny_config):
    values = {("liu_eps0.2", "u"): [0.1], ("proposed_d1.2", "u"): [0.2]}
    one = markdown_table(tiny(tiny_config, "seeds=1"), summarise(tidy_metrics(values)))
    assert "One seed, so no interval;" in one and "Student-t" not in one
    assert md_row(one, "liu_eps0.2")[1] == "0.1"
    two = markdown_table(tiny(tiny_config), summarise(tidy_metrics({k: v * 2 for k, v in values.items()})))
    assert "Mean over 2 seeds with the 95% Student-t interval in brackets;" in two and "One seed" not in two


def test_a_study_table_without_a_table_section_shows_depth_and_yaw_of_the_first_metric():
    """Multi-scenario (Tijjani) layout with ``table`` unset: a row per signal (depth, yaw) and scenario of the first
    metric, a column per variant, no paper columns."""
    exp, _ = load_experiment(ROOT / "configs" / "tijjani_table3.yaml", ["table=null"])
    scen = exp.scenario_names[0]
    first = exp.metrics[0].label
    rows = [(scen, v.name, sig, first, x) for v in exp.variants for sig, x in (("depth", 0.01), ("yaw", 0.02))]
    summary = summarise(pd.DataFrame(
        [("e", s, v, 0, sig, m, x, "ok") for s, v, sig, m, x in rows],
        columns=["experiment", "scenario", "variant", "seed", "signal", "metric", "value", "status"]))
    table = study_table(exp, summary)
    assert md_row(table, "index") == ["index", "scenario", *(f"{v.label or v.name} ours" for v in exp.variants)]
    assert md_row(table, f"{first} depth", scen)[2:] == ["0.01"] * len(exp.variants)
    assert md_row(table, f"{first} yaw", scen)[2:] == ["0.02"] * len(exp.variants)
    assert "paper" not in table.split("Variants:")[0]
    with_paper, _ = load_experiment(ROOT / "configs" / "tijjani_table3.yaml")
    header = md_row(study_table(with_paper, summary), "index")
    assert header[2:] == [f"{v.label or v.name} {side}" for v in exp.variants for side in ("ours", "paper")]
