"""``marinebench bench``: the batched engine timed against the plain per-run reference on the same runs."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from marinebench.cli.common import (
    DEFAULT_SWEEP,
    SweepConfig,
    check_points,
    check_sweep_config,
    load_config,
    one_line_errors,
    out,
)
from marinebench.errors import ConfigError


def bench(
    config: SweepConfig = DEFAULT_SWEEP,
    params: Annotated[str, typer.Option(metavar="PARAMS", help="comma-separated swept parameters")] = "k,delta,eps",
    n: Annotated[int | None, typer.Option("--n", metavar="N", help="points per parameter (default: the config's)")] = None,
    horizon: Annotated[float, typer.Option(metavar="SECONDS", min=0.1, help="simulated seconds per run in the benchmark")] = 50.0,
    runs: Annotated[int, typer.Option(metavar="N", min=1, help="runs timed with the per-run reference loop")] = 3,
) -> None:
    """Time the batched engine against the plain per-run reference on the same runs, in one process."""
    import resource
    import time as _time

    from marinebench.experiments.reference import against_reference
    from marinebench.experiments.runner import run as run_experiment
    from marinebench.experiments.sweep import sweep_experiment

    check_points(n, horizon)
    check_sweep_config(config)
    with one_line_errors():
        base, _ = load_config(config, [], None, None, sweep_params=False)
        _benchable(base, config)
        names = params.split(",")
        have = list(base.sweep.params) if base.sweep is not None else []
        if unknown := [p for p in names if p not in have]:
            raise ConfigError("--params", "", f"{params}: {config} has no sweep parameter {unknown[0]!r} (its "
                              f"sweep.params: {', '.join(have) or 'none: the config has no sweep section'})")
        if len(set(names)) < len(names):
            raise ConfigError("--params", "", f"{params}: a parameter given more than once")
        exp = sweep_experiment(base, names, None, n, horizon, config)
    full_horizon = base.scenario.horizon
    B = len(exp.variants)
    t0 = _time.perf_counter()
    batched = run_experiment(exp, traces=False)
    t_batch = _time.perf_counter() - t0
    picks = np.linspace(0, B - 1, max(1, min(runs, B))).round().astype(int)
    t_ref, worst = against_reference(exp, batched.metrics, picks)
    scale = full_horizon / horizon
    per_run_batched = t_batch / B
    out.print(f"runs: {B} x {horizon:g} s (sweep {params}); reference on {len(picks)} of them", markup=False)
    out.print(f"batched engine:      {t_batch:8.2f} s  ({per_run_batched * 1e3:.2f} ms per run)", markup=False)
    out.print(f"per-run reference:   {t_ref * B:8.2f} s  ({t_ref * 1e3:.2f} ms per run, extrapolated to {B} runs)", markup=False)
    out.print(f"speed-up (same process): {t_ref / per_run_batched:.1f}x", markup=False)
    out.print(f"extrapolated full sweep ({B} x {full_horizon:g} s): batched {t_batch * scale:.1f} s, "
              f"reference {t_ref * B * scale:.0f} s", markup=False)
    out.print(f"largest relative J_tot difference batched vs reference: {worst:.2e}", markup=False)
    out.print(f"peak RSS: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB", markup=False)


def _benchable(base, config: Path) -> None:
    """bench: the plain per-run reference exists for the DP observers (NPO, resetting) in a dp_supply world, and is
    compared with the batch on its J_tot metric."""
    if base.scenario is None or base.scenario.kind != "dp_supply":
        raise ConfigError(config, "scenario.kind", "bench compares the batched engine with the plain per-run "
                          "reference of the DP observers, which exists for dp_supply scenarios (e.g. configs/torben_fig3.yaml)")
    swept = [v for v in base.variants if v.name in (base.sweep.swept if base.sweep is not None else [])]
    if other := [v.name for v in swept if v.observer.kind not in ("npo", "resetting_fto")]:
        raise ConfigError(config, "sweep.variant", f"{other[0]}: bench's per-run reference is of the DP observers (npo, "
                          "resetting_fto), not of this variant's (e.g. configs/torben_fig3.yaml)")
    if not any(m.kind == "j_tot" and m.label == "J_tot" for m in base.metrics):
        raise ConfigError(config, "metrics", "bench compares the batch with the reference on a j_tot metric named J_tot")
