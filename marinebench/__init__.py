"""marinebench: simulation benchmarks for marine-vehicle observers and controllers.

The command line (``marinebench run/sweep/compare ...``) is the main interface. The same steps from Python
(a notebook, a script)::

    import marinebench as mb

    exp = mb.load("configs/torben_fig1.yaml", sets=["seeds=2"])  # validated; observer designs solved
    result = mb.run(exp)  # result.metrics: the tidy metrics.csv as a DataFrame; .summary: mean and CI
    result.trace_frame()  # the figures' data: truth and estimate of seed 0 of each variant over time, tidy
    mb.write(result, "results/torben_fig1_2seeds", config="configs/torben_fig1.yaml")  # the run's files
    mb.sweep("configs/torben_fig3.yaml", "k", n=11).metrics  # a sweep's runs, tagged param, param_value, gnss
    mb.compare("results/", "candidate/")  # the CI gate's table: one row per cell, its verdict; worse: a regression

Bad input raises a :class:`marinebench.errors.MarinebenchError` whose message names the file (a config's, a
:class:`~marinebench.errors.ConfigError`, names the key too); a bad argument, ValueError or TypeError.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pandas as pd

    from marinebench.config import Experiment
    from marinebench.experiments.runner import RunResult

__version__ = "0.1.0"
__all__ = ["compare", "load", "run", "sweep", "write"]


def load(path: str | Path, sets: Sequence[str] | str | None = (), profile: str | None = None) -> Experiment:
    """Read, validate and preflight an experiment YAML (``sets``: ``dotted.key=value`` overrides, as
    ``--set``, a list, or one string; ``profile``: a named profile of the config, as ``--profile``)."""
    from marinebench.loading import load_checked

    sets = [sets] if isinstance(sets, str) else list(sets or ())
    if wrong := [s for s in sets if not isinstance(s, str)]:
        raise TypeError(f"load(): each of sets is a 'dotted.key=value' string, not {wrong[0]!r}")
    return load_checked(path, sets, profile)[0]


def run(experiment: Experiment | str | Path, traces: bool = True) -> RunResult:
    """Simulate every variant x seed of an experiment in one batch (``traces``: keep the decimated traces
    the figures need: seed 0 of each variant, ``result.traced`` are their run indices). A path is loaded first,
    as :func:`load` does with no overrides."""
    from marinebench.experiments.runner import run as run_experiment

    return run_experiment(_experiment(experiment, "run"), traces=traces)


def sweep(experiment: Experiment | str | Path, params: Sequence[str] | str | None = None, *, n: int | None = None,
          grid: bool = False, groups: Sequence[str] | None = None, horizon: float | None = None) -> RunResult:
    """Simulate an experiment's sensitivity sweep (its ``sweep:`` section), every point and seed in one batch in
    this process, as ``marinebench sweep`` does but without writing files. ``params``: names of ``sweep.params``
    (default: all of them), or parameters given in place as ``marinebench sweep`` takes them, ``KEY=LO..HI[:log]``
    (``"delta_p1=0.5..3"``, ``"world.gnss_sigma=0.05..3:log"``; named after the key's last part, and added to the
    section or making one), one at a time, or with ``grid`` exactly two, every combination; ``n``: points per
    parameter (default: ``sweep.n``, or 11 on a grid); ``groups``: some of ``sweep.groups`` (Torben's ``dgnss``,
    ``dualband``; default: all); ``horizon``: simulated seconds per run. ``result.metrics`` tags every run with
    ``param``, ``param_value`` and ``gnss`` (its group), and on a grid ``param2`` and ``param2_value``: the
    command's ``metrics.csv`` (its rows in the same order), which rounds the values to 7 digits. Other settings go through :func:`load`:
    ``sets=["seeds=5"]``, ``"sweep.variants=[a, b]"``, or a parameter with probes or fixed settings,
    ``"sweep.params.NAME={key: KEY, range: [LO, HI], fixed: {...}}"``. A path is loaded first, as :func:`load` does."""
    from marinebench.errors import ConfigError
    from marinebench.experiments import sweep as sweeps
    from marinebench.experiments.chunks import sweep_order
    from marinebench.experiments.runner import run as run_experiment
    from marinebench.preflight import preflight

    if bad := sweeps.points_error(n, horizon):
        given = n if bad[0] == "n" else horizon
        raise ValueError(f"sweep(): {bad[0]} must be {bad[1]}, not {given!r}")
    params = [params] if isinstance(params, str) else list(params or [])
    if wrong := [p for p in params if not isinstance(p, str)]:
        raise TypeError(f"sweep(): each of params is a name of sweep.params or 'KEY=LO..HI[:log]', not {wrong[0]!r}")
    params, inline = sweeps.inline_params(params, sweeps.LIBRARY_ARGS["params"])
    exp = _experiment(experiment, "sweep")
    file = Path(experiment) if isinstance(experiment, str | Path) else Path(exp.name)  # what errors name
    exp = sweeps.with_params_in_place(exp, inline, file)
    if exp.sweep is None:
        raise ConfigError(file, "sweep", "no 'sweep' section: give a parameter in place, sweep(exp, 'KEY=LO..HI'), "
                          'or load the experiment with one, sets=["sweep.params.NAME={key: KEY, range: [LO, HI]}"]')
    params = params or list(exp.sweep.params)
    if grid and len(set(params)) != 2:
        raise ValueError(f"sweep(): grid=True takes two different parameters, not {params}")
    try:
        points = sweeps.sweep_experiment(exp, params, list(groups) if groups else None, n, horizon, file, grid=grid,
                                         args=sweeps.LIBRARY_ARGS)
        preflight(points, file)
    except ConfigError as exc:  # a parameter given in place named as typed
        raise sweeps.in_place_error(exc, inline) from None
    result = run_experiment(points, traces=False)
    return dataclasses.replace(result, metrics=sweep_order(result.metrics, points))


def _experiment(experiment: Experiment | str | Path, caller: str) -> Experiment:
    """:func:`run`'s and :func:`sweep`'s experiment: as given, or loaded from a path."""
    from marinebench.config import Experiment

    if isinstance(experiment, str | Path):
        experiment = load(experiment)
    if not isinstance(experiment, Experiment):
        raise TypeError(f"{caller}() takes an Experiment (marinebench.load(path)) or a path, not {type(experiment).__name__}")
    return experiment


def write(result: RunResult, out_dir: str | Path, config: str | Path | None = None) -> Path:
    """Write ``config.resolved.yaml``, ``manifest.json``, ``metrics.csv``, ``table.md`` and ``figures/``
    atomically to ``out_dir``, as ``marinebench run`` does (``config``: the file to name in the manifest). The figures
    are drawn from the result's traces: one of ``run(..., traces=False)`` is a ValueError (nothing written) unless its
    config draws no figures."""
    from marinebench.experiments.runner import RunResult
    from marinebench.results.outputs import write_run

    if not isinstance(result, RunResult):
        raise TypeError(f"write() takes the RunResult of marinebench.run(), not {type(result).__name__}")
    return write_run(result, Path(out_dir), {"experiment": Path(config)} if config is not None else {})


def compare(baseline: str | Path, candidate: str | Path | None = None, *, variants: Sequence[str] | None = None,
            metrics: Sequence[str] | str | None = None, rtol: float = 0.02, atol: float = 0.0, paired: bool = True,
            interval: str | None = None) -> pd.DataFrame:
    """Compare result folders (or trees of them, e.g. ``results/``) cell by cell over seeds, as ``marinebench
    compare`` does, writing nothing: ``candidate`` against ``baseline``, or with ``variants=(A, B)`` variant B against
    A inside ``baseline``. ``metrics``: only these (``"claim"`` for the papers' claims); ``rtol``/``atol``: what counts
    as the same; ``paired=False``: independent samples (``--unpaired``); ``interval``: ``"bootstrap"`` or ``"t"``
    (``--interval``). Returns one row per cell (experiment, scenario, variant, signal, metric) with the two means, the
    change and its CI, and ``verdict`` (worse, missing, new, changed, better, same), the most severe first: the gate fails
    where ``(table.verdict == "worse").any()`` (the command's ``--strict``: ``table.verdict.isin(["worse",
    "missing"]).any()``). Unusable input raises :class:`marinebench.errors.MarinebenchError`
    naming the folder or file; a bad argument, ValueError."""
    from marinebench.results.compare import Tolerance, compare_error, comparison

    pair = None if variants is None or isinstance(variants, str) else tuple(variants)
    if variants is not None and (pair is None or len(pair) != 2 or not all(isinstance(v, str) for v in pair)):
        raise ValueError(f"compare(): variants is two variant names (A, B), not {variants!r}")
    metrics = [metrics] if isinstance(metrics, str) else None if metrics is None else list(metrics)
    tol = Tolerance(rtol=rtol, atol=atol)
    names = {"tol": "rtol/atol", "interval": "interval", "unpaired": "paired=False", "candidate": "a candidate",
             "variants": "variants", "pair": "variants=(A, B)"}
    if wrong := compare_error(candidate, pair, tol, interval, paired, names):
        raise ValueError(f"compare(): {wrong}")
    candidate = None if candidate is None else Path(candidate)
    return comparison(Path(baseline), candidate, pair, metrics, tol, paired, interval)
