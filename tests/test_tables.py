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


def test_a_study_table_without_a_table_section_shows_depth_and_yaw_of_every_metric():
    """Multi-scenario (Tijjani) layout with ``table`` unset: a row per metric, signal (depth, yaw) and scenario, a
    column per variant, no paper columns."""
    exp, _ = load_experiment(ROOT / "configs" / "tijjani_table3.yaml", ["table=null"])
    scen = exp.scenario_names[0]
    first, second = exp.metrics[0].label, exp.metrics[1].label
    values = {(v.name, sig): [x] for v in exp.variants for sig, x in (("depth", 0.01), ("yaw", 0.02))}
    summary = summarise(pd.concat([tidy_metrics(values, scenario=scen, metric=first),
                                   tidy_metrics(values, scenario=scen, metric=second).assign(value=lambda d: d.value * 3)]))
    table = study_table(exp, summary)
    assert md_row(table, "index") == ["index", "scenario", *(f"{v.label or v.name} ours" for v in exp.variants)]
    assert md_row(table, f"{first} depth", scen)[2:] == ["0.01"] * len(exp.variants)
    assert md_row(table, f"{first} yaw", scen)[2:] == ["0.02"] * len(exp.variants)
    assert md_row(table, f"{second} yaw", scen)[2:] == ["0.06"] * len(exp.variants)
    assert "paper" not in table.split("Variants:")[0]
    with_paper, _ = load_experiment(ROOT / "configs" / "tijjani_table3.yaml")
    header = md_row(study_table(with_paper, summary), "index")
    assert header[2:] == [f"{v.label or v.name} {side}" for v in exp.variants for side in ("ours", "paper")]


def test_several_metrics_are_columns_named_by_metric_with_the_paper_beside_the_first(tiny_config):
    """``table.metrics: [std, rmse]``: 'std (e_u)' and its paper column, then 'rmse (e_u)' with none; the title is
    the table's and the variants list their settings, leaving out unset ones."""
    exp = tiny(tiny_config, "metrics=[{kind: std, t_start: 1.0}, {kind: rmse, t_start: 2.0}]", "table.metrics=[std, rmse]")
    std = tidy_metrics({("liu_eps0.2", "u"): [0.1, 0.2]})
    rmse = std.assign(metric="rmse", value=std["value"] * 3)
    table = markdown_table(exp, summarise(pd.concat([std, rmse])))
    assert table.startswith("## tiny\n")
    assert md_row(table, "variant") == ["variant", "std (e_u)", "std (e_u) paper", "std (e_sigma_u)",
                                        "std (e_sigma_u) paper", "rmse (e_u)", "rmse (e_sigma_u)"]
    assert [c.split(" [")[0] for c in md_row(table, "liu_eps0.2")[1:]] == ["0.15", "0.09", "n/a", "–", "0.45", "n/a"]
    assert "std of est − truth over t ∈ [1, 4] s; rmse: rmse of est − truth over t ∈ [2, 4] s." in table
    proposed = next(line for line in table.splitlines() if line.startswith("- `proposed_d1.2`: "))
    assert proposed.startswith("- `proposed_d1.2`: kind=bejarano, delta_psi1=1.2, delta_p1=1.2,") and "rho" not in proposed


def test_without_a_table_section_the_title_names_the_experiment_and_metric(tiny_config):
    table = markdown_table(tiny(tiny_config, "table=null"), summarise(tidy_metrics({("liu_eps0.2", "u"): [0.1, 0.2]})))
    assert table.startswith(f"## {tiny_config.stem}: std\n")
    assert md_row(table, "variant")[1:3] == ["e_u ours", "e_v ours"] and "paper" not in table


def test_without_a_table_section_every_metric_gets_a_table_of_its_signals(tiny_config):
    """No ``table:`` and two metrics: a table of each, one under the other, titled by the experiment and metric,
    each with its own signals; the preamble, once, gives both windows."""
    exp = tiny(tiny_config, "table=null", "metrics=[{kind: std, t_start: 1.0}, {kind: rmse, t_start: 2.0, signals: [v]}]")
    std = tidy_metrics({("liu_eps0.2", "u"): [0.1, 0.2], ("liu_eps0.2", "v"): [0.3, 0.3]})
    rmse = tidy_metrics({("liu_eps0.2", "v"): [0.5, 0.5]}, metric="rmse")
    table = markdown_table(exp, summarise(pd.concat([std, rmse])))
    head, sections = table.split("\n## ")[0], table.split("\n## ")[1:]
    assert head.startswith(f"## {tiny_config.stem}: std\n") and [s.splitlines()[0] for s in sections] == [
        f"{tiny_config.stem}: rmse"]
    assert "std: std of est − truth over t ∈ [1, 4] s; rmse: rmse of est − truth over t ∈ [2, 4] s." in head
    assert md_row(head, "variant")[1:3] == ["e_u ours", "e_v ours"] and md_row(head, "liu_eps0.2")[1] == "0.15 [-0.485, 0.785]"
    assert md_row(sections[0], "variant") == ["variant", "e_v ours"]
    assert md_row(sections[0], "liu_eps0.2") == ["liu_eps0.2", "0.5 [0.5, 0.5]"]


def test_a_study_table_lists_each_variant_with_its_scenarios_and_set_settings():
    """The variants under a study table: the scenarios each runs on (all when unset) and its controller's settings,
    without the empty gain overrides."""
    exp, _ = load_experiment(ROOT / "configs" / "tijjani_table3.yaml")
    summary = summarise(tidy_metrics({("rise", "depth"): [0.01]}, scenario="S1", metric=exp.metrics[0].label))
    listed = {line.split("`")[1]: line for line in study_table(exp, summary).splitlines() if line.startswith("- `")}
    assert listed["rise"].startswith("- `rise` (S1, S2-C1, S2-C2): kind=rise, feedback=measured")
    assert listed["cdo_srise"].startswith("- `cdo_srise` (S1, S2-C1, S2-C2, S3): kind=srise")
    assert "depth={}" not in listed["rise"] and "None" not in listed["rise"]
    assert "preset=subjugator" in listed["rise"] and "preset" not in listed["cdo_srise"]  # RISE's setting, not S+RISE's


def test_a_study_table_states_each_scenarios_windows_when_they_differ():
    """A metric's window once when the scenarios agree; else each window with its scenarios (S3 runs 44 s)."""
    summary = summarise(tidy_metrics({("rise", "depth"): [0.01]}, scenario="S1", metric="rmse"))
    text = "rmse: rmse of the tracking error (reference − actual) over t ∈ [0, {}] s"
    same, _ = load_experiment(ROOT / "configs" / "tijjani_table3.yaml", ["table.metrics=[rmse]", "scenarios.S3.horizon=40"])
    assert f"Ours: {text.format(40)}. Mean" in study_table(same, summary)
    table = study_table(load_experiment(ROOT / "configs" / "tijjani_table3.yaml", ["table.metrics=[rmse]"])[0], summary)
    assert f"Ours: {text.format(40)} in S1, S2-C1, S2-C2; {text.format(44)} in S3. Mean" in table


def test_a_pipe_in_a_label_or_a_claim_stays_in_its_cell(tmp_path):
    """A variant's label "RISE | old" heads one column of a study table, and a claim about |e_u| is one cell of
    claims.md (escaped as \\|); before, each pipe split the row, so the header had more columns than the rows."""
    from typer.testing import CliRunner

    from marinebench.cli import app

    res = CliRunner().invoke(app, ["run", str(ROOT / "configs" / "tijjani_table3.yaml"), "--profile", "quick", "--seeds",
                                   "1", "--set", "scenarios.*.horizon=2", "--set", "variants.0.label=RISE | old", "--set", 'claims.0.text="|e_u| | x"',
                                   "--out", str(tmp_path), "--quiet"])
    assert res.exit_code == 0, res.output
    table = (tmp_path / "tijjani_table3" / "table.md").read_text().splitlines()
    header = md_row("\n".join(table), "index")
    assert header[2:4] == ["RISE | old ours", "RISE | old paper"]
    assert len(header) == table[table.index(next(line for line in table if line.startswith("| index"))) + 1].count("---")
    assert md_row((tmp_path / "tijjani_table3" / "claims.md").read_text(), "1")[2:4] == ["|e_u| | x", "Table III, Sec. V"]
