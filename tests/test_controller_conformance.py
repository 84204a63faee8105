"""Conformance: every registered controller kind (and preset) obeys the batched command contract."""

import numpy as np
import pytest

from marinebench.controllers.spec import ControllerSpec
from marinebench.registry import kinds

from .conftest import ROOT

SPECS = [
    ControllerSpec(kind="rise"),
    ControllerSpec(kind="rise", preset="table2_equivalent"),
    ControllerSpec(kind="srise"),
    ControllerSpec(kind="custom", source=f"{ROOT / 'examples' / 'custom_controller' / 'pid.py'}:Pid"),  # the example
]
IDS = ["rise_subjugator", "rise_table2_equivalent", "srise", "custom_pid"]
RISE = [(s, i) for s, i in zip(SPECS, IDS) if s.kind != "custom"]


def test_every_registered_controller_kind_is_in_the_suite():
    assert {s.kind for s in SPECS} == set(kinds()["controllers"])


def errors(steps: int, batch: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    g = np.random.default_rng(seed)
    return 0.1 * g.standard_normal((steps, batch, 2)), 0.05 * g.standard_normal((steps, batch, 2))


@pytest.mark.parametrize("spec", SPECS, ids=IDS)
def test_command_shape_and_finite(spec):
    ctrl = spec.build(3)
    e1, e1_dot = errors(1, 3)
    tau = ctrl.command(e1[0], e1_dot[0], 0.01)
    assert tau.shape == (3, 2) and np.isfinite(tau).all()


@pytest.mark.parametrize("spec", [s for s, _ in RISE], ids=[i for _, i in RISE])
def test_rise_command_is_zero_at_the_start(spec):
    e1, e1_dot = errors(1, 3)
    np.testing.assert_allclose(spec.build(3).command(e1[0], e1_dot[0], 0.01), 0.0, atol=1e-12)  # -(.)e2(t0) term, eq. 15


@pytest.mark.parametrize("spec", SPECS, ids=IDS)
def test_runs_in_a_batch_are_independent(spec):
    """A run's commands do not depend on the other runs in its batch (batch-first contract)."""
    e1, e1_dot = errors(50, 4, seed=1)
    together = spec.build(4)
    alone = [spec.build(1) for _ in range(4)]
    for k in range(50):
        tau = together.command(e1[k], e1_dot[k], 0.01)
        for b in range(4):
            np.testing.assert_allclose(tau[b], alone[b].command(e1[k, b : b + 1], e1_dot[k, b : b + 1], 0.01)[0],
                                       rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("spec", SPECS, ids=IDS)
def test_integral_action_pushes_against_a_persistent_error(spec):
    """A constant positive tracking error (eta below eta_d) makes the command grow positive over time."""
    ctrl = spec.build(1)
    e1, zero = np.full((1, 2), 0.05), np.zeros((1, 2))
    first = ctrl.command(e1, zero, 0.01)
    for _ in range(500):
        last = ctrl.command(e1, zero, 0.01)
    assert (last > first).all() and (last > 0).all()
