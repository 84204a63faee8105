"""Open-loop ASV observers: named outputs, mixed tunings in one batch, and the noise transfer behind Table IV
(their convergence is in the registry-wide conformance suite, tests/test_conformance.py)."""

import numpy as np
import pytest

from marinebench.observers.base import wrap_angle
from marinebench.observers.bejarano import BejaranoObserver, BejaranoTuning
from marinebench.observers.liu_eso import LiuEsoObserver, LiuEsoTuning
from marinebench.scenario import OpenLoopASV, Scenario, stream_rngs
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


def test_observer_outputs_named_signals():
    world = steady_world()
    for obs in (LiuEsoObserver([LiuEsoTuning()], world.plant.Minv),
                BejaranoObserver([BejaranoTuning()], world.plant.Minv)):
        out = obs.outputs(obs.init())
        assert set(out) == set(SIGNALS) == set(obs.signals)
        assert all(v.shape == (1,) for v in out.values())


def test_liu_tunings_of_different_modes_share_a_batch():
    """Linear and fal Liu ESOs (with different alpha) in one batch: each run's derivative is its own."""
    tunings = [LiuEsoTuning(eps=0.1), LiuEsoTuning(eps=0.2, mode="fal"), LiuEsoTuning(eps=0.1, mode="fal", alpha=0.8)]
    Minv = steady_world().plant.Minv
    g = np.random.default_rng(3)
    xhat, y, tau = g.normal(size=(3, 9)), g.normal(size=(3, 3)), g.normal(size=(3, 3))
    together = LiuEsoObserver(tunings, Minv).derivative(xhat, y, tau)
    for b, t in enumerate(tunings):
        alone = LiuEsoObserver([t], Minv).derivative(xhat[b : b + 1], y[b : b + 1], tau[b : b + 1])
        np.testing.assert_array_equal(together[b], alone[0])
    assert not np.allclose(together[1], LiuEsoObserver([tunings[1].model_copy(update={"mode": "linear"})], Minv)
                           .derivative(xhat[1:2], y[1:2], tau[1:2])[0])


def test_wrap_angle():
    a = np.array([0.0, np.pi, -np.pi, 3 * np.pi / 2, -7.0])
    w = wrap_angle(a)
    assert np.all(w <= np.pi) and np.all(w > -np.pi)
    np.testing.assert_allclose(np.cos(w), np.cos(a), atol=1e-12)


NOISE = {"kind": "bandlimited_uniform", "bound": 0.2, "f_low": 0.1, "f_high": 0.5, "n_components": 40, "rms": 0.0327}


def chain_response(gains, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Velocity and disturbance estimates of the 3-state chain ``x1' = x2 + l1 e, x2' = x3 + l2 e, x3' = l3 e``
    (e = y - x1) per unit position measurement at ``omega``: ``(l2 s + l3) s / p(s)`` and ``l3 s^2 / p(s)``."""
    l1, l2, l3 = gains
    s = 1j * omega
    p = s**3 + l1 * s**2 + l2 * s + l3
    return (l2 * s + l3) * s / p, l3 * s**2 / p


def test_noisy_errors_are_the_observers_noise_transfer_sampled_by_the_multisine():
    """Table IV's mechanism, end to end: on a vessel at rest (psi = 0, no input) the u and sigma_u errors are
    the position noise through each observer's linear chain, so their simulated std equals the steady-state
    response of that chain to the seed's multisine components, computed on the same time grid. This checks the
    noise generator, both observers' positional channels with their designed gains, the engine and the std
    recorder against closed-form linear theory (README, Table IV)."""
    zero = {**CONSTANT, "value": 0.0}
    sc = Scenario(name="rest", horizon=40.0, dt=0.005, initial={"eta": (0.0, 0.0, 0.0)}, sensors={"position_noise": NOISE},
                  inputs={"F_u": zero, "tau_r": zero}, disturbances={"F_wu": zero, "F_wv": zero, "tau_wr": zero})
    seeds = np.array([0, 1])
    liu = [LiuEsoTuning(eps=0.2), LiuEsoTuning(eps=0.1)]
    prop = [BejaranoTuning(delta_psi1=d, delta_p1=d, k_omega=1, k_n=1) for d in (1.2, 2.2)]
    world = OpenLoopASV(sc, 11, np.tile(seeds, 4))
    runs = np.arange(8)
    observers = [LiuEsoObserver(liu[:1] * 2 + liu[1:] * 2, world.plant.Minv),
                 BejaranoObserver(prop[:1] * 2 + prop[1:] * 2, world.plant.Minv)]
    window = ErrorMoments(["u", "sigma_u"], t_start=20.0)
    simulate(world, [ObserverGroup(observers[0], runs[:4]), ObserverGroup(observers[1], runs[4:])], sc.dt, 8000, [window])
    std = window.result("std")

    gains = [(3 / t.eps, 3 / t.eps**2, 1 / t.eps**3) for t in liu]
    gains += [tuple(-observers[1].L_pz[2 * i, [0, 2, 4], 0]) for i in range(2)]  # x-channel of -L_pz
    noise = sc.sensors.position_noise.sample(stream_rngs(11, list(seeds), "position_noise"), 2)
    t = np.arange(4000, 8001) * sc.dt
    for run in runs:
        omega, phase = noise.omega[seeds[run % 2], 0], noise.phase[seeds[run % 2], 0]  # channel 0: the x (north) noise, which is e_u's at psi = 0
        for name, H in zip(("u", "sigma_u"), chain_response(gains[run // 2], omega)):
            e = (noise.amplitude * np.abs(H) * np.sin(np.outer(t, omega) + phase + np.angle(H))).sum(axis=1)
            assert std[name][run] == pytest.approx(e.std(), rel=1e-5), (run, name)
