"""What a config leaves out: the defaults an experiment gets, as the README and the schema describe them."""

import yaml

from marinebench.loading import load_experiment

from .conftest import ROOT


def test_a_minimal_experiment_gets_the_documented_defaults(tmp_path):
    """Root seed 2024 and 5 seeds; one std metric over t >= 5 s (after the start-up peaking) of every estimated signal;
    the engine's step check on at dt |lambda|max <= 0.5 with traces every 0.02 s; no table, figures or claims."""
    path = tmp_path / "minimal.yaml"
    path.write_text(yaml.safe_dump({"scenario": str(ROOT / "scenarios" / "cs2_noiseless.yaml"),
                                    "variants": [{"name": "liu", "observer": {"kind": "liu_eso"}}]}))
    exp, _ = load_experiment(path)
    assert (exp.name, exp.seed, exp.seeds) == ("minimal", 2024, 5)
    [metric] = exp.metrics
    assert (metric.kind, metric.label, metric.t_start, metric.t_end) == ("std", "std", 5.0, None)
    assert metric.signals == ["u", "v", "r", "sigma_u", "sigma_v", "sigma_r"]
    assert (exp.engine.check_step, exp.engine.stiffness_limit, exp.engine.trace_dt) == (True, 0.5, 0.02)
    assert (exp.table, exp.figures, exp.claims, exp.sweep, exp.scenarios) == (None, [], [], None, None)


def test_metric_figure_display_and_sweep_defaults():
    """Recovery looks 4 s after each push for a return within 1 cm and 1 deg (0.0175 rad) of the undisturbed run; a
    figure is a time series with error panels; a display scale is 1; a sweep has 100 points per parameter."""
    from marinebench.config import Display, FigureSpec, RecoveryMetric, SweepParam, SweepSpec

    recovery = RecoveryMetric()
    assert (recovery.window, recovery.tol, recovery.against) == (4.0, {"depth": 0.01, "yaw": 0.0175}, "undisturbed")
    figure = FigureSpec(file="a.png", signals=["u"])
    assert (figure.kind, figure.error) == ("timeseries", True)
    assert (Display().scale, Display().unit) == (1.0, "")
    assert SweepSpec(variant="x", params={"k": SweepParam(key="k", range=(0.0, 1.0))}).n == 100
