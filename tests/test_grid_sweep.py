"""Two-parameter grid sweeps (`sweep P1 P2 --grid`): the points, the table on a surface known in closed form,
and the command end to end."""

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from marinebench.cli import app
from marinebench.config import SweepParam, SweepSpec
from marinebench.errors import ConfigError
from marinebench.experiments.grid import grid_surfaces, grid_table
from marinebench.experiments.sweep import GRID_N, sweep_experiment, sweep_suffix
from marinebench.loading import load_experiment

from .conftest import ROOT

CFG = ROOT / "configs" / "torben_fig3.yaml"


def test_grid_points_are_every_combination_with_both_values_tagged():
    base, _ = load_experiment(CFG)
    exp = sweep_experiment(base, ["k", "eps"], ["dgnss"], 3, 20.0, CFG, grid=True)
    assert exp.name == "torben_fig3_sweep_grid_k_eps_dgnss_n3_20s"
    assert len(exp.variants) == 3 * 3
    k = base.sweep.params["k"].values(3)
    eps = base.sweep.params["eps"].values(3)
    seen = {(v.tags["param_value"], v.tags["param2_value"]) for v in exp.variants}
    assert seen == {(float(a), float(b)) for a in k for b in eps}
    v = next(v for v in exp.variants if v.name == "k_002_eps_001_dgnss")
    assert v.observer.k == k[2] and v.observer.eps_scale == pytest.approx(eps[1]) and v.tags["param2"] == "eps"
    assert list(v.observer.eps) == [0.1, 0.1, 0.01]  # the eps parameter's fixed settings apply
    assert sweep_suffix(base, ["delta", "k"], grid=True) == "_sweep_grid_delta_k"  # the order given
    assert sweep_suffix(base, ["k", "eps"], n=GRID_N, grid=True) == "_sweep_grid_k_eps"
    with pytest.raises(ConfigError, match="two different parameters"):
        sweep_experiment(base, ["k"], None, 3, None, CFG, grid=True)


def test_the_figure_marks_the_variants_own_tuning_where_it_is_a_number_in_range():
    from marinebench.experiments.grid import tuning

    torben, _ = load_experiment(CFG)
    assert (tuning(torben, "k"), tuning(torben, "delta")) == (0.7, 2.5)
    assert tuning(torben, "eps") is None  # c_eps scales the parameter's fixed eps: the variant's own eps is no c_eps
    tijjani, _ = load_experiment(ROOT / "configs" / "tijjani_table3.yaml")
    assert (tuning(tijjani, "yaw_alpha"), tuning(tijjani, "yaw_k0")) == (1.1, 0.72)  # Table II, not set in the file


def synthetic() -> pd.DataFrame:
    """J = (1 + a) (2 + b) (1 + 0.1 seed) on a 3 x 4 grid, two seeds; one run of the corner a=0, b=0 diverged."""
    rows = []
    for s in (0, 1):
        for a in (0.0, 1.0, 2.0):
            for b in (0.0, 1.0, 2.0, 3.0):
                diverged = s == 1 and a == 0 and b == 0
                rows.append((a, b, s, np.nan if diverged else (1 + a) * (2 + b) * (1 + 0.1 * s),
                             "diverged" if diverged else "ok"))
    df = pd.DataFrame(rows, columns=["param_value", "param2_value", "seed", "value", "status"])
    return df.assign(param="a", param2="b", gnss="default", metric="J", signal="z")


def test_grid_table_on_a_known_surface():
    m = synthetic()
    surface = grid_surfaces(m, "J")["default", "z"]
    assert surface.shape == (3, 4)
    assert surface.loc[2.0, 3.0] == pytest.approx(3 * 5 * 1.05)  # mean over the two seeds
    assert surface.loc[0.0, 0.0] == pytest.approx(2.0)  # the diverged run is left out, not averaged as 0
    spec = SweepSpec(variant="x", metric="J", params={"a": SweepParam(key="a", range=(0, 2)),
                                                       "b": SweepParam(key="b", range=(0, 3))})
    table = grid_table(m, "J", spec)
    # lowest at a = 0, b = 0 (2.0, seed 0 alone); highest at a = 2, b = 3; the largest ratios along each axis are
    # those through that corner: 6.3 / 2 along a (column b = 0), 5.25 / 2 along b (row a = 0)
    assert "| default | z | 2 | 0 | 0 | 15.75 | 3.15× | 2.62× |" in table
    assert "| a \\ b | 0 | 1 | 2 | 3 |" in table and "| 2 | 6.3 | 9.45 | 12.6 | 15.75 |" in table
    flat = grid_table(m.assign(value=1.0), "J", spec)  # a parameter that does not reach the metric: no matrix
    assert "| default | z | 1 | (flat) | (flat) | 1 | 1× | 1× |" in flat and "| a \\ b |" not in flat


def test_cli_grid_sweep_writes_matrix_heat_map_and_no_claims(tmp_path):
    res = CliRunner().invoke(app, ["sweep", "k", "delta", "--grid", "--config", str(CFG), "--n", "2", "--horizon", "60",
                                   "--gnss", "dgnss", "--out", str(tmp_path), "--quiet"])
    assert res.exit_code == 0, res.output
    d = tmp_path / "torben_fig3_sweep_grid_k_delta_dgnss_n2_60s"
    m = pd.read_csv(d / "metrics.csv")
    j = m[m["metric"] == "J_tot"]
    assert len(j) == 4 and set(j["param"]) == {"k"} and set(j["param2"]) == {"delta"}
    assert sorted(set(zip(j["param_value"], j["param2_value"]))) == [(0.0, 0.15), (0.0, 10.0), (1.0, 0.15), (1.0, 10.0)]
    table = (d / "table.md").read_text()
    assert "## Grid: J_tot over k × delta" in table and "| k \\ delta | 0.15 | 10 |" in table
    assert (d / "figures" / "grid.png").stat().st_size > 1000 and not (d / "claims.md").exists()
    bad = CliRunner().invoke(app, ["sweep", "k", "--grid", "--config", str(CFG), "--out", str(tmp_path)])
    assert bad.exit_code == 2 and "two different parameters" in bad.output
