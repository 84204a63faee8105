"""Speed and memory of the batched engine on the Torben sweep (pytest-benchmark; not part of ``pytest``).

    pip install -e '.[bench]'
    pytest benchmarks -n 0                              # timings, the speed-up and the memory target
    pytest benchmarks -n 0 --benchmark-autosave         # keep this machine's timings ...
    pytest benchmarks -n 0 --benchmark-compare --benchmark-compare-fail=mean:15%   # ... and gate later commits on them

(``-n 0``: in one process; pyproject's pytest options spread test files over pytest-xdist workers, and
pytest-benchmark does not time under xdist.)

The targets are those of the sweep issue, checked as ratios measured in the same process (the machines are
shared and noisy): the 600-run batch must be at least 10x faster per run than the plain per-run reference
loop (``experiments/reference.py``), agree with it, and stay under 500 MiB of traced
memory. Runs are 20 s long, so a round takes seconds; the speed-up grows with the horizon (33x here, 42x at 50 s with
``marinebench bench``, which also extrapolates to the full sweep).
"""

import tracemalloc
from pathlib import Path

import pytest

from marinebench.experiments.reference import against_reference
from marinebench.experiments.runner import run
from marinebench.experiments.sweep import sweep_experiment
from marinebench.loading import load_experiment

ROOT = Path(__file__).resolve().parents[1]
CFG = ROOT / "configs" / "torben_fig3.yaml"
HORIZON = 20.0  # simulated seconds per run


@pytest.fixture(scope="module")
def sweep():
    base, _ = load_experiment(CFG)
    return sweep_experiment(base, ["k", "delta", "eps"], None, None, HORIZON, CFG)  # 600 runs


def test_batched_sweep_is_at_least_10x_the_per_run_loop(benchmark, sweep):
    result = benchmark.pedantic(lambda: run(sweep, traces=False), rounds=3, iterations=1, warmup_rounds=1)
    runs = len(sweep.variants)
    per_run_reference, worst = against_reference(sweep, result.metrics, [0, runs // 2, runs - 1])
    speedup = per_run_reference / (benchmark.stats.stats.median / runs)
    benchmark.extra_info.update(runs=runs, horizon_s=HORIZON, speedup_vs_reference=round(speedup, 1), max_rel_diff_J=worst)
    assert worst < 1e-9
    assert speedup >= 10, f"batched engine only {speedup:.1f}x faster per run than the reference loop"


def test_batched_sweep_memory_stays_under_500_mib(sweep):
    tracemalloc.start()
    try:
        run(sweep, traces=False)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 500 * 2**20, f"peak traced memory {peak / 2**20:.0f} MiB"
