"""Paper claims as short-horizon ordering tests with fixed seeds (not exact values)."""

import pytest

from marinebench.experiments.runner import run
from marinebench.loading import load_experiment

from .conftest import ROOT


def means(config: str, *sets: str):
    exp, _ = load_experiment(ROOT / "configs" / config, ["figures=[]", *sets])
    s = run(exp).summary
    return s.set_index(["variant", "signal"])["mean"]


@pytest.fixture(scope="module")
def table3():
    return means("bejarano_table3.yaml", "scenario.horizon=5", "metrics.0.t_start=2", "seeds=2")  # ratios within 5 % of an 8 s run's


@pytest.fixture(scope="module")
def table4():
    return means("bejarano_table4.yaml", "scenario.horizon=30", "seeds=3")


POS = ("u", "v", "sigma_u", "sigma_v")
ROT = ("r", "sigma_r")


def test_table3_liu_faster_tuning_better_on_all_six(table3):
    for s in POS + ROT:
        assert table3["liu_eps0.006", s] < table3["liu_eps0.1", s], s


def test_table3_delta_psi_cuts_rotational_errors_tenfold_only(table3):
    for s in ROT:
        assert table3["proposed_dpsi300", s] * 10 <= table3["proposed_d0.05", s], s
    for s in POS:
        assert abs(table3["proposed_dpsi300", s] / table3["proposed_d0.05", s] - 1) < 0.1, s


def test_table3_delta_p_cuts_positional_errors_only(table3):
    for s in POS:
        assert table3["proposed_dp400", s] < table3["proposed_d0.05", s], s
    for s in ROT:
        assert abs(table3["proposed_dp400", s] / table3["proposed_d0.05", s] - 1) < 0.1, s


def test_table4_proposed_slow_dominates_liu_slow(table4):
    for s in POS:
        assert table4["proposed_d1.2", s] < table4["liu_eps0.2", s], s


def test_table4_faster_tuning_trades_velocity_for_disturbance_liu(table4):
    for s in ("u", "v"):
        assert table4["liu_eps0.1", s] < table4["liu_eps0.2", s], s
    for s in ("sigma_u", "sigma_v"):
        assert table4["liu_eps0.1", s] > table4["liu_eps0.2", s], s


def test_table4_faster_proposed_raises_disturbance_errors(table4):
    for s in ("sigma_u", "sigma_v"):
        assert table4["proposed_d2.2", s] > table4["proposed_d1.2", s], s


def test_fig6_faster_rotational_observer_only_helps():
    m = means("bejarano_fig6.yaml", "scenario.horizon=20", "seeds=2")
    for s in ROT:
        assert m["proposed_dpsi10", s] < m["proposed_dpsi2", s] <= m["proposed_dpsi0.5", s] * 1.001, s


def study_means(config: str, *sets: str):
    exp, _ = load_experiment(ROOT / "configs" / config, ["figures=[]", *sets])
    s = run(exp).summary
    return s.set_index(["scenario", "variant", "signal"])["mean"]


def test_figs4_5_and_7_disturbance_part_falls_with_delta_p_and_k_omega_noise_part_rises():
    """The paper's text for Figs 4-5 and 7 separated into its two parts: without position noise (the same runs'
    disturbance-driven error) a faster delta_p1 or a larger k_omega/k_n gives more accurate velocities; with the
    noise, the sigma estimates degrade (README, Bejarano)."""
    short = ["seeds=2", "scenarios.noisy.horizon=20", "scenarios.noise_free.horizon=20"]
    fig45 = study_means("bejarano_fig4_5.yaml", *short)
    for s in ("u", "v"):
        assert fig45["noise_free", "proposed_dp3", s] < 0.5 * fig45["noise_free", "proposed_dp0.5", s], s
    for s in ("sigma_u", "sigma_v"):
        assert fig45["noisy", "proposed_dp3", s] > fig45["noisy", "proposed_dp0.5", s], s
    fig7 = study_means("bejarano_fig7.yaml", *short, "variants=[{name: kw1, observer: {kind: bejarano, delta_psi1: 0, "
                       "delta_p1: 0, k_omega: 1, k_n: 1}}, {name: kw100, observer: {kind: bejarano, delta_psi1: 0, "
                       "delta_p1: 0, k_omega: 100, k_n: 1}}]")
    assert fig7["noise_free", "kw100", "v"] < 0.5 * fig7["noise_free", "kw1", "v"]
    assert fig7["noisy", "kw100", "sigma_v"] > fig7["noisy", "kw1", "sigma_v"]
