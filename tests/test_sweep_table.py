"""The sweep's table.md: probe values interpolated per seed, paired changes, trends and group ratios,
checked on a synthetic metrics table whose curves are known in closed form."""

import numpy as np
import pandas as pd
import pytest

from marinebench.config import SweepParam, SweepSpec
from marinebench.experiments.curves import sweep_claims, sweep_table

from .conftest import md_row as row


def synthetic(seeds=(0, 1)) -> pd.DataFrame:
    """J = (10 - 5 k) (1 + 0.1 seed) for 'a', twice that for 'b'; J = delta (1 + 0.1 seed) on a log grid."""
    rows = []
    for s in seeds:
        for g, f in (("a", 1.0), ("b", 2.0)):
            for k in np.linspace(0, 1, 11):
                rows.append(("k", k, g, s, f * (10 - 5 * k) * (1 + 0.1 * s)))
            for d in np.geomspace(0.1, 10, 9):
                rows.append(("delta", d, g, s, f * d * (1 + 0.1 * s)))
    df = pd.DataFrame(rows, columns=["param", "param_value", "gnss", "seed", "value"])
    return df.assign(metric="J_tot", signal="z", status="ok")


SPEC = SweepSpec(variant="x", metric="J_tot", params={
    "k": SweepParam(key="k", range=(0, 1), probes=[0.0, 0.75]),
    "delta": SweepParam(key="delta", range=(0.1, 10), spacing="log", probes=[1.0, 10.0], trend=(1.0, 10.0)),
})


def test_probes_changes_trends_and_group_ratios():
    t = sweep_table(synthetic(), "J_tot", SPEC)
    # k = 0.75 lies between grid points 0.7 and 0.8: linear interpolation is exact for a linear curve
    mean_at = np.mean([(10 - 3.75) * 1.0, (10 - 3.75) * 1.1])
    assert row(t, "k", "a", "z", "0.75")[4].startswith(f"{mean_at:.4g} [")
    assert row(t, "k", "a", "z", "0.75")[5].startswith("-37.5 % [-37.5 %, -37.5 %]")  # paired: the seed factor cancels
    # log spacing: J = delta is linear in delta but interpolated in log(delta) between grid points; 1 and 10 are on the grid
    assert row(t, "delta", "b", "z", "10")[5].startswith("+900.0 %")
    assert row(t, "delta", "a", "z", "[1, 10]")[5] == "+1.00"
    assert row(t, "k", "z", "b / a")[3:] == ["2", "0", "2", "0", "–"]  # never equal


def test_one_seed_has_no_intervals_and_bad_probes_are_refused():
    t = sweep_table(synthetic(seeds=(0,)), "J_tot", SPEC)
    assert "One run per point" in t and row(t, "k", "a", "z", "0.75")[4:] == ["6.25", "-37.5 %"]
    with pytest.raises(ValueError, match="outside the range"):
        SweepParam(key="k", range=(0, 1), probes=[1.5])
    with pytest.raises(ValueError, match=r"\[0.5\] given more than once"):  # before: the same table row twice
        SweepParam(key="k", range=(0, 1), probes=[0.5, 0.2, 0.5])
    with pytest.raises(ValueError, match="lower end"):
        SweepParam(key="k", range=(0, 1), trend=(0.8, 0.2))


def test_other_observers_sweep_the_same_way(tmp_path):
    """The issue's example: `marinebench sweep --config configs/bejarano_table4.yaml delta_p1`."""
    from typer.testing import CliRunner

    from marinebench.cli import app

    from .conftest import ROOT

    res = CliRunner().invoke(app, ["sweep", "--config", str(ROOT / "configs" / "bejarano_table4.yaml"), "delta_p1",
                                   "--n", "2", "--horizon", "8", "--seeds", "1", "--out", str(tmp_path), "--quiet"])
    assert res.exit_code == 0, res.output
    d = tmp_path / "bejarano_table4_sweep_delta_p1_n2_8s"
    m = pd.read_csv(d / "metrics.csv")
    std = m[m["metric"] == "std"]
    assert sorted(std["param_value"].unique()) == [0.2, 5.0] and {"u", "v", "sigma_u", "sigma_v"} <= set(std["signal"])
    table = (d / "table.md").read_text()
    assert row(table, "delta_p1", "default", "sigma_u", "1.2")[4] != "–" and (d / "figures" / "sweep.png").exists()


def test_sweep_claims_on_known_curves():
    """k: J falls to 62.5 % at k = 0.75; delta: J rises; group b is twice a everywhere."""
    claims = [
        {"kind": "probe", "param": "k", "at": 0.75, "vs": 0.0, "factor": 0.8, "text": "k gain > 20 %"},
        {"kind": "probe", "param": "k", "at": 0.75, "vs": 0.0, "factor": 0.6, "text": "k gain > 40 %"},
        {"kind": "trend", "param": "delta", "range": (1.0, 10.0), "text": "grows"},
        {"kind": "trend", "param": "delta", "range": (1.0, 10.0), "decreasing": True, "text": "falls"},
        {"kind": "groups", "param": "k", "above": "b", "below": "a", "text": "b above a"},
        {"kind": "groups", "param": "k", "above": "a", "below": "b", "text": "a above b"},
        {"kind": "probe", "param": "k", "at": 0.75, "vs": 0.0, "groups": ["b"], "text": "only b"},
    ]
    spec = SPEC.model_copy(update={"groups": {"a": {}, "b": {}}})
    spec = SweepSpec.model_validate({**spec.model_dump(), "claims": claims})
    res = sweep_claims(synthetic(), spec)
    assert [r.holds for r in res] == [True, False, True, False, True, False, True]
    assert res[0].checks[0].statistic == pytest.approx(0.625) and res[2].checks[0].statistic == pytest.approx(1.0)
    assert res[0].checks[0].ci == pytest.approx((0.625, 0.625))  # the ratio of means is 0.625 in every resample
    assert res[0].checks[0].means == pytest.approx({"k=0.75": 6.5625, "k=0": 10.5})
    assert res[4].checks[0].statistic == pytest.approx(2.0) and [c.where for c in res[6].checks] == ["b"]
    only_a = synthetic()[lambda d: d["gnss"] == "a"]
    # with one group swept, the groups claims and the claim about group b alone are not checked
    assert [r.claim.text for r in sweep_claims(only_a, spec)] == ["k gain > 20 %", "k gain > 40 %", "grows", "falls"]
    with pytest.raises(ValueError, match="unknown groups"):
        SweepSpec.model_validate({**spec.model_dump(), "claims": [{**claims[0], "groups": ["c"]}]})
    with pytest.raises(ValueError, match="outside k's range"):
        SweepSpec.model_validate({**spec.model_dump(), "claims": [{**claims[0], "at": 2.0}]})


def test_log_probes_interpolate_in_the_log_and_trends_keep_to_their_range():
    """J = (1 + |log10 delta|) (1 + 0.1 seed): falls on [0.1, 1], rises above. A probe between grid points is
    interpolated in log(delta); the trend over [0.1, 1] sees only the falling half."""
    m = synthetic()
    is_delta = m["param"] == "delta"
    m.loc[is_delta, "value"] = (1 + np.abs(np.log10(m.loc[is_delta, "param_value"]))) * (1 + 0.1 * m.loc[is_delta, "seed"])
    spec = SweepSpec.model_validate({**SPEC.model_dump(), "params": {
        "delta": {"key": "delta", "range": (0.1, 10), "spacing": "log", "probes": [1.0, 3.0], "trend": (0.1, 1.0)}},
        "claims": [{"kind": "trend", "param": "delta", "range": (0.1, 1.0), "decreasing": True, "text": "falls"}]})
    t = sweep_table(m[is_delta], "J_tot", spec)
    # 3 lies between the grid points 10^0.25 and 10^0.5, where J is linear in log10(delta): J(3) = 1 + log10(3)
    assert row(t, "delta", "a", "z", "3")[4].startswith(f"{1.05 * (1 + np.log10(3)):.4g} [")
    assert row(t, "delta", "a", "z", "[0.1, 1]")[4:] == ["5", "-1.00"]
    (falls,) = sweep_claims(m[is_delta], spec)
    assert falls.holds and falls.checks[0].statistic == pytest.approx(-1.0)


def test_a_groups_claim_needs_every_value():
    """'b above a at every k': b is twice a except at k = 1, where it is half; the claim fails there, and its
    statistic is that lowest ratio (not the ratio on average, 1.86)."""
    m = synthetic()
    m.loc[(m["gnss"] == "b") & (m["param"] == "k") & np.isclose(m["param_value"], 1.0), "value"] /= 4
    spec = SweepSpec.model_validate({**SPEC.model_dump(), "groups": {"a": {}, "b": {}}, "claims": [
        {"kind": "groups", "param": "k", "above": "b", "below": "a", "text": "b above a"}]})
    (res,) = sweep_claims(m, spec)
    assert not res.holds and res.checks[0].statistic == pytest.approx(0.5)
    assert res.checks[0].means == pytest.approx({"b at k=1": 2.625, "a": 5.25})  # where the lowest ratio is


def test_trend_claims_take_the_range_with_its_ends_and_need_three_points():
    """J = (1 + |log10 delta|) (1 + 0.1 seed), raised by 30 % at delta = 1: over [0.1, 1] (5 grid points, both
    ends included) the mean curve's ranks are 5 4 3 1 2, Spearman rho = -0.9, short of a claimed -0.95; over
    [1, 10] ranks 2 1 3 4 5, rho = +0.9. A range holding 3 grid points gets a rho; 2 points get none, and fail."""
    m = synthetic()
    m = m[m["param"] == "delta"].copy()
    m["value"] = (1 + np.abs(np.log10(m["param_value"]))) * (1 + 0.1 * m["seed"])
    m.loc[np.isclose(m["param_value"], 1.0), "value"] *= 1.3
    claims = [
        {"kind": "trend", "param": "delta", "range": (0.1, 1.0), "decreasing": True, "min_rho": 0.95, "text": "falls"},
        {"kind": "trend", "param": "delta", "range": (1.0, 10.0), "min_rho": 0.5, "text": "grows"},
        {"kind": "trend", "param": "delta", "range": (0.1, 0.4), "decreasing": True, "text": "3 points"},
        {"kind": "trend", "param": "delta", "range": (0.1, 0.2), "decreasing": True, "text": "2 points"},
    ]
    spec = SweepSpec.model_validate({**SPEC.model_dump(), "claims": claims, "params": {
        "delta": {"key": "delta", "range": (0.1, 10), "spacing": "log", "trend": (0.1, 0.2)}}})
    falls, grows, three, two = (r.checks[0] for r in sweep_claims(m, spec))
    assert falls.statistic == pytest.approx(-0.9) and not falls.holds and falls.needs == "< -0.95 (Spearman ρ)"
    assert grows.statistic == pytest.approx(0.9) and grows.holds and grows.needs == "> +0.5 (Spearman ρ)"
    assert three.statistic == pytest.approx(-1.0) and three.holds
    assert np.isnan(two.statistic) and not two.holds
    assert row(sweep_table(m, "J_tot", spec), "delta", "a", "z", "[0.1, 0.2]")[4:] == ["2", "–"]
    spec3 = SweepSpec.model_validate({**spec.model_dump(), "params": {
        "delta": {"key": "delta", "range": (0.1, 10), "spacing": "log", "trend": (0.1, 0.4)}}})
    assert row(sweep_table(m, "J_tot", spec3), "delta", "a", "z", "[0.1, 0.4]")[4:] == ["3", "-1.00"]


def test_sweep_table_says_how_many_seeds_names_its_group_column_and_shows_diverged_points():
    """The preamble counts the seeds; the group column is headed `group` for a sweep without named world groups
    and `gnss` (metrics.csv's column) with them; a curve whose every run diverged shows '–' and counts them,
    also at its probes, in its trend and between groups; a metric with no values says so."""
    m = synthetic(seeds=(0, 1, 2))
    m.loc[m["param"] == "delta", "status"] = "diverged"
    t = sweep_table(m, "J_tot", SPEC)
    assert "3 runs per point (seeds 0..2)" in t and "| param | group | signal | points |" in t
    assert row(t, "delta", "a", "z", "9")[4:] == ["–", "–", "–", "–", "27"]
    assert row(t, "delta", "z", "b / a")[3:] == ["–", "–", "–", "–", "–"] and row(t, "k", "z", "b / a")[3] == "2"
    assert row(t, "delta", "a", "z", "10")[4:] == ["–", "–"] and row(t, "delta", "a", "z", "[1, 10]")[4:] == ["5", "–"]
    named = SPEC.model_copy(update={"groups": {"a": {}, "b": {}}})
    assert "| param | gnss | signal | points |" in sweep_table(m, "J_tot", named)
    assert sweep_table(m, "rmse", SPEC) == "## Sweep: rmse vs each parameter\n\nNo values of metric 'rmse'.\n"
