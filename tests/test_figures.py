"""What the figures show: each curve is the right run's data (seed 0 of each variant, wherever it sits in the
batch), errors are truth minus estimate, axes are scaled to the steady state, labels carry units and model."""

import numpy as np
import pandas as pd
import pytest

from marinebench.config import IntMetric
from marinebench.loading import load_experiment
from marinebench.plotting import figures

from .conftest import ROOT, write_tiny

# A batch of 2 variants x 2 seeds in shuffled order: seed 0 of variant 0 is column 3, of variant 1 column 2.
RUN_VARIANT = np.array([1, 0, 1, 0])
RUN_SEED = np.array([1, 1, 0, 0])
SEED0 = {0: 3, 1: 2}


@pytest.fixture
def drawn(monkeypatch):
    """The figures a drawing function made (kept open instead of closed after saving)."""
    kept, close = [], figures.plt.close
    monkeypatch.setattr(figures.plt, "close", kept.append)
    yield kept
    for fig in kept:
        close(fig)


def traces(signals, n=201, horizon=4.0):
    """Every run of a seed sees the same world (the variants' truths agree per seed, as in an open-loop world)."""
    t = np.linspace(0.0, horizon, n)
    rng = np.random.default_rng(7)
    per_seed = {s: np.sin(t)[:, None] + 0.1 * np.arange(2)[None, :] + 0.01 * rng.standard_normal((n, 2)) for s in signals}
    truth = {s: per_seed[s][:, RUN_SEED] for s in signals}
    est = {s: truth[s] + 0.05 * rng.standard_normal((n, 4)) for s in signals}
    for s in signals:
        est[s][:5] += 50.0  # start-up peaking the y axes must not be scaled to
    return t, truth, est


def lines(ax):
    return {line.get_label(): (line.get_xdata(), line.get_ydata()) for line in ax.get_lines()}


def has_zero_line(ax) -> bool:
    """Whether ``ax`` carries an unlabelled horizontal line at y = 0 (the error rows' reference)."""
    return any(line.get_label().startswith("_") and np.all(np.asarray(line.get_ydata()) == 0) for line in ax.get_lines())


def share_x(axes) -> bool:
    """Whether all ``axes`` share one x axis (zooming one zooms them all)."""
    return all(axes[0].get_shared_x_axes().joined(axes[0], ax) for ax in axes[1:])


def test_timeseries_plots_seed0_of_each_variant_its_error_and_scales_to_the_steady_state(tmp_path, drawn):
    exp, _ = load_experiment(write_tiny(tmp_path))
    spec = exp.figures[0].model_copy(update={"signals": ["u", "sigma_v"]})
    t, truth, est = traces(["u", "sigma_v"])
    assert t[50] == 1.0  # the first metric's t_start, a sample time: the scaled window includes it
    est["u"][50, 3] = 5.0  # the maximum sits on the window's first sample
    path = tmp_path / "u.png"
    figures.timeseries(exp, spec, t, truth, est, RUN_VARIANT, RUN_SEED, path)
    assert path.stat().st_size > 0 and len(drawn) == 1
    fig = drawn[0]
    axes = fig.axes
    assert len(axes) == 4  # a signal row and its error row, per signal
    for i, sig in enumerate(["u", "sigma_v"]):
        top, err = lines(axes[2 * i]), lines(axes[2 * i + 1])
        assert list(top) == ["actual", "liu_eps0.2", "proposed_d1.2"]
        np.testing.assert_array_equal(top["actual"][1], truth[sig][:, 2])  # the first seed-0 run's truth
        for v, name in enumerate(["liu_eps0.2", "proposed_d1.2"]):
            b = SEED0[v]
            np.testing.assert_array_equal(top[name][1], est[sig][:, b])
            np.testing.assert_array_equal(err[name][1], truth[sig][:, b] - est[sig][:, b])
        late = t >= 1.0  # the first metric's t_start
        lo, hi = axes[2 * i].get_ylim()
        data = np.concatenate([truth[sig][late, 2], est[sig][late][:, [3, 2]].ravel()])
        assert lo < data.min() and hi > data.max() and hi < 10.0  # the start-up spike (+50) is off the axis
        span = data.max() - data.min()
        assert hi - lo == pytest.approx(1.2 * span)
        lo, hi = axes[2 * i + 1].get_ylim()
        errors = (truth[sig] - est[sig])[late][:, [3, 2]]
        assert lo == pytest.approx(errors.min() - 0.1 * np.ptp(errors)) and hi == pytest.approx(errors.max() + 0.1 * np.ptp(errors))
        assert has_zero_line(axes[2 * i + 1]) and not has_zero_line(axes[2 * i])
    assert share_x(axes) and all(ax.get_legend() is not None for ax in axes[::2])
    assert axes[0].get_ylabel() == "surge u [m/s]" and axes[1].get_ylabel() == "error [m/s]"
    assert axes[2].get_ylabel() == "σ_v [m/s²]" and axes[-1].get_xlabel() == "time [s]"
    assert "t ≥ 1 s" in fig._suptitle.get_text() and "model cybership2" in fig._suptitle.get_text()


def test_timeseries_draws_each_variants_own_trajectory_when_a_closed_loop_drives_them_apart(tmp_path, drawn):
    """Observers that steer the vehicle (CDO-S+RISE with another CDO tuning) give each variant its own truth: one black
    "actual" would pair one variant's estimate with another's trajectory, so each variant's actual is drawn dashed in
    its colour, and the axes are scaled to all of them."""
    exp, _ = load_experiment(write_tiny(tmp_path))
    spec = exp.figures[0].model_copy(update={"signals": ["u"]})
    t, truth, est = traces(["u"])
    truth["u"][:, SEED0[1]] += 3.0 * (t >= 2.0)  # variant 1's loop leaves variant 0's after 2 s
    est["u"][:, SEED0[1]] = truth["u"][:, SEED0[1]] + 0.01
    figures.timeseries(exp, spec, t, truth, est, RUN_VARIANT, RUN_SEED, tmp_path / "own.png")
    top, err = lines(drawn[0].axes[0]), lines(drawn[0].axes[1])
    names = ["liu_eps0.2", "proposed_d1.2"]
    assert list(top) == ["liu_eps0.2", "actual (liu_eps0.2)", "proposed_d1.2", "actual (proposed_d1.2)"]
    by_label = {line.get_label(): line for line in drawn[0].axes[0].get_lines()}
    for v, name in enumerate(names):
        np.testing.assert_array_equal(top[f"actual ({name})"][1], truth["u"][:, SEED0[v]])
        np.testing.assert_array_equal(err[name][1], truth["u"][:, SEED0[v]] - est["u"][:, SEED0[v]])
        assert by_label[f"actual ({name})"].get_color() == by_label[name].get_color()
        assert by_label[f"actual ({name})"].get_linestyle() == "--"
    assert drawn[0].axes[0].get_ylim()[1] > truth["u"][t >= 1.0, SEED0[1]].max()  # the upper trajectory is in view


def test_timeseries_time_window_own_y_scale_and_world_signals_without_estimate(tmp_path, drawn):
    exp, _ = load_experiment(write_tiny(tmp_path))
    t, truth, est = traces(["u", "tau_yaw"])
    after = float(t[125])  # 2.5 s, a sample time: the window includes it
    truth["tau_yaw"][125, 2] = -3.0  # the minimum sits on the window's first sample
    spec = exp.figures[0].model_copy(update={"signals": ["u", "tau_yaw"], "error": False, "t_range": (2.0, 3.0),
                                             "ylim_after": after, "variants": ["proposed_d1.2"], "title": "zoom"})
    del est["tau_yaw"]  # a control input: recorded in the world, estimated by nobody
    est["u"][130:, 3] = np.nan  # a diverged run of a variant this figure leaves out
    est["u"][140:, 2] = np.nan  # the drawn run diverges: its finite part still scales the axis
    figures.timeseries(exp, spec, t, truth, est, RUN_VARIANT, RUN_SEED, tmp_path / "z.png")
    axes = drawn[0].axes
    assert len(axes) == 2
    window = (t >= 2.0) & (t <= 3.0)
    top = lines(axes[0])
    assert list(top) == ["actual", "proposed_d1.2"]
    np.testing.assert_array_equal(top["proposed_d1.2"][0], t[window])
    np.testing.assert_array_equal(top["proposed_d1.2"][1], est["u"][window, 2])
    finite = np.concatenate([truth["u"][(t >= after) & window, 2], est["u"][(t >= after) & (t < t[140]) & window, 2]])
    lo, hi = axes[0].get_ylim()
    assert lo == pytest.approx(finite.min() - 0.1 * np.ptp(finite)) and hi == pytest.approx(finite.max() + 0.1 * np.ptp(finite))
    world = lines(axes[1])
    assert list(world) == ["proposed_d1.2"]
    np.testing.assert_array_equal(world["proposed_d1.2"][1], truth["tau_yaw"][window, 2])
    late = (t >= after) & window
    lo, _ = axes[1].get_ylim()
    assert lo < -3.0 and lo == pytest.approx(truth["tau_yaw"][late, 2].min() - 0.1 * np.ptp(truth["tau_yaw"][late, 2]))
    assert axes[1].get_ylabel() == "tau_yaw [N m]"
    assert drawn[0]._suptitle.get_text().startswith("zoom\n(y axes scaled to t ≥ 2.5 s")


def test_timeseries_scales_from_zero_when_the_first_metric_has_no_window(tmp_path, drawn):
    exp, _ = load_experiment(write_tiny(tmp_path))
    exp = exp.model_copy(update={"metrics": [IntMetric()]})  # INT has no t_start
    t, truth, est = traces(["u"])
    figures.timeseries(exp, exp.figures[0].model_copy(update={"signals": ["u"], "error": False}), t, truth, est,
                       RUN_VARIANT, RUN_SEED, tmp_path / "u.png")
    _, hi = drawn[0].axes[0].get_ylim()
    assert hi > 50.0  # the start-up spike is part of the scaled data
    assert "(y axes scaled to t ≥ 0 s;" in drawn[0]._suptitle.get_text()


def tracking_traces(n_var):
    """Random closed-loop traces with seed 0 of variant v at column 2 * (n - v) - 1 (a reversed batch)."""
    run_variant = np.repeat(np.arange(n_var), 2)[::-1].copy()
    run_seed = np.tile([0, 1], n_var)
    t = np.linspace(0.0, 10.0, 101)
    rng = np.random.default_rng(3)
    truth = {s: rng.standard_normal((t.size, 2 * n_var))
             for s in ["depth", "yaw", "depth_ref", "yaw_ref", "tau_depth", "tau_yaw"]}
    est = {s: rng.standard_normal((t.size, 2 * n_var)) for s in ["depth", "yaw"]}  # an observer's: not drawn
    return t, truth, est, run_variant, run_seed


def test_tracking_columns_reference_error_and_input_yaw_in_degrees(tmp_path, drawn):
    exp, _ = load_experiment(ROOT / "configs" / "tijjani_table3.yaml")
    part = exp.part("S1")
    spec = next(f for f in part.figures if f.scenario == "S1").model_copy(update={"t_range": (2.0, 5.0), "title": "trk"})
    n_var = len(part.variants)
    t, truth, est, run_variant, run_seed = tracking_traces(n_var)
    figures.tracking(part, spec, t, truth, est, run_variant, run_seed, tmp_path / "f.png")
    axes = np.array(drawn[0].axes).reshape(3, 2)
    labels = [v.label or v.name for v in part.variants]
    seed0 = [int(np.flatnonzero((run_variant == v) & (run_seed == 0))[0]) for v in range(n_var)]
    window = slice(20, 51)  # 2.0 s to 5.0 s, both ends included
    for j, (s, k) in enumerate([("depth", 1.0), ("yaw", 180 / np.pi)]):
        top, mid, bottom = (lines(a) for a in axes[:, j])
        assert list(top) == ["desired", *labels]
        np.testing.assert_array_equal(top["desired"][0], t[window])
        np.testing.assert_allclose(top["desired"][1], k * truth[f"{s}_ref"][window, seed0[0]])
        for label, b in zip(labels, seed0):  # the tracking error, whichever estimate a variant reports
            np.testing.assert_allclose(top[label][1], k * truth[s][window, b])
            np.testing.assert_allclose(mid[label][1], k * (truth[f"{s}_ref"][window, b] - truth[s][window, b]))
            np.testing.assert_array_equal(bottom[label][1], truth[f"tau_{s}"][window, b])
        assert has_zero_line(axes[1, j]) and not has_zero_line(axes[0, j])
    assert share_x(axes.ravel()) and all(ax.get_legend() is not None for ax in axes.ravel())
    assert (tmp_path / "f.png").stat().st_size > 0
    assert axes[0, 1].get_ylabel() == "yaw [deg]" and axes[1, 0].get_ylabel() == "error [m]"
    assert axes[2, 0].get_ylabel() == "tau_depth [N]" and axes[2, 1].get_xlabel() == "time [s]"
    title = drawn[0]._suptitle.get_text()
    assert title.startswith("trk (seed 0, model leonard_like")


def test_tracking_of_one_dof_is_one_column(tmp_path, drawn):
    exp, _ = load_experiment(ROOT / "configs" / "tijjani_table3.yaml")
    part = exp.part("S1")
    spec = next(f for f in part.figures if f.scenario == "S1").model_copy(update={"signals": ["depth"], "title": None})
    t, truth, est, run_variant, run_seed = tracking_traces(len(part.variants))
    figures.tracking(part, spec, t, truth, est, run_variant, run_seed, tmp_path / "d.png")
    axes = drawn[0].axes
    assert len(axes) == 3 and [ax.get_ylabel() for ax in axes] == ["depth [m]", "error [m]", "tau_depth [N]"]
    assert drawn[0]._suptitle.get_text().startswith(f"{spec.file} (seed 0")


def test_a_long_title_is_wrapped_to_the_figures_width_not_cut_off(tmp_path, drawn):
    """Fig. 3's sweep figure is 7 in wide and its model label long: the title was cut off at both edges; and in a
    tall figure (seven panels, as the ROV observers' sweep) tight_layout let the three-line title overlap the top
    panel."""
    fig, _ = figures.plt.subplots(7, 1, figsize=(7, 18.2))
    figures.save(fig, "torben_fig3: J_tot sensitivity\n(one parameter at a time, mean of 5 seeds (band: their range); "
                 "model supply_shipx_lf (observers: supply_dp_linear))", tmp_path / "f.png")
    title = fig._suptitle
    box = title.get_window_extent(fig.canvas.get_renderer())
    assert 0 <= box.x0 and box.x1 <= fig.bbox.width
    assert max(ax.get_tightbbox(fig.canvas.get_renderer()).y1 for ax in fig.axes) <= box.y0
    assert title.get_text().startswith("torben_fig3: J_tot sensitivity\n") and title.get_text().count("\n") == 2
    assert (tmp_path / "f.png").stat().st_size > 0


def test_a_sweep_panel_marks_the_variants_own_value_and_labels_a_log_axis_in_plain_numbers(tmp_path, drawn):
    """Fig. 3: a dotted line at Table I's k = 0.7, δ = 2.5 s and ε = [0.5, 0.5, 0.05], which is c_ε = 5 of the
    sweep's fixed ε = [0.1, 0.1, 0.01]; δ's log axis reads 0.2 … 10, not 2×10⁻¹ … 10¹."""
    from marinebench.experiments.curves import sweep_figure

    exp = load_experiment(ROOT / "configs" / "torben_fig3.yaml")[0]
    values = {"k": [0.0, 0.5, 1.0], "delta": [0.15, 1.0, 10.0], "eps": [0.1, 1.0, 10.0]}
    rows = [("torben_fig3", "s", "resetting", seed, "z", "J_tot", 10.0 + x + seed, "ok", p, x, g)
            for p, xs in values.items() for x in xs for g in ("dgnss", "dualband") for seed in (0, 1)]
    metrics = pd.DataFrame(rows, columns=["experiment", "scenario", "variant", "seed", "signal", "metric", "value", "status",
                                          "param", "param_value", "gnss"])
    sweep_figure(metrics, ["J_tot"], exp, tmp_path / "sweep.png")
    (fig,) = drawn
    k_ax, delta_ax, eps_ax = fig.axes

    def dotted(ax):
        return [line.get_xdata()[0] for line in ax.get_lines() if line.get_linestyle() == ":"]

    assert dotted(k_ax) == [0.7] and dotted(delta_ax) == [2.5] and dotted(eps_ax) == [5.0]
    assert "dotted: resetting's own value" in " ".join(fig._suptitle.get_text().split())
    fig.canvas.draw()
    labels = {t.get_text() for t in delta_ax.get_xticklabels(which="both") if t.get_text()}
    assert {"1", "10"} <= labels and not any("10^" in s or "times" in s for s in labels), labels


def test_a_figure_with_a_hidden_panel_is_saved(tmp_path, drawn):
    """A hidden panel has no extent (get_tightbbox is None); the layout below the title must not fail on it."""
    fig, axes = figures.plt.subplots(1, 2, figsize=(7, 3))
    axes[1].set_visible(False)
    figures.save(fig, "a title", tmp_path / "f.png")
    assert (tmp_path / "f.png").stat().st_size > 0
