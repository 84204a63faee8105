"""marinebench: simulation benchmarks for marine-vehicle observers and controllers.

The command line (``marinebench run/sweep/compare ...``) is the main interface. The same steps from Python
(a notebook, a script)::

    import marinebench as mb

    exp = mb.load("configs/torben_fig1.yaml", sets=["seeds=2"])  # validated; observer designs solved
    result = mb.run(exp)  # result.metrics: the tidy metrics.csv as a DataFrame; .summary: mean and CI
    result.trace_frame()  # the figures' data: truth and estimate of seed 0 of each variant over time, tidy
    mb.write(result, "results/torben_fig1_2seeds", config="configs/torben_fig1.yaml")  # the run's files

Bad input raises :class:`marinebench.errors.ConfigError`, whose message names the file and key.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from marinebench.config import Experiment
    from marinebench.experiments.runner import RunResult

__version__ = "0.1.0"
__all__ = ["load", "run", "write"]


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
    from marinebench.config import Experiment
    from marinebench.experiments.runner import run as run_experiment

    if isinstance(experiment, str | Path):
        experiment = load(experiment)
    if not isinstance(experiment, Experiment):
        raise TypeError(f"run() takes an Experiment (marinebench.load(path)) or a path, not {type(experiment).__name__}")
    return run_experiment(experiment, traces=traces)


def write(result: RunResult, out_dir: str | Path, config: str | Path | None = None) -> Path:
    """Write ``config.resolved.yaml``, ``manifest.json``, ``metrics.csv``, ``table.md`` and ``figures/``
    atomically to ``out_dir``, as ``marinebench run`` does (``config``: the file to name in the manifest)."""
    from marinebench.experiments.runner import RunResult
    from marinebench.results.outputs import write_run

    if not isinstance(result, RunResult):
        raise TypeError(f"write() takes the RunResult of marinebench.run(), not {type(result).__name__}")
    return write_run(result, Path(out_dir), {"experiment": Path(config)} if config is not None else {})
