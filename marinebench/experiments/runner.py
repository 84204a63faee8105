"""Run one experiment: variants x seeds in a single batch through the one engine.

Run ``b = v * seeds + j`` is variant ``v`` with seed index ``j``; all variants share the world of seed
``j`` (paired comparisons) apart from the per-run world parameters a variant sets (``world:``).
Observers of the same kind run as one batched group with per-run gains.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from marinebench.config import Experiment
from marinebench.dp_scenario import DpWorld
from marinebench.metrics.stats import mean_ci
from marinebench.models.cybership2 import CyberShip2, linear_dp_model
from marinebench.models.rov import LeonardLike
from marinebench.models.supply import SupplyVessel, bis_scale
from marinebench.observers.base import chain_response
from marinebench.observers.bejarano import BejaranoObserver
from marinebench.observers.custom import CheckedObserver, observer_class
from marinebench.observers.dp import LUMPED_SIGNALS, DpObserver
from marinebench.observers.dp import SIGNALS as DP_SIGNALS
from marinebench.observers.liu_eso import LiuEsoObserver
from marinebench.plugins import source_record, user_code_error
from marinebench.provenance import custom_sources
from marinebench.rov_scenario import RovWorld
from marinebench.scenario import OpenLoopASV
from marinebench.sim.engine import ObserverGroup, check_step, simulate
from marinebench.sim.recorders import ControlEnergy, ErrorMoments, NormIntegral, RecoveryTime, Traces, TruthLog

# Observer kinds per scenario kind. Bejarano's estimator and Liu's ESO need only M^-1 of the vessel and a pose
# measurement, so they also run on the DP world (against its lumped-disturbance truth); the DP observers run on
# the open-loop ASV world with CyberShip II's linear model (41) (``linear_dp_model``) and report the lumped
# disturbance their model implies (the ASV world has no bias truth).
OBSERVER_KINDS = {
    "open_loop_asv": ("bejarano", "liu_eso", "npo", "resetting_fto", "custom"),
    "dp_supply": ("npo", "resetting_fto", "bejarano", "liu_eso", "custom"),
    "rov_tracking": (),
}  # a custom observer's class narrows its own: ``scenario_kinds`` (observers/custom.py)
LUMPED_KINDS = ("bejarano", "liu_eso")  # observers of the lumped disturbance sigma (Bejarano eq. (6))
# Observers a closed-loop world runs itself; a variant's `observer` picks the one whose estimates it reports.
WORLD_OBSERVERS = {"rov_tracking": ("cdo", "eo", "custom")}
DESIGNS_UP_TO = 20  # variants whose per-variant Kalman or CDO/EO designs the manifest lists (a sweep has more)


def observer_kinds_for(scenario) -> tuple[str, ...]:
    """Observer kinds that apply to a scenario's kind."""
    return OBSERVER_KINDS[scenario.kind]


def scenario_kinds_for(observer_kind: str) -> list[str]:
    """Scenario kinds an observer kind applies to (``marinebench list``, the conformance suite)."""
    return [s for s in OBSERVER_KINDS if observer_kind in OBSERVER_KINDS[s] + WORLD_OBSERVERS.get(s, ())]


def plant_of(scenario):
    """The vessel model the observers are built on: the plant's, or a DP scenario's ``design_vessel``."""
    params = scenario.model if scenario.kind == "dp_supply" else scenario.vessel
    return {"open_loop_asv": CyberShip2, "dp_supply": SupplyVessel, "rov_tracking": LeonardLike}[scenario.kind](params)


def wants_lumped(exp: Experiment) -> bool:
    """Whether the DP observers report the lumped disturbance sigma their model implies (and a DP world records
    its truth): always on the open-loop ASV world, whose truth is sigma; on a DP world when an observer of sigma
    runs, or a metric, the table or a figure asks for a sigma signal. Torben's experiments ask for neither and
    do not pay for the extra plant evaluation per step."""
    if exp.scenario.kind == "open_loop_asv":
        return True  # its truth is sigma, not a bias: the DP observers must report the sigma they imply
    if exp.scenario.kind != "dp_supply":
        return False
    asked = {s for m in exp.metrics for s in (getattr(m, "signals", None) or ())}
    asked |= {s for f in exp.figures for s in (getattr(f, "signals", None) or ())}
    asked |= set(exp.table.signals or ()) if exp.table is not None else set()
    return bool(asked & set(LUMPED_SIGNALS)) or any(v.observer.kind in LUMPED_KINDS for v in exp.variants)


def make_observer(kind: str, tunings: list, scenario, plant, lumped: bool = False):
    """Build one batched observer of ``kind`` with one tuning per run (``lumped``: DP observers also report
    the lumped disturbance their model implies)."""
    if kind == "bejarano":
        return BejaranoObserver(tunings, plant.Minv)
    if kind == "liu_eso":
        return LiuEsoObserver(tunings, plant.Minv)
    if kind == "custom":
        return CheckedObserver(observer_class(tunings[0].source)([t.params for t in tunings], plant, scenario.dt), len(tunings))
    if kind in ("npo", "resetting_fto"):
        model = plant if isinstance(plant, SupplyVessel) else SupplyVessel(linear_dp_model(plant.params))
        return DpObserver(tunings, model, scenario.dt, bis_scale(model.params), lumped)
    raise KeyError(kind)


def per_run_world(exp: Experiment, run_variant: np.ndarray) -> dict[str, np.ndarray]:
    """Each per-run world key some variant sets (its ``world:``), over the runs: the run's variant's value, or the
    scenario's own."""
    return {key: np.array([exp.variants[v].world.get(key, own) for v in run_variant], dtype=float)
            for key, own in exp.scenario.per_run_defaults().items() if any(key in v.world for v in exp.variants)}


def make_world(exp: Experiment, run_variant: np.ndarray, run_seed: np.ndarray):
    sc = exp.scenario
    if sc.kind == "open_loop_asv":
        return OpenLoopASV(sc, exp.seed, run_seed, per_run_world(exp, run_variant))
    if sc.kind == "rov_tracking":
        specs = {}
        for b, v in enumerate(run_variant):
            spec = exp.variants[v].controller
            specs.setdefault(spec.model_dump_json(), (spec, []))[1].append(b)
        return RovWorld(sc, exp.seed, run_seed, list(specs.values()), [exp.variants[v].observer for v in run_variant],
                        per_run_world(exp, run_variant))
    return DpWorld(sc, exp.seed, run_seed, per_run_world(exp, run_variant), wants_lumped(exp))


@dataclass
class RunResult:
    experiment: Experiment
    metrics: pd.DataFrame  # tidy: experiment, scenario, variant, seed, signal, metric, value, status (+ tags)
    summary: pd.DataFrame  # variant, signal, metric, mean, ci_low, ci_high, n, n_diverged
    traces: tuple[np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray]]  # t (T,), truth and estimates (T, R)
    run_variant: np.ndarray
    run_seed: np.ndarray
    wall_time: float
    max_rate: float
    designs: dict[str, dict] = field(default_factory=dict)
    parts: dict[str, RunResult] = field(default_factory=dict)  # per scenario, for multi-scenario experiments
    traced: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))  # the R traced runs: seed 0 of each variant

    def trace_frame(self) -> pd.DataFrame:
        """The traces the figures draw as a tidy DataFrame: scenario, variant, seed, t, signal, truth, estimate
        (:func:`marinebench.results.traces.trace_frame`)."""
        from marinebench.results.traces import trace_frame

        return trace_frame(self)


def build_groups(exp: Experiment, run_variant: np.ndarray, plant) -> list[ObserverGroup]:
    """One batched observer per observer kind (per class for custom observers), with one tuning per run."""
    groups = []
    lumped = wants_lumped(exp)
    observers = [exp.variants[v].observer for v in run_variant]
    sources = [o.source if o is not None and o.kind == "custom" else None for o in observers]
    for kind in observer_kinds_for(exp.scenario):
        for source in dict.fromkeys(sources) if kind == "custom" else [None]:
            idx = np.array([b for b, o in enumerate(observers)
                            if o is not None and o.kind == kind and sources[b] == source], dtype=int)
            if idx.size:
                groups.append(ObserverGroup(make_observer(kind, [observers[b] for b in idx], exp.scenario, plant, lumped), idx))
    return groups


def noise_parts(sc, chains: dict[str, np.ndarray]) -> dict[str, float]:
    """Predicted std of the velocity and disturbance errors (``u``, ``sigma_u`` for axis ``u``; ``v``, ``sigma_v``)
    that an observer's position channels, ``{axis: (l1, l2, l3)}``, make of the scenario's band-limited position
    noise alone, at rest (linear theory, ``observers.base.chain_response``); empty where the world has no such
    noise. Table IV's errors are mostly this part (README)."""
    if sc.kind != "open_loop_asv" or sc.sensors.position_noise.kind != "bandlimited_uniform":
        return {}
    out = {}
    for axis, gains in chains.items():
        velocity, disturbance = sc.sensors.position_noise.response_std(lambda w, g=gains: np.stack(chain_response(g, w)))
        out |= {f"noise_part_std_{axis}": float(velocity), f"noise_part_std_sigma_{axis}": float(disturbance)}
    return out


def design_summary(exp: Experiment) -> dict[str, dict]:
    """Designed gains and poles per variant (and, on a noisy ASV world, the noise part of each velocity and
    disturbance error, ``noise_parts``), for the manifest."""
    from marinebench.observers import bejarano

    out = {}
    if exp.scenario.kind == "rov_tracking":
        out = {"world_cdo": exp.scenario.cdo_design(), "world_eo": exp.scenario.eo_design()}
    for v in exp.variants:
        o = v.observer
        if v.controller is not None:
            out[v.name] = _closed_loop_design(exp, v)
        elif o.kind == "bejarano":
            rot, pos = bejarano.design(o)
            out[v.name] = {
                "L_psi": rot.gain[:, 0].tolist(),
                "L_pz": pos.gain.tolist(),
                "beta_psi": rot.beta,
                "beta_p": pos.beta,
                "slowest_pole_psi": float(rot.poles.real.max()),
                "slowest_pole_p": float(pos.poles.real.max()),
                "fastest_pole_abs": float(max(np.abs(rot.poles).max(), np.abs(pos.poles).max())),
                **noise_parts(exp.scenario, {"u": -pos.gain[[0, 2, 4], 0], "v": -pos.gain[[1, 3, 5], 1]}),  # -L_pz, eq. (26) at psi = 0
            }
        elif o.kind == "custom":
            sha, imports = source_record(o.source)
            out[v.name] = {"source": o.source, "sha256": sha, "imports": imports, "params": o.params}
        elif o.kind == "liu_eso":
            gains = o.gains().tolist()
            out[v.name] = {"gains": gains, "mode": o.mode, **(noise_parts(exp.scenario, {"u": gains, "v": gains}) if o.mode == "linear" else {})}
        elif len(exp.variants) <= DESIGNS_UP_TO:  # DP observers: Kalman gains (skipped for large sweeps)
            obs = make_observer(o.kind, [o], exp.scenario, plant_of(exp.scenario))
            design = obs.classes[0]
            used = (0,) if design["one_gain"] else (0, 1)  # the NPO runs L1 alone (L2 = L1)
            out[v.name] = {f"K{j}_L{i + 1}": K[i].tolist() for i in used for j, K in enumerate(design["K"], start=1)}
            out[v.name].update({f"poles_L{i + 1}_re": sorted(np.round(obs.poles[i].real, 4).tolist()) for i in used})
    return out


def _closed_loop_design(exp: Experiment, v) -> dict:
    """A closed-loop variant's controller and the observer it is seen through: a custom class's file, or its own CDO
    and EO designs where it sets them (not for large sweeps)."""
    o = v.observer
    out = {"controller": v.controller.model_dump(), "observed_through": o.kind if o else None}
    if v.controller.kind == "custom":
        sha, imports = source_record(v.controller.source)
        out.update(controller_sha256=sha, controller_imports=imports)
    if o is not None and o.kind == "custom":
        sha, imports = source_record(o.source)
        out.update(observer={"source": o.source, "sha256": sha, "imports": imports, "params": o.params})
    elif o is not None and (o.cdo or o.eo) and len(exp.variants) <= DESIGNS_UP_TO:
        cdo, eo = o.resolve(exp.scenario)
        out.update(cdo=exp.scenario.cdo_design(cdo), eo=exp.scenario.eo_design(eo))
    return out


def steps(exp: Experiment) -> int:
    """Time steps of an experiment's simulations, over its scenarios and the worlds its variants' settings make
    (:func:`world_batches`): what ``run``'s progress callback counts."""
    return sum(round(p.scenario.horizon / p.scenario.dt) * len(world_batches(p)) for p in map(exp.part, exp.scenario_names))


def run_steps(exp: Experiment) -> int:
    """Runs x time steps over the experiment's scenarios (each scenario with its own variants): its rough cost."""
    return sum(len(p.variants) * p.seeds * round(p.scenario.horizon / p.scenario.dt) for p in map(exp.part, exp.scenario_names))


def world_batches(exp: Experiment) -> list[tuple[dict[str, Any], list[int]]]:
    """A single-scenario experiment's variants (their indices) by the world they run in, in the order of their first
    variant: the variants whose ``world:`` sets per-run keys only share the scenario's world and one batch; those
    that set other settings of the world by their dotted paths (``waves.tp``, ``sensors.hold``) run, per distinct set
    of them, in a world with those settings, a batch of its own (:meth:`~marinebench.scenario.ScenarioBase.
    world_settings`)."""
    batches: dict[str, tuple[dict[str, Any], list[int]]] = {}
    for i, v in enumerate(exp.variants):
        settings = exp.scenario.world_settings(v.world)
        batches.setdefault(repr(sorted(settings.items())), (settings, []))[1].append(i)
    return list(batches.values())


def run(
    exp: Experiment,
    progress: Callable[[int], None] | None = None,
    on_start: Callable[[int], None] | None = None,
    traces: bool = True,
) -> RunResult:
    """Design, check the step, simulate and reduce to tidy metrics; a multi-scenario experiment runs each
    scenario's variants as one batch and stacks the metrics (``parts`` keeps each scenario's result).

    All of it with one BLAS thread (:class:`_OneBlasThread`)."""
    with one_blas_thread():
        return _run(exp, progress, on_start, traces)


class _OneBlasThread:
    """One BLAS thread while any run of this process is simulating, as in the sweep's and ``--jobs``' worker
    processes and on Dask's: some OpenBLAS builds (numpy 1.26's) round a product differently with more threads,
    and a run's numbers must not depend on where it ran. The limit is process-wide, so the first run to start
    sets it and the last to end restores it (runs side by side in threads, as on a threaded Dask worker, would
    otherwise lift it from under each other)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._runs = 0
        self._limit = None

    @contextmanager
    def __call__(self) -> Iterator[None]:
        with self._lock:
            if self._runs == 0:
                self._limit = threadpool_limits(1, user_api="blas")
            self._runs += 1
        try:
            yield
        finally:
            with self._lock:
                self._runs -= 1
                if self._runs == 0:
                    self._limit.restore_original_limits()


one_blas_thread = _OneBlasThread()


def _run(exp: Experiment, progress: Callable[[int], None] | None, on_start: Callable[[int], None] | None,
         traces: bool) -> RunResult:
    if exp.scenarios is None:
        return _run_single(exp, progress, on_start, traces)
    parts = {name: exp.part(name) for name in exp.scenarios}
    if on_start is not None:
        on_start(steps(exp))
    done = {name: _run_single(p, progress, None, traces) for name, p in parts.items()}
    metrics = pd.concat([r.metrics for r in done.values()], ignore_index=True)
    return RunResult(
        exp, metrics, summarise(metrics), (np.zeros(0), {}, {}),
        np.concatenate([r.run_variant for r in done.values()]), np.concatenate([r.run_seed for r in done.values()]),
        sum(r.wall_time for r in done.values()), max(r.max_rate for r in done.values()),
        {name: r.designs for name, r in done.items()}, done,
    )


def _run_single(exp: Experiment, progress: Callable[[int], None] | None, on_start: Callable[[int], None] | None,
                traces: bool) -> RunResult:
    """One scenario's variants: one batch in the scenario's world, or one per world their settings make
    (:func:`world_batches`), merged as if run together (run, trace and variant indices of the whole experiment)."""
    batches = world_batches(exp)
    if len(batches) == 1 and not batches[0][0]:
        return _run_batch(exp, progress, on_start, traces)
    if on_start is not None:
        on_start(steps(exp))
    done = [(settings, np.array(index), _run_batch(part, progress, None, traces)) for settings, index, part in world_parts(exp)]
    return _merged(exp, done)


def world_parts(exp: Experiment) -> list[tuple[dict[str, Any], list[int], Experiment]]:
    """:func:`world_batches` with each batch's own experiment: its variants, in a world built with its settings."""
    return [(settings, index, exp.model_copy(update={"scenario": exp.scenario.with_settings(settings),
                                                     "variants": [exp.variants[i] for i in index]}))
            for settings, index in world_batches(exp)]


def designs(exp: Experiment) -> dict[str, dict]:
    """:func:`design_summary` of a single-scenario experiment over the worlds its variants run in (each variant's
    designs on its own world's vessel), as a run's manifest records them (:func:`merged_designs`)."""
    return merged_designs(exp, [(settings, design_summary(part)) for settings, _, part in world_parts(exp)])


def merged_designs(exp: Experiment, found: list[tuple[dict[str, Any], dict[str, dict]]]) -> dict[str, dict]:
    """The designs of each world (its settings, its :func:`design_summary`) as one: a variant's under its name, a
    world's own (an ROV world's CDO and EO) under its key for the scenario's world, with the settings of another
    (``world_cdo (cdo.theta=3)``)."""
    names = {v.name for v in exp.variants}
    out: dict[str, dict] = {}
    for settings, designs_there in found:
        world = ", ".join(f"{k}={_shown(v)}" for k, v in settings.items())
        for key, design in designs_there.items():
            out[key if key in names or not settings else f"{key} ({world})"] = design
    return out


def _merged(exp: Experiment, done: list[tuple[dict[str, Any], np.ndarray, RunResult]]) -> RunResult:
    """The results of one scenario's world batches (``(settings, variant indices, result)`` each) as one result: runs
    in batch order, variant indices the experiment's, the traced runs' traces side by side (NaN where a batch has no
    trace of a signal), and the designs of each world (:func:`merged_designs`)."""
    offsets = np.cumsum([0] + [len(r.run_variant) for _, _, r in done])
    t = next((r.traces[0] for _, _, r in done if r.traces[0].size), np.zeros(0))
    traces = [t, {}, {}]
    for k in (1, 2):  # truth, estimates: (T, R) per signal
        names = sorted({name for _, _, r in done for name in r.traces[k]})
        traces[k] = {name: np.concatenate([r.traces[k].get(name, np.full((t.size, r.traced.size), np.nan))
                                           for _, _, r in done], axis=1) for name in names}
    metrics = pd.concat([r.metrics for _, _, r in done], ignore_index=True)
    return RunResult(exp, metrics, summarise(metrics), tuple(traces),
                     np.concatenate([index[r.run_variant] for _, index, r in done]),
                     np.concatenate([r.run_seed for _, _, r in done]), sum(r.wall_time for _, _, r in done),
                     max(r.max_rate for _, _, r in done), merged_designs(exp, [(w, r.designs) for w, _, r in done]),
                     traced=np.concatenate([r.traced + offset for (_, _, r), offset in zip(done, offsets)]))


def _shown(value: Any) -> str:
    """A world setting's value as a design's name shows it: a number as ``3``, anything else as JSON (``null``)."""
    return f"{value:g}" if isinstance(value, int | float) and not isinstance(value, bool) else json.dumps(value)


def _run_batch(
    exp: Experiment,
    progress: Callable[[int], None] | None,
    on_start: Callable[[int], None] | None,
    traces: bool,
) -> RunResult:
    V, S = len(exp.variants), exp.seeds
    run_variant = np.repeat(np.arange(V), S)
    run_seed = np.tile(np.arange(S), V)
    sc = exp.scenario
    world = make_world(exp, run_variant, run_seed)
    groups = build_groups(exp, run_variant, plant_of(sc))
    rate = check_step(groups, sc.dt, exp.engine.stiffness_limit if exp.engine.check_step else np.inf, world)
    n_steps = round(sc.horizon / sc.dt)
    recorders = _recorders(exp, run_variant, run_seed, n_steps)
    truth0 = world.truth(0.0, world.x0)
    trace_signals = sorted({s for g in groups for s in g.observer.signals} & set(truth0))  # estimated and true
    if hasattr(world, "estimates"):
        trace_signals = sorted(set(trace_signals) | set(world.estimates(0.0, world.x0)) | set(truth0))
    traced = np.flatnonzero(run_seed == 0) if traces else np.zeros(0, dtype=int)  # the runs the figures draw
    tracer = Traces(trace_signals, round(exp.engine.trace_dt / sc.dt), traced) if traces else None
    if on_start is not None:
        on_start(n_steps)
    t0 = time.perf_counter()
    try:
        diverged = simulate(world, groups, sc.dt, n_steps, recorders + ([tracer] if tracer else []), progress)
    except Exception as exc:  # re-raised: as one line when it came from a class of the user's
        if (error := user_code_error(exc, custom_sources(exp))) is not None:
            raise error from exc
        raise
    wall = time.perf_counter() - t0
    metrics = _tidy(exp, _values(exp, recorders, groups, V * S), _estimated_signals(groups, world, V * S),
                    diverged, run_variant, run_seed)
    arrays = tracer.arrays() if tracer else (np.zeros(0), {}, {})
    return RunResult(exp, metrics, summarise(metrics), arrays, run_variant, run_seed, wall, rate, design_summary(exp),
                     traced=traced)


def _recorders(exp: Experiment, run_variant: np.ndarray, run_seed: np.ndarray, n_steps: int) -> list:
    """One streaming recorder per configured metric, in the config's order."""
    sc = exp.scenario
    recorders = []
    for m in exp.metrics:
        if m.kind == "j_tot":
            start, end = m.window(sc.horizon)
            recorders.append(NormIntegral(list(DP_SIGNALS), bis_scale(sc.vessel), {"psi"}, start, end, sc.dt))
        elif m.kind == "int":
            recorders.append(ControlEnergy(m.signals, [f"tau_{s}" for s in m.signals], [m.tol[s] for s in m.signals], sc.dt))
        elif m.kind == "recovery":
            ends = {s: [p.t_start + p.duration for p in sc.pushes if p.force[("depth", "yaw").index(s)] != 0]
                    for s in m.signals}
            ends = {s: e for s, e in ends.items() if e}
            twin = _undisturbed_truth(exp, run_variant, run_seed, list(ends), n_steps) if m.against == "undisturbed" else None
            recorders.append(RecoveryTime(ends, m.tol, m.window, twin))
        else:
            recorders.append(ErrorMoments(m.signals, m.t_start, m.t_end or sc.horizon))
    return recorders


def _values(exp: Experiment, recorders: list, groups: list[ObserverGroup], n_runs: int) -> list[tuple[str, dict[str, np.ndarray]]]:
    """(metric name, {signal: per-run value}) for every metric, then the observers' diagnostics (resets,
    condition numbers) under signal ``z``."""
    out: list[tuple[str, dict[str, np.ndarray]]] = []
    for spec, rec in zip(exp.metrics, recorders):
        if spec.kind == "j_tot":
            out.append((spec.label, {"z": rec.value}))
        elif spec.kind in ("int", "recovery"):
            out.append((spec.label, rec.value))
        else:
            out.append((spec.label, rec.result(spec.kind)))
    for g in groups:
        diag = getattr(g.observer, "diagnostics", None)
        if diag is not None:
            for name, values in diag().items():
                full = np.full(n_runs, np.nan)
                full[g.index] = values
                out.append((name, {"z": full}))
    return out


def _tidy(exp: Experiment, values: list[tuple[str, dict[str, np.ndarray]]], estimated: list[set[str]],
          diverged: np.ndarray, run_variant: np.ndarray, run_seed: np.ndarray) -> pd.DataFrame:
    """The tidy ``metrics.csv`` rows: one per run, signal and metric, for the signals each run's observer
    produces; a diverged run's values are NaN with status ``diverged``."""
    rows = []
    tag_keys = sorted({k for v in exp.variants for k in v.tags})
    labels = [m.label for m in exp.metrics]
    for metric, per_signal in values:
        for signal, per_run in per_signal.items():
            for b in range(len(run_variant)):
                if not np.isfinite(per_run[b]) and (metric not in labels or signal not in estimated[b]):
                    continue  # a diagnostic or a signal this run's observer kind does not produce
                ok = not diverged[b] and np.isfinite(per_run[b])
                variant = exp.variants[run_variant[b]]
                rows.append(
                    (exp.name, exp.scenario.name, variant.name, int(run_seed[b]), signal, metric,
                     float(per_run[b]) if ok else float("nan"), "ok" if ok else "diverged",
                     *[variant.tags.get(k, "") for k in tag_keys])
                )
    columns = ["experiment", "scenario", "variant", "seed", "signal", "metric", "value", "status", *tag_keys]
    return pd.DataFrame(rows, columns=columns)


def _estimated_signals(groups: list[ObserverGroup], world, n_runs: int) -> list[set[str]]:
    """Per run, the signals its observer (or the world, e.g. a closed loop's tracking) produces; ``z`` (the
    J_tot state) when all of the DP state is among them."""
    if hasattr(world, "signals_of_runs"):  # a world whose runs report different estimates (the ROV's disturbances)
        out = world.signals_of_runs()
    else:
        common = set(world.estimates(0.0, world.x0)) if hasattr(world, "estimates") else set()
        out = [set(common) for _ in range(n_runs)]
    for g in groups:
        for b in g.index:
            out[b] |= set(g.observer.signals)
    for names in out:
        if set(DP_SIGNALS) <= names:
            names.add("z")
    return out


def _undisturbed_truth(exp: Experiment, run_variant, run_seed, signals: list[str], n_steps: int) -> dict[str, np.ndarray]:
    """Per-step truth of the same runs (same seeds, noise, controllers) with the scenario's pushes removed."""
    if not signals:
        return {}
    calm = exp.model_copy(update={"scenario": exp.scenario.model_copy(update={"pushes": []})})
    world = make_world(calm, run_variant, run_seed)
    log = TruthLog(signals, n_steps)
    simulate(world, build_groups(calm, run_variant, plant_of(calm.scenario)), exp.scenario.dt, n_steps, [log])
    return log.values


def summarise(metrics: pd.DataFrame, level: float = 0.95) -> pd.DataFrame:
    """Mean and CI over seeds per (scenario, variant, signal, metric), diverged runs excluded and counted;
    groups in order of first appearance. (Positions per group from one ``ngroup``, not a pandas filter per
    group: a sweep's chunk has thousands of groups.)"""
    keys = ["scenario", "variant", "signal", "metric"]
    columns = [*keys, "mean", "ci_low", "ci_high", "n", "n_diverged"]
    if metrics.empty:
        return pd.DataFrame([], columns=columns)
    codes = metrics.groupby(keys, sort=False).ngroup().to_numpy()
    first = metrics.loc[~metrics.duplicated(keys), keys]  # row i is group i: ngroup numbers by first appearance
    order = np.argsort(codes, kind="stable")
    bounds = np.searchsorted(codes[order], np.arange(len(first) + 1))
    ok, values = (metrics["status"] == "ok").to_numpy(), metrics["value"].to_numpy(dtype=float)
    out = []
    for i, key in enumerate(first.itertuples(index=False, name=None)):
        rows = order[bounds[i]:bounds[i + 1]]
        good = values[rows[ok[rows]]]
        m, lo, hi = mean_ci(good, level)
        out.append((*key, m, lo, hi, int(good.size), int(rows.size - good.size)))
    return pd.DataFrame(out, columns=columns)
