"""Two-parameter grid sweeps (`sweep P1 P2 --grid`): the points, the table on a surface known in closed form,
and the command end to end."""

import json
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from marinebench.claims import GroupsClaim, ProbeClaim, TrendClaim
from marinebench.cli import app
from marinebench.config import SweepParam, SweepSpec
from marinebench.errors import ConfigError
from marinebench.experiments.grid import GridClaim, grid_claims, grid_claims_markdown, grid_surfaces, grid_table
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
    with pytest.raises(ConfigError, match=r"\['k'\] given more than once"):  # one at a time: before, a traceback
        sweep_experiment(base, ["k", "eps", "k"], None, 3, None, CFG)


def test_the_figure_marks_the_variants_own_tuning_where_it_is_a_number_in_range():
    from marinebench.experiments.settings import tuning

    torben, _ = load_experiment(CFG)
    assert (tuning(torben, "k"), tuning(torben, "delta")) == (0.7, 2.5)
    # c_eps scales the parameter's fixed eps = [0.1, 0.1, 0.01]: Table I's eps = [0.5, 0.5, 0.05] is c_eps = 5, and
    # the variant's own eps_scale multiplies it; an eps that no one c_eps gives, or out of range, is not marked
    assert tuning(torben, "eps") == 5.0
    scaled, _ = load_experiment(CFG, sets=["variants[resetting].observer.eps_scale=0.4"])
    assert tuning(scaled, "eps") == pytest.approx(2.0, rel=1e-12)
    for other in ("eps=[0.5, 0.5, 0.1]", "eps_scale=0.01"):
        assert tuning(load_experiment(CFG, sets=[f"variants[resetting].observer.{other}"])[0], "eps") is None, other
    # only a fixed setting of the scaled key itself says what the scale means
    moved, _ = load_experiment(CFG, sets=["sweep.params.eps.fixed={eps: [0.1, 0.1, 0.01], k: 0.5}"])
    assert tuning(moved, "eps") is None
    tijjani, _ = load_experiment(ROOT / "configs" / "tijjani_table3.yaml")
    assert (tuning(tijjani, "yaw_alpha"), tuning(tijjani, "yaw_k0")) == (1.1, 0.72)  # Table II, not set in the file
    # outside the swept range (here, delta = 2.5 above [0.15, 2]) there is nothing to mark on the axis
    narrow, _ = load_experiment(CFG, sets=["sweep.params.delta.range=[0.15, 2.0]", "sweep.params.delta.probes=[0.15]",
                                           "sweep.params.delta.trend=null", "sweep.claims=[]"])
    assert tuning(narrow, "delta") is None and tuning(narrow, "k") == 0.7
    # the range's ends are inside it
    ends, _ = load_experiment(CFG, sets=["sweep.params.delta.range=[2.5, 10.0]", "sweep.params.delta.probes=[2.5]",
                                         "sweep.params.delta.trend=null", "sweep.params.k.range=[0.0, 0.7]",
                                         "sweep.params.k.probes=[0.0]", "sweep.claims=[]"])
    assert (tuning(ends, "delta"), tuning(ends, "k")) == (2.5, 0.7)
    # the ROV observers' settings and per-run world keys: the variant's own, else its scenario's
    observers = ROOT / "configs" / "tijjani_observers.yaml"
    rov, _ = load_experiment(observers)
    assert [tuning(rov, p) for p in ("lmi_decay", "theta", "eo_eps", "offset_depth", "offset_yaw")] == [0.35, 24.39, 0.041, 0.05, 10.0]
    rov, _ = load_experiment(observers, sets=["variants[cdo].world={estimate_offset_yaw_deg: 2.0}",
                                              "variants[cdo].observer.cdo={theta: 30.0}"])
    assert (tuning(rov, "offset_yaw"), tuning(rov, "theta")) == (2.0, 30.0)


def test_heat_map_cells_are_centred_on_the_grid_values():
    """Cell edges: midpoints between grid values (geometric midpoints for log spacing), the end cells as wide
    again as their half-cell inside; one value gets a cell of width 2 around it (in the log for log spacing)."""
    from marinebench.experiments.grid import _edges

    np.testing.assert_allclose(_edges(np.array([0.0, 1.0, 3.0]), log=False), [-0.5, 0.5, 2.0, 4.0])
    np.testing.assert_allclose(_edges(np.array([1.0, 10.0, 1000.0]), log=True), 10.0 ** np.array([-0.5, 0.5, 2.0, 4.0]))
    np.testing.assert_allclose(_edges(np.array([5.0]), log=False), [4.0, 6.0])
    np.testing.assert_allclose(_edges(np.array([10.0]), log=True), [10.0 / np.e, 10.0 * np.e])


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
    assert "Mean over 2 seeds; rows a, columns b." in table and "| group | signal | lowest | at a | at b |" in table
    one = grid_table(m[m["seed"] == 0], "J", spec.model_copy(update={"groups": {"lo": {}, "hi": {}}}))
    assert "One run per point (seed index 0); rows a, columns b." in one and "| gnss | signal | lowest |" in one
    # lowest at a = 0, b = 0 (2.0, seed 0 alone); highest at a = 2, b = 3; the largest ratios along each axis are
    # those through that corner: 6.3 / 2 along a (column b = 0), 5.25 / 2 along b (row a = 0)
    assert "| default | z | 2 | 0 | 0 | 15.75 | 3.15× | 2.62× |" in table
    assert "| a \\ b | 0 | 1 | 2 | 3 |" in table and "| 2 | 6.3 | 9.45 | 12.6 | 15.75 |" in table
    flat = grid_table(m.assign(value=1.0), "J", spec)  # a parameter that does not reach the metric: no matrix
    assert "| default | z | 1 | (flat) | (flat) | 1 | 1× | 1× |" in flat and "| a \\ b |" not in flat


def test_grid_claims_map_the_slices_of_the_other_parameter_where_a_claim_holds():
    """J = (1 + a) (2.5 + b - a) (1 + 0.1 seed), group 'hi' twice group 'lo': along a (three points), J's rank
    correlation with a is positive on the slices b = 1, 2, 3 and negative on b = 0; along b, J grows on every slice."""
    m = synthetic()
    m["value"] = (1 + m["param_value"]) * (2.5 + m["param2_value"] - m["param_value"]) * (1 + 0.1 * m["seed"])
    m["status"] = "ok"
    m = pd.concat([m, m.assign(gnss="hi", value=2 * m["value"])]).replace({"gnss": {"default": "lo"}})
    spec = SweepSpec(variant="x", metric="J", groups={"lo": {}, "hi": {}}, params={
        "a": SweepParam(key="a", range=(0, 2)), "b": SweepParam(key="b", range=(0, 3)), "c": SweepParam(key="c", range=(0, 1))}, claims=[
        TrendClaim(param="a", range=(0, 2), text="J grows with a"),
        ProbeClaim(param="b", at=0, vs=3, factor=0.9, text="b = 0 at least 10 % below b = 3"),
        GroupsClaim(param="a", above="hi", below="lo", text="hi above lo at every a"),
        TrendClaim(param="c", range=(0, 1), text="not a grid parameter: left out"),
    ])
    grows, probe, groups = grid_claims(m, spec)
    # along a, slice b: J at a = 0, 1, 2 is 2.5, 3, 1.5 for b = 0 (rho -0.5); 3.5, 5, 4.5 for b = 1 (rho +0.5); rising for b = 2, 3
    assert (grows.other, grows.holding) == ("b", [1.0, 2.0, 3.0])
    assert {c.where for c in grows.slices[0.0]} == {"lo", "hi"} and not grows.holds_at(0.0)
    # along b, slice a: J(b=0) / J(b=3) = (2.5 - a) / (5.5 - a) < 0.9 on every slice (0.45, 0.33, 0.14)
    assert (probe.other, probe.holding) == ("a", [0.0, 1.0, 2.0])
    assert groups.holding == [0.0, 1.0, 2.0, 3.0]  # hi = 2 lo on every slice
    empty = GridClaim(grows.claim, "J", "b", {0.0: [], 1.0: grows.slices[1.0]})
    assert (empty.holding, empty.failing) == ([1.0], [0.0])  # a slice with nothing checked does not hold
    exp = SimpleNamespace(name="syn", seeds=2, seed=0, model_label=lambda: "toy_vessel")
    md = grid_claims_markdown(exp, [grows, probe], {"a": None, "b": 2.0})
    assert "Simulated on the model `toy_vessel`." in md
    assert "| 1 | J grows with a (config's b = 2: holds) |" in md and "b ∈ {1, 2, 3} | b ∈ {0} |" in md
    assert "| 2 | b = 0 at least 10 % below b = 3 |" in md and "| 2 | a = 1, lo | z |" in md


def test_cli_grid_sweep_writes_matrix_heat_map_and_mapped_claims(tmp_path):
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
    assert (d / "figures" / "grid.png").stat().st_size > 1000
    claims = (d / "claims.md").read_text()  # k's claims along the two slices of delta (delta's trend needs 3 points)
    assert "## Claims along the grid" in claims and "| 1 | J_tot at k = 0.7 at least 20 % below k = 0 (the NPO) |" in claims
    mapped = json.loads((d / "manifest.json").read_text())["grid_claims"]
    # k's probe and groups claims along each slice of delta; delta's trend along each slice of k (two points in
    # [0.15, 10] leave none inside its range [2.5, 10] to rank: it fails there, as in a one-at-a-time sweep)
    assert [(c["along"], c["slices_of"]) for c in mapped] == [("k", "delta"), ("delta", "k")]
    assert sorted(mapped[0]["holds_at"] + mapped[0]["fails_at"]) == [0.15, 10.0]
    assert mapped[1]["fails_at"] == [0.0, 1.0]
    refused = CliRunner().invoke(app, ["sweep", "k", "delta", "--grid", "--require-claims", "--config", str(CFG)])
    assert refused.exit_code == 2 and "--require-claims" in refused.output
    bad = CliRunner().invoke(app, ["sweep", "k", "--grid", "--config", str(CFG), "--out", str(tmp_path)])
    assert bad.exit_code == 2 and "two different parameters" in bad.output


def test_the_heat_map_stars_the_lowest_point_and_crosses_the_variants_tuning(monkeypatch, tmp_path):
    """grid_figure on J = (1 + a) (2 + b) over k x delta: the star at the lowest cell, the cross at Torben's own
    (k, delta) = (0.7, 2.5), delta (log spacing) on a log axis; a flat surface gets no star."""
    from matplotlib.colors import LogNorm

    from marinebench.experiments import grid

    figures = []
    monkeypatch.setattr(grid.plt, "close", figures.append)
    exp, _ = load_experiment(CFG)
    m = synthetic().assign(param="k", param2="delta", metric="J_tot")
    m["param_value"] = m["param_value"] / 4 + 0.25  # k in {0.25, 0.5, 0.75}
    m["param2_value"] = m["param2_value"] + 1.0  # delta in {1, 2, 3, 4}
    m.loc[(m["param_value"] == 0.5) & (m["param2_value"] == 3.0), "value"] = 0.5  # the lowest, away from a corner
    grid.grid_figure(m, ["J_tot"], exp, tmp_path / "grid.png")
    ax = figures[0].axes[0]
    marks = {line.get_marker(): (float(line.get_xdata()[0]), float(line.get_ydata()[0])) for line in ax.get_lines()}
    assert marks == {"*": (3.0, 0.5), "x": (2.5, 0.7)}  # x: delta, y: k
    assert ax.get_xscale() == "log" and ax.get_yscale() == "linear"
    assert ax.get_xlabel() == "δ [s]" and ax.get_ylabel() == "k"
    assert ax.get_title() == "J_tot: default" and "(mean of 2 seeds)" in figures[0].texts[0].get_text()
    norm = ax.collections[0].norm  # log colours from the lowest to the highest seed mean
    assert isinstance(norm, LogNorm) and (norm.vmin, norm.vmax) == (0.5, pytest.approx(3 * 5 * 1.05))
    grid.grid_figure(m.assign(value=1.0), ["J_tot"], exp, tmp_path / "flat.png")
    flat = figures[1].axes[0]
    assert [line.get_marker() for line in flat.get_lines()] == ["x"] and not isinstance(flat.collections[0].norm, LogNorm)
    # two variants side by side, two signals: a row per variant, each crossed at its own tuning (the NPO has no k)
    both = pd.concat([m.assign(sweep_variant=v, signal=sig) for v in ("resetting", "npo") for sig in ("z", "x")])
    two = exp.model_copy(update={"sweep": exp.sweep.model_copy(update={"variants": ["resetting", "npo"]})})
    grid.grid_figure(both, ["J_tot"], two, tmp_path / "both.png")
    panels = [ax for ax in figures[2].axes if ax.get_title()]
    assert [ax.get_title() for ax in panels] == ["J_tot: resetting", "J_tot: resetting, x", "J_tot: npo", "J_tot: npo, x"]
    assert [[line.get_marker() for line in ax.get_lines()] for ax in panels] == [["*", "x"], ["*", "x"], ["*"], ["*"]]


@pytest.mark.parametrize("grid", [False, True])
def test_a_group_whose_every_run_diverges_fails_its_claims_and_is_said_once(tmp_path, grid):
    """Differential GNSS noise of 1e300 m makes every run of that group diverge. Before, its groups claim
    raised ValueError (numpy's nanargmin on an all-NaN curve) after simulating; now the claims on it fail, the
    command warns once, as `run` does, and numpy's all-NaN RuntimeWarnings stay off the terminal; the heat map
    says so across the empty panel, with no legend (c_ε has no own value to cross: before, matplotlib warned of
    a legend without entries)."""
    import warnings

    from marinebench.experiments import grid as grid_module

    args = ["sweep", *(["k", "eps", "--grid"] if grid else ["k"]), "--config", str(CFG), "--n", "2", "--horizon", "20",
            "--out", str(tmp_path), "--quiet", "--set", "sweep.groups.dgnss.gnss_sigma=1e300"]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    assert [str(w.message) for w in caught if w.category in (RuntimeWarning, UserWarning)] == []
    (d,) = tmp_path.iterdir()
    m = pd.read_csv(d / "metrics.csv")
    diverged = m["status"] == "diverged"
    assert set(m.loc[diverged, "gnss"]) == {"dgnss"} and diverged[(m["gnss"] == "dgnss") & (m["metric"] == "J_tot")].all()
    warning = f"warning: {d.name}: {diverged.sum()} metric values from diverged runs excluded (table.md: the diverged column)"
    assert res.output.strip().splitlines() == [warning]
    claims = (d / "claims.md").read_text()
    if grid:
        assert "## Claims along the grid" in claims
    else:
        assert "| 2 | **fails** | dual-band GNSS above differential at every k |" in claims
        assert "| 2 | dualband / dgnss | z | dualband at k=0 " in claims and ", dgnss – | – | > 1 at every value | **fails** |" in claims
    if grid:
        exp, _ = load_experiment(CFG)
        figures = []
        monkeypatch = pytest.MonkeyPatch()
        monkeypatch.setattr(grid_module.plt, "close", figures.append)
        try:
            grid_module.grid_figure(m, ["J_tot"], exp, tmp_path / "again.png")
        finally:
            monkeypatch.undo()
        empty = next(ax for ax in figures[0].axes if ax.get_title() == "J_tot: dgnss")
        assert [t.get_text() for t in empty.texts] == ["every run diverged"] and empty.get_legend() is None
        # the other surface crosses Table I's tuning: k = 0.7 and eps = [0.5, 0.5, 0.05], c_eps = 5
        full = next(ax for ax in figures[0].axes if ax.get_title() == "J_tot: dualband")
        assert "resetting (0.7, 5)" in [t.get_text() for t in full.get_legend().get_texts()]
