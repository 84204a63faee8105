"""Conformance: every registered observer converges on a noiseless plant of its own model."""

import numpy as np
import pytest

from marinebench.observers.base import wrap_angle
from marinebench.observers.bejarano import BejaranoObserver, BejaranoTuning
from marinebench.observers.liu_eso import LiuEsoObserver, LiuEsoTuning
from marinebench.scenario import OpenLoopASV, Scenario
from marinebench.sim.engine import ObserverGroup, simulate
from marinebench.sim.recorders import ErrorMoments

SIGNALS = ["u", "v", "r", "sigma_u", "sigma_v", "sigma_r"]
CONSTANT = {"kind": "constant"}


def steady_world(seeds: int = 1) -> OpenLoopASV:
    """Constant thrust, torque and environment: the vessel settles in a steady turn, so sigma is constant."""
    sc = Scenario(
        name="steady",
        horizon=40.0,
        dt=0.005,
        inputs={"F_u": {**CONSTANT, "value": 3.0}, "tau_r": {**CONSTANT, "value": 0.1}},
        disturbances={"F_wu": {**CONSTANT, "value": 0.3}, "F_wv": {**CONSTANT, "value": -0.2},
                      "tau_wr": {**CONSTANT, "value": 0.02}},
    )
    return OpenLoopASV(sc, 0, np.zeros(seeds, dtype=int))


@pytest.mark.parametrize(
    "make",
    [
        lambda Minv: LiuEsoObserver([LiuEsoTuning(eps=0.1)], Minv),
        lambda Minv: LiuEsoObserver([LiuEsoTuning(eps=0.1, mode="fal")], Minv),
        lambda Minv: BejaranoObserver([BejaranoTuning(delta_psi1=1.0, delta_p1=1.0, k_n=1)], Minv),
        lambda Minv: BejaranoObserver([BejaranoTuning()], Minv),
    ],
    ids=["liu_linear", "liu_fal", "bejarano_noisy_tuning", "bejarano_noiseless_tuning"],
)
def test_observer_converges_on_noiseless_plant(make):
    world = steady_world()
    obs = make(world.plant.Minv)
    late = ErrorMoments(SIGNALS, t_start=35.0)
    simulate(world, [ObserverGroup(obs, np.array([0]))], 0.005, 8000, [late])
    worst = late.result("max_abs")
    for s in SIGNALS:
        assert worst[s][0] < 1e-4, (s, worst[s][0])


def test_observer_outputs_named_signals():
    world = steady_world()
    for obs in (LiuEsoObserver([LiuEsoTuning()], world.plant.Minv),
                BejaranoObserver([BejaranoTuning()], world.plant.Minv)):
        out = obs.outputs(obs.init())
        assert set(out) == set(SIGNALS) == set(obs.signals)
        assert all(v.shape == (1,) for v in out.values())


def test_wrap_angle():
    a = np.array([0.0, np.pi, -np.pi, 3 * np.pi / 2, -7.0])
    w = wrap_angle(a)
    assert np.all(w <= np.pi) and np.all(w > -np.pi)
    np.testing.assert_allclose(np.cos(w), np.cos(a), atol=1e-12)
