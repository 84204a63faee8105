"""Preflight: every check an experiment needs before anything runs, so that a run never fails minutes in.

:func:`preflight` solves each variant's observer design (Bejarano's LMIs, the DP observers' Kalman gains, the
CDO's LMIs (39)-(40)) and builds a custom class, builds each variant's world for one seed, checks the step
against the fastest observer pole (``dt * |lambda|max <= stiffness_limit``) and that the world's first step is
finite, and checks the per-run world settings of the variants and of the sweep's groups, the signals the
figures and metrics name and (for a sweep) that each parameter names a setting of the swept variant. Every
failure is a :class:`~marinebench.errors.ConfigError` naming the file and key; ``marinebench validate`` is this
without running. Called after :func:`marinebench.loading.load_experiment` by
:func:`marinebench.loading.load_checked`.
"""

from __future__ import annotations

import difflib
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationError

from marinebench.config import DP_SIGNALS, TRUTH_SIGNALS, Experiment, Variant
from marinebench.controllers.spec import check_built as check_controller
from marinebench.errors import ConfigError, ProtocolError
from marinebench.keypaths import did_you_mean, keyed_message, near_misses
from marinebench.observers.custom import check_built as check_observer
from marinebench.observers.custom import observer_class
from marinebench.plugins import split_source
from marinebench.settings import lax_boolean


def preflight(exp: Experiment, file: Path, sweep_params: bool = True) -> None:
    """Solve every variant's observer design and check the step before anything runs, so an infeasible
    LMI or a too-large dt is a config error naming the file and key; check the per-run world settings of the
    variants and of the sweep's groups, and (``sweep_params``) that each sweep parameter's key and ``fixed`` settings
    name settings of the swept variant, valid at both ends of its range (its points are built, not designed or run)."""
    if exp.sweep is not None:
        swept = exp.part(exp.sweep_scenario()).scenario if exp.scenarios is not None else exp.scenario
        for group, world in exp.sweep.groups.items():
            _check_world(swept, world, file, f"sweep.groups.{group}")
    if exp.scenarios is None:
        _preflight_worlds(exp, file, "scenario", list(range(len(exp.variants))))
    else:
        position = {v.name: i for i, v in enumerate(exp.variants)}
        for name in exp.scenarios:
            part = exp.part(name)
            _preflight_worlds(part, file, f"scenarios.{name}", [position[v.name] for v in part.variants])
    if exp.sweep is not None and sweep_params:  # after the variants: what is left wrong is the sweep's own
        from marinebench.experiments.sweep import sweep_experiment

        # in one group: a world key that the groups set may still be swept in one of them (--groups NAME)
        sweep_experiment(exp, list(exp.sweep.params), list(exp.sweep.groups)[:1], 2, None, file)


@contextmanager
def _user_code(file: Path, key: str) -> Iterator[None]:
    """Run a custom class's own code at validation: whatever it raises (a constructor refusing its params, a
    member failing or returning the wrong thing, a ProtocolError: said as it is) becomes one config error at ``key``."""
    try:
        yield
    except ProtocolError as exc:
        raise ConfigError(file, key, str(exc)) from None
    except Exception as exc:  # noqa: BLE001 - the class's code: any exception is the user's to fix
        raise ConfigError(file, key, f"{type(exc).__name__}: {exc}") from None


@contextmanager
def _numerics(file: Path, key: str, failure: str, custom_key: str | None = None) -> Iterator[None]:
    """Build an observer's design or a world. A design that refuses its settings (an infeasible LMI), a custom
    class's constructor refusing its params (at ``custom_key``), and values valid in range but too extreme for the
    numerics (e.g. 1e300: an ArithmeticError or ValueError, as numpy's LinAlgError is) each become one config
    error (``failure``, then the exception); the numerics' warnings are shown only when the build succeeds."""
    from marinebench.errors import DesignError

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            yield
        except DesignError as exc:
            raise ConfigError(file, key, str(exc)) from None
        except Exception as exc:
            if custom_key is not None:
                raise ConfigError(file, custom_key, f"{type(exc).__name__}: {exc}") from None
            if not isinstance(exc, ArithmeticError | ValueError):
                raise
            first = str(exc).splitlines()[0] if str(exc) else "numerical failure"
            raise ConfigError(file, key, f"{failure} ({type(exc).__name__}: {first})") from None
    for w in caught:
        warnings.showwarning(w.message, w.category, w.filename, w.lineno)


def _preflight_worlds(exp: Experiment, file: Path, key: str, positions: list[int]) -> None:
    """Preflight of one scenario's variants in its own world (their settings, designs, signals), then in each world
    their settings make (:func:`~marinebench.experiments.runner.world_batches`: designs on that world's vessel, the
    step, the first step), named at the first such variant's ``world``."""
    from marinebench.experiments.runner import world_parts

    _preflight_single(exp, file, key, positions)
    for settings, index, own in world_parts(exp):
        if settings:
            _preflight_single(own, file, f"variants.{positions[index[0]]}.world", [positions[j] for j in index],
                              signals=False)


def _preflight_single(exp: Experiment, file: Path, key: str, positions: list[int], signals: bool = True) -> None:
    """Preflight of one scenario's variants (``key`` is where the scenario sits, ``positions`` the variants'
    indices in the file): each variant's controller or observer, the CDO designs, that each variant's world builds
    (one seed), the step, and (``signals``) the metrics' and figures' signals."""
    from marinebench.errors import StiffnessError
    from marinebench.experiments.runner import make_world, plant_of
    from marinebench.sim.engine import check_step

    model_key = "design_vessel" if getattr(exp.scenario, "design_vessel", None) is not None else "vessel"
    with _numerics(file, f"{key}.{model_key}", "the vessel model cannot be built from these values"):
        plant = plant_of(exp.scenario)  # the model every variant's observer is designed on
    named = [(v.name, g) for i, v in zip(positions, exp.variants)
             if (g := _preflight_variant(exp, file, i, v, plant)) is not None]
    groups = [g for _, g in named]
    if exp.scenario.kind == "rov_tracking":
        _preflight_cdo(exp, file, key, positions)
    if signals:
        _preflight_metrics(exp, file, groups)
        _preflight_figures(exp, file, groups)
    # the world's numerics' warnings are shown only if it builds, passes the step check and starts finite
    with _numerics(file, key, "the world cannot be built from these values"):  # each variant's, one seed
        world = make_world(exp, np.arange(len(exp.variants)), np.zeros(len(exp.variants), dtype=int))
        if exp.engine.check_step:
            try:
                check_step(groups, exp.scenario.dt, exp.engine.stiffness_limit, world)
            except StiffnessError as exc:
                raise ConfigError(file, f"{key}.dt", f"{exc} ({_fastest(exp, named, world)})") from None
        if (problem := _first_step_problem(world)) is not None:  # after the step check, which says more
            raise ConfigError(file, key, f"the world cannot be run from these values ({problem})")


def _first_step_problem(world: Any) -> str | None:
    """What is not finite in the world's first step (its sensors sampled, then its state derivative, measurement
    and input at t = 0), or None. Values in range but absurd for the physics (a sea state's gamma of 1e300) would
    otherwise make every run diverge at once, found only after the whole simulation."""
    x0 = world.x0.copy()
    with np.errstate(all="ignore"):
        if hasattr(world, "begin_step"):
            world.begin_step(0, 0.0, x0)
        parts = dict(zip(("state derivative", "measurement", "input"), world.derivative(0.0, x0)))
    bad = (["initial state"] if not np.isfinite(x0).all() else []) + [n for n, a in parts.items() if not np.isfinite(a).all()]
    return f"not finite at t = 0: its {' and '.join(bad)}" if bad else None


def _fastest(exp: Experiment, named: list, world: Any) -> str:
    """Which variant has the fastest observer pole: its observer group's, or those its world integrates (one run per
    variant, as preflight builds it; a world's own setting can make them all alike)."""
    rates = dict.fromkeys((v.name for v in exp.variants), 0.0)
    for name, group in named:
        rates[name] = max(rates[name], group.observer.max_rate())
    for v, rate in zip(exp.variants, world.observer_rates() if hasattr(world, "observer_rates") else []):
        rates[v.name] = max(rates[v.name], float(rate))
    if len(rates) > 1 and len(set(rates.values())) == 1:
        return "every variant alike"
    return f"the fastest: variant {max(rates, key=rates.__getitem__)!r}"


def _check_world(scenario: Any, world: dict[str, Any], file: Path, key: str) -> None:
    """A run's world settings (a variant's ``world:``, a sweep group): numbers for the keys the scenario takes per
    run, or settings of the world by their dotted paths (a world of their own, :meth:`~marinebench.scenario.
    ScenarioBase.with_settings`); values within the bounds of the world's own fields (e.g. no negative noise level)."""
    allowed = list(scenario.per_run_defaults())
    settings = scenario.world_settings(world)
    unknown = sorted(k for k in settings if not scenario.has_setting(k))
    if nulled := next(((k, null) for k in unknown if (null := scenario.null_section(k))), None):
        raise ConfigError(file, f"{key}.{nulled[0]}", f"not a setting of this world, whose {nulled[1]} is null")
    if unknown:
        near = did_you_mean(list(dict.fromkeys(m for u in unknown for m in [
            *near_misses(u, allowed), *difflib.get_close_matches(u, scenario.setting_paths(), 3, 0.8)])))
        takes = near or (f" (per run: {allowed}, or a setting of the world by its dotted path, e.g. sensors.<key>; "
                         f"{' and '.join(scenario.SHARED)} are every run's)")
        raise ConfigError(file, key, f"unknown world keys {unknown}{takes}")
    for k, v in world.items():  # per-run keys are numbers (other settings are checked by their world's fields)
        if k not in settings and (isinstance(v, bool) or not isinstance(v, float)):
            raise ConfigError(file, f"{key}.{k}", lax_boolean(v, 0.0)[1] if isinstance(v, bool) else
                              f"Input should be a number (a per-run key), not {v!r}")
    try:
        scenario.check_world(world)
    except ValidationError as exc:
        err = exc.errors()[0]
        msg = err["msg"].removeprefix("Value error, ")
        at = ".".join(map(str, err["loc"]))
        if not at:  # a check across a world's fields names its key in its message ("sensors.ts: ...")
            keys, rest = keyed_message(msg)
            at, msg = (keys[0], rest) if keys else (next(iter(world)), msg)
        raise ConfigError(file, f"{key}.{at}", msg) from None
    except ValueError as exc:  # a path inside another of the settings (waves.tp beside waves: null)
        keys, rest = keyed_message(str(exc))
        raise ConfigError(file, f"{key}.{keys[0]}" if keys else key, rest if keys else str(exc)) from None


def _preflight_variant(exp: Experiment, file: Path, i: int, v: Variant, plant: Any) -> Any:
    """Check variant ``i``: its per-run world keys, that it has what its scenario needs (a controller in a
    closed loop, an applicable observer otherwise), and that its design solves. Returns the observer's group
    for the step check, or None for a controller."""
    from marinebench.experiments.runner import make_observer, observer_kinds_for, wants_lumped
    from marinebench.sim.engine import ObserverGroup

    _check_world(exp.scenario, v.world, file, f"variants.{i}.world")
    closed_loop = exp.scenario.kind == "rov_tracking"
    if closed_loop != (v.controller is not None):
        need = "a 'controller'" if closed_loop else "an 'observer'"
        raise ConfigError(file, f"variants.{i}", f"scenario kind {exp.scenario.kind} needs {need} in every variant")
    if closed_loop:
        if v.controller.kind == "custom":
            with _user_code(file, f"variants.{i}.controller.params"):  # its constructor refusing its params
                built = v.controller.build(1)
            with _user_code(file, f"variants.{i}.controller.source"):
                check_controller(built, exp.scenario.control_period)
        if v.observer is not None and v.observer.kind == "custom":
            _preflight_rov_observer(exp, file, i, v)
        return None
    if v.observer.kind not in (usable := observer_kinds_for(exp.scenario)):
        raise ConfigError(file, f"variants.{i}.observer.kind", f"'{v.observer.kind}' does not apply to scenario kind "
                          f"{exp.scenario.kind} (its observers: {', '.join(sorted(usable))})")
    custom = v.observer.kind == "custom"
    if custom:
        _check_applies(exp, file, i, v.observer.source)
    with _numerics(file, f"variants.{i}.observer", "no design for these values",
                   f"variants.{i}.observer.params" if custom else None):
        group = ObserverGroup(make_observer(v.observer.kind, [v.observer], exp.scenario, plant, wants_lumped(exp)), [0])
    if custom:
        with _user_code(file, f"variants.{i}.observer.source"):
            check_observer(group.observer, 1)
    return group


def _check_applies(exp: Experiment, file: Path, i: int, source: str) -> None:
    """A custom observer class applies to the scenario's kind (its ``scenario_kinds``)."""
    if exp.scenario.kind not in (own := observer_class(source).scenario_kinds):
        raise ConfigError(file, f"variants.{i}.observer.source", f"{split_source(source)[1]} does not apply "
                          f"to scenario kind {exp.scenario.kind} (its scenario_kinds: {', '.join(own)})")


def _preflight_rov_observer(exp: Experiment, file: Path, i: int, v: Variant) -> None:
    """A closed-loop variant's custom observer (``observers/custom_rov.py``): it applies to the world, its constructor
    takes its params, and it answers as the protocol says for the ROV's two DOF, its signals the ROV's estimates."""
    from marinebench.observers.custom_rov import checked, observer_plant

    _check_applies(exp, file, i, v.observer.source)
    start = exp.scenario.initial_estimates(exp.scenario.per_run_values({k: [x] for k, x in v.world.items()}, 1))
    with _user_code(file, f"variants.{i}.observer.params"):  # its constructor refusing its params
        built = observer_class(v.observer.source)([v.observer.params], observer_plant(exp.scenario, start), exp.scenario.dt)
    with _user_code(file, f"variants.{i}.observer.source"):
        check_observer(checked(built, 1), 1, dof=2)


def _preflight_cdo(exp: Experiment, file: Path, key: str, positions: list[int]) -> None:
    """Solve the scenario's CDO design (LMIs (39)-(40)) and each distinct per-variant CDO override's."""
    failure = "the CDO design fails for these values"
    with _numerics(file, f"{key}.cdo", failure):
        exp.scenario.cdo_design()
    checked = set()
    for i, v in zip(positions, exp.variants):
        if v.observer is None or v.observer.kind == "custom" or not v.observer.cdo:
            continue
        cdo = v.observer.resolve(exp.scenario)[0]
        if (fingerprint := cdo.model_dump_json()) in checked:
            continue
        with _numerics(file, f"variants.{i}.observer.cdo", failure):
            exp.scenario.cdo_design(cdo)
        checked.add(fingerprint)


def _estimated(groups: list) -> set[str]:
    """The signals the variants' observers estimate; on a closed-loop world (no observer groups) its own."""
    from marinebench.rov_scenario import ROV_SIGNALS

    return set().union(*(g.observer.signals for g in groups)) if groups else set(ROV_SIGNALS)


def _preflight_figures(exp: Experiment, file: Path, groups: list) -> None:
    """Every figure's signals are in the traces: estimated by a variant's observer, with a truth in the world. Before,
    a figure of another signal failed after the whole simulation, with a traceback."""
    truth = TRUTH_SIGNALS.get(exp.scenario.kind)
    usable = _estimated(groups) & set(truth) if truth is not None else _estimated(groups)
    for f in exp.figures:
        if bad := [s for s in f.signals if s not in usable]:
            raise ConfigError(file, "figures", f"{f.file}: no trace of {bad} on this world (a figure may show: "
                              f"{', '.join(sorted(usable))}; `marinebench list {exp.scenario.kind}` says what each is)")


def _preflight_metrics(exp: Experiment, file: Path, groups: list) -> None:
    """Every metric's signals are ones the variants' observers estimate and the world has a truth of."""
    signals = _estimated(groups)
    truth = TRUTH_SIGNALS.get(exp.scenario.kind)
    for j, m in enumerate(exp.metrics):
        if m.kind not in ("j_tot", "int", "recovery"):
            if bad := set(m.signals) - signals:
                hint = (did_you_mean(near_misses(min(bad), sorted(signals)))
                        or f" (estimated here: {', '.join(sorted(signals))}; `marinebench list {exp.scenario.kind}` "
                           "says what each is)")
                raise ConfigError(file, f"metrics.{j}.signals", f"unknown signals {sorted(bad)}{hint}")
            if truth is not None and set(m.signals) - set(truth):
                raise ConfigError(file, f"metrics.{j}.signals", f"{sorted(set(m.signals) - set(truth))}: an "
                                  f"{exp.scenario.kind} world has no truth of these (it has {', '.join(truth)})")
        if m.kind == "j_tot" and not set(DP_SIGNALS) <= signals:
            raise ConfigError(file, f"metrics.{j}", "j_tot needs the DP state estimates (pose, bias, velocity), "
                              "which no variant's observer produces (npo and resetting_fto do)")
