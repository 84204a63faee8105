"""Engine: integration accuracy, stiffness check, determinism, divergence flagging."""

import numpy as np
import pytest

from marinebench.batch import columns
from marinebench.errors import StiffnessError
from marinebench.experiments.runner import run
from marinebench.loading import load_experiment
from marinebench.observers.liu_eso import LiuEsoObserver, LiuEsoTuning
from marinebench.sim.engine import ObserverGroup, check_step, rk4_step

from .conftest import ROOT, accepts_and_refuses, md_row


def short(tiny_config, *sets):
    exp, _ = load_experiment(tiny_config, list(sets))
    return run(exp)


def values(result):
    m = result.metrics
    return m.set_index(["variant", "seed", "signal", "metric"])["value"]


def errors_at_trace_times(result):
    t, truth, est = result.traces
    return t, {k: est[k] - truth[k] for k in est}


def test_integration_error_small_at_configured_step(tiny_config):
    """Noisy configs use dt = 0.005: the estimation errors at common times move by < 1e-5 when dt halves,
    four orders below the ~0.07-0.15 errors of Table IV."""
    ta, a = errors_at_trace_times(short(tiny_config, "scenario.dt=0.005"))
    tb, b = errors_at_trace_times(short(tiny_config, "scenario.dt=0.0025"))
    np.testing.assert_allclose(ta, tb)
    for k in a:
        assert np.abs(a[k][10:] - b[k][10:]).max() < 1e-5, k


def test_integration_error_far_below_smallest_table3_value():
    """Table III's stiffest variant (delta_p1 = 400) at its dt = 2.5e-4: halving dt moves the errors by
    << 1e-7, the smallest tabulated value."""
    exp, _ = load_experiment(ROOT / "configs" / "bejarano_table3.yaml",
                             ["scenario.horizon=1", "metrics.0.t_start=0.5", "seeds=1", "figures=[]", "table=null"])
    exp = exp.model_copy(update={"variants": [v for v in exp.variants if v.name == "proposed_dp400"]})
    _, a = errors_at_trace_times(run(exp))
    exp2 = exp.model_copy(update={"scenario": exp.scenario.model_copy(update={"dt": 1.25e-4})})
    _, b = errors_at_trace_times(run(exp2))
    for k, tol in (("u", 1e-9), ("v", 1e-9), ("sigma_u", 1e-8), ("sigma_v", 1e-8)):  # errors ~6e-8 and ~1e-4
        assert np.abs(a[k][25:] - b[k][25:]).max() < tol, k  # from 0.5 s (traces every 0.02 s); moves ~1e-11, 4e-9


def test_stiff_gains_refused_with_clear_message(tiny_config):
    exp, _ = load_experiment(tiny_config, ["scenario.dt=0.05"])
    with pytest.raises(StiffnessError, match=r"dt=0.05 s is too large .* use dt <="):
        run(exp)


class _Rate:
    """An observer stand-in with a given fastest pole."""

    def __init__(self, rate: float) -> None:
        self.rate = rate

    def max_rate(self) -> float:
        return self.rate


def test_step_check_accepts_dt_lambda_at_the_limit_and_names_the_largest_step():
    """dt |lambda| = limit passes (0.125 s x 4 rad/s = 0.5, exact in binary); above it the error gives the
    fastest pole over the groups and the step that would pass; no observer (a world alone) passes any step."""
    groups = [ObserverGroup(_Rate(1.0), np.arange(1)), ObserverGroup(_Rate(4.0), np.arange(1))]
    assert check_step(groups, 0.125, 0.5) == 4.0
    with pytest.raises(StiffnessError) as e:
        check_step(groups, 0.25, 0.5)
    assert str(e.value) == ("dt=0.25 s is too large for observer poles up to |lambda|=4 rad/s (dt*|lambda| = 1 > 0.5); "
                            "use dt <= 0.125")
    assert check_step([], 1e3, 0.5) == 0.0


def test_a_multiple_pole_at_the_limit_passes_and_a_refusal_suggests_a_step_that_passes():
    """Liu's ESO at eps = 0.1 has a triple pole at exactly 10 rad/s, computed as 10.0000248 (a triple root is found to
    about machine epsilon^(1/3)): dt = 0.05 s is at the limit 0.5 and passes (before: refused, 'dt*|lambda| = 0.5 >
    0.5; use dt <= 0.05', the step it refused). A refusal's suggested step passes, rounded down, not to nearest."""
    liu = LiuEsoObserver([LiuEsoTuning(eps=0.1)], np.eye(3))
    assert 10.0 < liu.max_rate() < 10.0 * (1 + 1e-5)
    assert check_step([ObserverGroup(liu, np.arange(1))], 0.05, 0.5) == liu.max_rate()
    # 0.5 / 47.549 = 0.010516 (0.0105 either way); 0.5 / 47.63 = 0.010498, to nearest 0.0105, which is refused
    for r, suggested in ((47.549, "0.0105"), (47.63, "0.0104"), (4.0, "0.125")):
        with pytest.raises(StiffnessError) as e:
            check_step([ObserverGroup(_Rate(r), np.arange(1))], 1.0, 0.5)
        assert str(e.value).endswith(f"use dt <= {suggested}")
        assert check_step([ObserverGroup(_Rate(r), np.arange(1))], float(suggested), 0.5) == r


class _WorldWithObservers:
    """A world stand-in that integrates observers of its own (as the ROV world does its CDO and EO)."""

    def observer_rates(self) -> np.ndarray:
        return np.array([2.0, 8.0])


def test_step_check_counts_the_observers_a_world_integrates():
    """Before, the ROV world's CDO and EO were not checked: a stiff EO ran, diverged and was dropped with a warning."""
    groups = [ObserverGroup(_Rate(4.0), np.arange(1))]
    assert check_step(groups, 0.05, 0.5, _WorldWithObservers()) == 8.0
    with pytest.raises(StiffnessError, match=r"up to \|lambda\|=8 rad/s"):
        check_step(groups, 0.125, 0.5, _WorldWithObservers())
    assert check_step(groups, 0.125, 0.5, object()) == 4.0  # a world without observers of its own


def test_rk4_step_is_the_classic_scheme():
    """On x' = A x one step is the 4th-order Taylor polynomial of exp(A dt); on x' = f(t) it is Simpson's rule over
    the step (stages at t, t + dt/2 twice, t + dt); every state of the list (plant, observers) takes the same step."""
    A = np.array([[-0.3, 1.2], [-0.7, -0.1]])
    x0, dt = np.array([[1.0, -2.0], [0.5, 0.25]]), 0.4
    hA = dt * A
    taylor = np.eye(2) + hA + hA @ hA / 2 + hA @ hA @ hA / 6 + hA @ hA @ hA @ hA / 24
    linear = rk4_step(lambda t, s: [s[0] @ A.T, s[1] @ A.T], 0.0, dt, [x0, 2 * x0])
    np.testing.assert_allclose(linear[0], x0 @ taylor.T, rtol=1e-14)
    np.testing.assert_allclose(linear[1], 2 * x0 @ taylor.T, rtol=1e-14)
    f = lambda t: np.array([[np.exp(t), t**5]])
    t0 = 1.5
    (got,) = rk4_step(lambda t, s: [f(t)], t0, dt, [np.zeros((1, 2))])
    np.testing.assert_allclose(got, dt / 6 * (f(t0) + 4 * f(t0 + dt / 2) + f(t0 + dt)), rtol=1e-14)


def test_progress_hears_of_every_step_and_on_start_of_their_total(tiny_config):
    exp, _ = load_experiment(tiny_config, ["scenario.horizon=12.5"])  # 1250 steps: a block of 1000 and the rest
    steps, totals = [], []
    run(exp, progress=steps.append, on_start=totals.append, traces=False)
    assert steps == [1000, 250] and totals == [1250]


def test_same_seed_same_numbers_and_batch_independence(tiny_config):
    a = values(short(tiny_config))
    b = values(short(tiny_config))
    pd_equal = (a == b).all()
    assert pd_equal
    three = values(short(tiny_config, "seeds=3"))
    np.testing.assert_array_equal(three.loc[a.index].to_numpy(), a.to_numpy())  # seeds 0, 1 unchanged


def test_traces_keep_seed_0_of_each_variant_whatever_the_seed_count(tiny_config):
    """The figures draw seed 0, so only those runs are traced: memory does not grow with --seeds."""
    one, three = short(tiny_config, "seeds=1"), short(tiny_config, "seeds=3")
    assert three.run_seed[three.traced].tolist() == [0, 0] and three.run_variant[three.traced].tolist() == [0, 1]
    for a, b in zip(one.traces[1:], three.traces[1:]):  # truth, estimates
        assert a.keys() == b.keys()
        for k in a:
            assert b[k].shape == (len(three.traces[0]), 2)
            np.testing.assert_array_equal(a[k], b[k])  # the same runs as with one seed


def test_other_root_seed_changes_numbers(tiny_config):
    a = values(short(tiny_config))
    b = values(short(tiny_config, "seed=7"))
    assert not np.allclose(a.to_numpy(), b.to_numpy())


def test_diverged_runs_are_flagged_not_averaged(tiny_config):
    # allow a step far beyond RK4's stability limit for the Liu observer only (eps tiny)
    r = short(tiny_config, "variants.0.observer.eps=0.001", "engine.check_step=false")
    liu = r.metrics[r.metrics["variant"] == "liu_eps0.2"]
    assert (liu["status"] == "diverged").all() and liu["value"].isna().all()
    other = r.metrics[r.metrics["variant"] == "proposed_d1.2"]
    assert (other["status"] == "ok").all()
    s = r.summary[r.summary["variant"] == "liu_eps0.2"]
    assert (s["n"] == 0).all() and (s["n_diverged"] == 2).all()
    from marinebench.results.tables import markdown_table

    table = markdown_table(r.experiment, r.summary)
    liu_row, other_row = (" | ".join(md_row(table, v)) for v in ("liu_eps0.2", "proposed_d1.2"))
    assert "(2 diverged)" in liu_row and "diverged" not in other_row


def test_columns_is_np_stack_bit_for_bit():
    rng = np.random.default_rng(3)
    cols = [rng.normal(size=7) * 10.0 ** rng.integers(-8, 8) for _ in range(4)]
    got = columns(*cols)
    assert got.flags.c_contiguous and got.dtype == np.float64
    np.testing.assert_array_equal(got, np.stack(cols, axis=1))


def _open_loop_world(seeds: list[int]):
    """Table III's noiseless open-loop world at root seed 5, one run per entry of ``seeds``."""
    from marinebench.loading import load_scenario
    from marinebench.scenario import OpenLoopASV

    return OpenLoopASV(load_scenario(ROOT / "scenarios" / "cs2_noiseless.yaml"), 5, np.array(seeds))


def test_open_loop_forces_kept_for_one_time_equal_fresh_ones():
    """The world keeps the forces of the last time asked; asking again, after other times, gives the forces a
    fresh world computes at that time."""
    world = _open_loop_world([0, 1, 1])
    for t in (0.0, 0.0, 1.25, 1.25, 2.5, 0.0):
        got, want = world.forces(t), _open_loop_world([0, 1, 1]).forces(t)
        for a, b in zip(got, want):
            np.testing.assert_array_equal(a, b)
    assert np.any(world.forces(1.25)[0] != world.forces(0.0)[0])


def test_a_runs_world_is_its_seeds_whatever_the_batch():
    """Run b of an open-loop world draws from seed seed_of_run[b] alone: in any order, repeated or not, its forces
    and noise are those of a world of that seed by itself."""
    mixed = _open_loop_world([3, 0, 3, 1])
    for t in (0.0, 2.5):
        for b, seed in enumerate([3, 0, 3, 1]):
            alone = _open_loop_world([seed])
            for got, want in zip(mixed.forces(t), alone.forces(t)):
                np.testing.assert_array_equal(got[b], want[0])


def test_kept_forces_are_read_only():
    tau, _ = _open_loop_world([0]).forces(0.5)
    with pytest.raises(ValueError, match="read-only"):
        tau[0, 0] = 1.0


def test_open_loop_world_starts_at_bejaranos_initial_state_and_measures_eta_with_noiseless_heading():
    """Bejarano Sec. IV: eta(0) = [0 10 0], nu(0) = 0 (the defaults of ``initial``); y = eta + n with noise (within its
    0.2-m bound) on x, y only (eq. (8), Assumption 3)."""
    from marinebench.scenario import OpenLoopASV, Scenario

    sc = Scenario(name="s", horizon=1.0, dt=0.01, sensors={"position_noise": {"kind": "bandlimited_uniform"}})
    world = OpenLoopASV(sc, 1, np.array([0, 1]))
    np.testing.assert_array_equal(world.x0, [[0.0, 10.0, 0.0, 0.0, 0.0, 0.0]] * 2)
    x = np.array([[1.0, 2.0, 0.5, 0.1, 0.2, 0.3], [-1.0, 4.0, -0.5, 0.0, 0.0, 0.0]])
    y = world.measure(0.0, x)
    assert np.all(y[:, :2] != x[:, :2]) and np.all(np.abs(y[:, :2] - x[:, :2]) <= 0.2)
    np.testing.assert_array_equal(y[:, 2], x[:, 2])


def test_an_open_loop_scenario_left_unset_is_table_iiis_calibrated_world():
    """The defaults of vessel, initial state, excitation, disturbances and sensors are cs2_noiseless.yaml's."""
    from marinebench.loading import load_scenario
    from marinebench.scenario import Scenario

    table3 = load_scenario(ROOT / "scenarios" / "cs2_noiseless.yaml")
    default = Scenario(name="d", horizon=1.0, dt=0.01)
    for part in ("vessel", "initial", "inputs", "disturbances", "sensors"):
        assert getattr(default, part) == getattr(table3, part), part


def test_a_scenario_needs_a_name_a_step_within_its_horizon_and_at_most_max_steps():
    from marinebench.scenario import Scenario, ScenarioBase

    assert ScenarioBase.MAX_STEPS == 10**8
    accepts_and_refuses(Scenario, {"name": "s", "horizon": 2.0, "dt": 0.01},
                        [{"name": "a"}, {"dt": 2.0}, {"horizon": 0.5}, {"horizon": 1.0, "dt": 1e-8}],
                        [{"name": ""}, {"dt": 2.5}, {"horizon": 0.0}, {"dt": 0.0}, {"horizon": 1.0000001, "dt": 1e-8}])


def test_open_loop_truth_is_the_state_and_bejarano_eq_6s_lumped_disturbance():
    """``truth``: eta and nu from their state columns, and sigma = nu_dot - M^-1 tau (eq. (6)) from the plant's own
    derivative, for a state with every entry distinct."""
    world = _open_loop_world([0, 1])
    x = np.array([[1.0, 2.0, 0.3, 0.4, -0.2, 0.1], [-3.0, 5.0, -1.1, 0.7, 0.05, -0.3]])
    truth = world.truth(1.5, x)
    for i, name in enumerate(("x", "y", "psi", "u", "v", "r")):
        np.testing.assert_array_equal(truth[name], x[:, i])
    x_dot, _, tau = world.derivative(1.5, x)
    sigma = x_dot[:, 3:] - tau @ world.plant.Minv.T
    for i, name in enumerate(("sigma_u", "sigma_v", "sigma_r")):
        np.testing.assert_allclose(truth[name], sigma[:, i], rtol=1e-12, atol=1e-12)
    assert np.all(np.abs(sigma) > 1e-3)


def test_a_random_sinusoid_draws_bias_amplitude_frequency_and_phase_uniformly_per_seed():
    """Bejarano Sec. IV's "sinusoidal signals with random amplitude, frequency and bias": s(t) = b + a sin(2 pi f t +
    phi), each parameter uniform in its range (means at the midpoints within 4 standard errors over 4000 draws)."""
    from marinebench.environment.signals import Constant, RandomSinusoid

    spec = RandomSinusoid(bias=(-0.3, 0.5), amplitude=(0.4, 1.8), frequency=(0.1, 0.4))
    batch = spec.sample([np.random.default_rng(s) for s in range(4000)])
    f = batch.omega / (2 * np.pi)
    for values, (lo, hi) in ((batch.bias, spec.bias), (batch.amplitude, spec.amplitude), (f, spec.frequency),
                             (batch.phase, (0.0, 2 * np.pi))):
        assert lo <= values.min() and values.max() <= hi
        assert abs(values.mean() - (lo + hi) / 2) < 4 * (hi - lo) / np.sqrt(12 * 4000)
    t = 2.7
    np.testing.assert_allclose(batch(t), batch.bias + batch.amplitude * np.sin(2 * np.pi * f * t + batch.phase), rtol=1e-12)
    picked = batch.take(np.array([7, 3, 7]))
    np.testing.assert_allclose(picked(t), batch(t)[[7, 3, 7]], rtol=1e-12)
    np.testing.assert_array_equal(Constant(value=-0.25).sample([np.random.default_rng(0)] * 2)(t), [-0.25, -0.25])
    for unset in (RandomSinusoid(), Constant()):  # a signal left at its defaults is zero
        np.testing.assert_array_equal(unset.sample([np.random.default_rng(1)] * 2)(t), [0.0, 0.0])


def test_a_random_sinusoids_ranges_are_ordered_and_amplitude_and_frequency_non_negative():
    from marinebench.environment.signals import RandomSinusoid

    accepts_and_refuses(RandomSinusoid, {}, [{"bias": (-2.0, -1.0)}, {"amplitude": (0.0, 0.0)}, {"frequency": (0.0, 0.0)}],
                        [{"bias": (1.0, 0.0)}, {"amplitude": (0.5, 0.4)}])
    for bad in ({"amplitude": (-0.1, 0.2)}, {"frequency": (-1.0, 1.0)}):
        with pytest.raises(ValueError, match="amplitude and frequency ranges must be non-negative"):
            RandomSinusoid(**bad)


def blas_threads() -> list[int]:
    """The thread count of each BLAS library loaded (numpy's, scipy's, and those of solvers' wheels)."""
    from threadpoolctl import threadpool_info

    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]


def test_runs_side_by_side_in_threads_keep_one_blas_thread_until_the_last_ends():
    """Some OpenBLAS builds (numpy 1.26's) round differently with more threads, so a run simulates with one, as in
    the worker processes. The limit is process-wide: two runs in threads (a threaded Dask worker) end in any order,
    and the first to end must not lift it from under the other (with one threadpool_limits each it did)."""
    from threadpoolctl import threadpool_limits

    from marinebench.experiments.runner import one_blas_thread

    with threadpool_limits(2, user_api="blas"):
        before = blas_threads()  # 2 each, but a library built for one thread keeps 1
        assert 2 in before
        first, second = one_blas_thread(), one_blas_thread()
        first.__enter__()
        second.__enter__()
        assert set(blas_threads()) == {1}
        first.__exit__(None, None, None)  # the first run ends while the second simulates
        assert set(blas_threads()) == {1}
        second.__exit__(None, None, None)
        assert blas_threads() == before  # the caller's setting again
