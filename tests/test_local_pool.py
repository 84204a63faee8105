"""Sweeps in local worker processes (``sweep --jobs``): the same numbers as in one process, progress while the
batches run, resumable after a failed batch, and clear refusals."""

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from marinebench.cli import app
from marinebench.errors import ClusterError
from marinebench.experiments import runner as runner_module
from marinebench.experiments.chunks import chunks_of, run_chunked
from marinebench.experiments.cluster import available_cores, local_pool
from marinebench.experiments.sweep import sweep_experiment
from marinebench.loading import load_experiment

from .conftest import TORBEN_FIG3 as CFG
from .conftest import sorted_values as _values


def test_worker_processes_give_the_in_process_numbers_report_progress_and_resume(tmp_path):
    base, _ = load_experiment(CFG)
    exp = sweep_experiment(base, ["k"], ["dgnss"], 3, 60.0, CFG)  # 3 runs of 1200 steps, 3 chunks of 1
    assert len(chunks_of(exp, 1)) == 3 and len(chunks_of(exp, 2)) == 2
    two = exp.model_copy(update={"seeds": 2})  # a chunk's size counts runs: 2 seeds of each variant
    assert [len(c) for c in chunks_of(two, 4)] == [2, 1] and [len(c) for c in chunks_of(two, 1)] == [1, 1, 1]
    local, _, _ = run_chunked(exp, tmp_path / "local", chunk_size=1)
    target, partial = tmp_path / "pool", tmp_path / ".pool.partial"
    steps = []
    with local_pool(2) as pool:
        assert pool.describe() == "2 local worker process(es)"
        first, summed, ran = run_chunked(exp, target, chunk_size=1, progress=steps.append, pool=pool)
        assert ran == 3 and summed > 0 and _values(first) == _values(local)
        assert sum(steps) == 3 * 1200  # each worker's engine reports its steps through the shared counter
        (partial / "chunk-0002.csv").unlink()  # as if the sweep had been interrupted before this chunk came back
        resumed, _, ran = run_chunked(exp, target, chunk_size=1, pool=pool)
    assert ran == 1 and _values(resumed) == _values(local)


def test_a_batch_failing_in_a_worker_keeps_the_finished_batches_and_a_rerun_resumes(tmp_path, monkeypatch):
    base, _ = load_experiment(CFG)
    exp = sweep_experiment(base, ["k"], ["dgnss"], 3, 15.0, CFG)  # 3 chunks of 1 run
    reference, _, _ = run_chunked(exp, tmp_path / "local", chunk_size=1)
    real = runner_module.run

    def failing(e, *args, **kwargs):
        if e.variants[0].name == exp.variants[1].name:
            raise MemoryError("worker ran out of memory")
        return real(e, *args, **kwargs)

    monkeypatch.setattr(runner_module, "run", failing)  # before the pool: its workers are forked with it
    target, partial = tmp_path / "pool", tmp_path / ".pool.partial"
    with local_pool(1) as pool, pytest.raises(ClusterError, match=r"^--jobs: chunk 1 failed on a worker "
                                               r"\(MemoryError: worker ran out of memory\); the finished chunks are kept"):
        run_chunked(exp, target, chunk_size=1, pool=pool)
    assert (partial / "chunk-0000.csv").exists() and not (partial / "chunk-0001.csv").exists()
    monkeypatch.setattr(runner_module, "run", real)
    with local_pool(2) as pool:
        resumed, _, ran = run_chunked(exp, target, chunk_size=1, pool=pool)
    assert 1 <= ran <= 2 and _values(resumed) == _values(reference)


def test_cli_sweep_jobs_and_their_manifest(tmp_path):
    args = ["sweep", "k", "--config", str(CFG), "--n", "2", "--horizon", "15", "--gnss", "dgnss", "--chunk-size", "1",
            "--quiet"]
    one = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "one"), "--jobs", "1"])
    two = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "two"), "--jobs", "2"])
    assert one.exit_code == 0 and two.exit_code == 0, one.output + two.output
    folder = "torben_fig3_sweep_k_dgnss_n2_15s"
    a, b = (pd.read_csv(tmp_path / d / folder / "metrics.csv") for d in ("one", "two"))
    assert _values(a) == _values(b)
    m1, m2 = (json.loads((tmp_path / d / folder / "manifest.json").read_text()) for d in ("one", "two"))
    assert m1["executor"] == "this process" and m2["executor"] == "2 local worker process(es)"
    assert m2["wall_time_s"] > 0 and m2["batch_time_s"] > 0 and m2["chunks_run"] == 2


def test_jobs_with_dask_is_refused_in_one_line(tmp_path):
    res = CliRunner().invoke(app, ["sweep", "k", "--config", str(CFG), "--n", "2", "--horizon", "15", "--out",
                                   str(tmp_path), "--jobs", "2", "--dask", "local", "--quiet"])
    assert res.exit_code == 2 and len(res.output.strip().splitlines()) == 1
    assert res.output.startswith("error: --jobs:") and not any(tmp_path.iterdir())


def test_ctrl_c_stops_the_running_batches_instead_of_waiting_for_them():
    with pytest.raises(KeyboardInterrupt), local_pool(1) as pool:
        workers = list(pool.pool._processes.values())
        pool.pool.submit(time.sleep, 30)  # a batch that would keep the shutdown waiting for 30 s, then exit 0
        raise KeyboardInterrupt  # the user presses Ctrl-C while it runs
    assert [w.exitcode for w in workers] == [-signal.SIGTERM]  # stopped, not waited for


_KILLED_PARENT = """
import os, signal, time
from marinebench.experiments.cluster import LocalPool
pool = LocalPool(2)
pool.pool.submit(time.sleep, 120)  # a chunk still running when the parent dies
print(*(p.pid for p in pool.pool._processes.values()), flush=True)
os.kill(os.getpid(), signal.SIGKILL)  # as kill -9 or the OOM killer would: no handler, no shutdown
"""


def _running(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except FileNotFoundError:
        return False
    return state != "Z"  # an orphan that exited may stay a zombie where nothing reaps it


def test_workers_end_when_the_process_that_made_the_pool_is_killed(tmp_path):
    pids, errors = tmp_path / "workers.txt", tmp_path / "stderr.txt"
    with pids.open("w") as out, errors.open("w") as err:  # files: orphans holding a pipe would keep run() waiting
        done = subprocess.run([sys.executable, "-c", _KILLED_PARENT], stdout=out, stderr=err, check=False, timeout=60)
    workers = [int(pid) for pid in pids.read_text().split()]
    assert done.returncode == -9 and len(workers) == 2, errors.read_text()
    deadline = time.monotonic() + 20
    while any(map(_running, workers)) and time.monotonic() < deadline:
        time.sleep(0.1)
    left = [pid for pid in workers if _running(pid)]
    for pid in left:  # do not leave them behind on a failure
        subprocess.run(["kill", "-9", str(pid)], check=False)
    assert not left, "orphaned workers still running after their parent was killed"


def _worker_setup() -> tuple:
    from threadpoolctl import threadpool_info

    return (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM),
            max((lib["num_threads"] for lib in threadpool_info()), default=1))


def test_workers_are_forked_ignore_ctrl_c_end_on_sigterm_and_run_one_blas_thread():
    # as in the CLI, which a fork inherits: its SIGTERM handler, and Ctrl-C raising KeyboardInterrupt (a test
    # runner's worker may ignore SIGINT)
    term = signal.signal(signal.SIGTERM, lambda *_: None)
    interrupt = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with local_pool(1) as pool:
            assert pool.pool._mp_context.get_start_method() == "fork"  # shares this process's imported modules
            sigint, sigterm, blas_threads = pool.pool.submit(_worker_setup).result()
    finally:
        signal.signal(signal.SIGTERM, term)
        signal.signal(signal.SIGINT, interrupt)
    assert sigint == signal.SIG_IGN  # Ctrl-C reaches the process group; the parent stops the workers
    assert sigterm == signal.SIG_DFL  # so the parent's terminate() ends them, not the inherited handler
    assert blas_threads == 1


def _mark(folder: Path, i: int, progress) -> int:
    (folder / f"{i}.done").touch()
    time.sleep(0.3)
    return i


def test_closing_the_pool_cancels_the_chunks_nobody_waits_for(tmp_path):
    with local_pool(1) as pool:
        for _ in pool.results(_mark, {i: (tmp_path, i) for i in range(10)}):
            break  # the consumer stops after the first chunk
    # the finished one, the one running and the two in the worker's call queue (workers + 1 deep; handed over,
    # so no longer cancellable), not the other six
    assert len(list(tmp_path.glob("*.done"))) <= 4


def test_the_default_worker_count_is_the_cores_this_process_may_run_on(monkeypatch):
    """``--jobs`` defaults to the affinity mask (``taskset``, a container's cpuset), not the machine's core count."""
    monkeypatch.setattr("os.sched_getaffinity", lambda pid: {3}, raising=False)
    assert available_cores() == 1
    monkeypatch.delattr("os.sched_getaffinity", raising=False)  # where the OS has no affinity mask
    monkeypatch.setattr("os.cpu_count", lambda: 6)
    assert available_cores() == 6


def _square_or_fail(x: int, progress=None) -> int:
    if x == 3:
        raise MemoryError("worker ran out of memory")
    return x * x


def test_chunks_that_finish_beside_a_failed_one_are_all_kept(monkeypatch):
    """Under load every chunk may be done by the time the pool looks (here forced: it waits for all): before, the
    failed chunk could come first in the unordered set and the finished ones beside it were dropped, so a rerun
    simulated them again (the flaky failure of the test above on a busy machine)."""
    from concurrent.futures import ALL_COMPLETED
    from concurrent.futures import wait as real_wait

    from marinebench.experiments import cluster

    monkeypatch.setattr(cluster, "wait", lambda fs, timeout=None, return_when=None: real_wait(fs, return_when=ALL_COMPLETED))
    got = {}
    with local_pool(2) as pool, pytest.raises(cluster.ChunkFailed) as failed:
        for c, value in pool.results(_square_or_fail, {c: (c,) for c in range(8)}):
            got[c] = value
    assert failed.value.chunk == 3 and got == {c: c * c for c in range(8) if c != 3}
