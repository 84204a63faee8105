"""Sweeps on Dask: the same numbers as in one process, resumable, and clear errors when Dask is unusable."""

import sys

import pandas as pd
import pytest
from typer.testing import CliRunner

from marinebench.cli import app
from marinebench.errors import ClusterError
from marinebench.experiments import chunks
from marinebench.experiments.chunks import run_chunked
from marinebench.experiments.cluster import DaskPool, check_workers, dask_pool
from marinebench.experiments.sweep import sweep_experiment
from marinebench.loading import load_experiment
from marinebench.provenance import package_digest

from .conftest import TORBEN_FIG3 as CFG
from .conftest import sorted_values as _values


def test_dask_chunks_give_the_in_process_numbers_and_resume(tmp_path):
    from distributed import Client

    base, _ = load_experiment(CFG)
    exp = sweep_experiment(base, ["k"], None, 3, 15.0, CFG)  # 6 runs, 3 chunks of 2
    here, there = [], []
    local, _, ran_local = run_chunked(exp, tmp_path / "local", chunk_size=2, progress=here.append)
    target = tmp_path / "dask"
    partial = tmp_path / ".dask.partial"
    with Client(processes=False, n_workers=1, threads_per_worker=2, dashboard_address=None) as client:
        first, _, ran = run_chunked(exp, target, chunk_size=2, progress=there.append, pool=DaskPool(client))
        assert ran == ran_local == 3 and _values(first) == _values(local)
        assert sum(there) == sum(here) == 3 * 300 and there.count(300) == 3  # the bar moves as each chunk comes back
        (partial / "chunk-0001.csv").unlink()  # as if the sweep had been interrupted before this chunk came back
        resumed, _, ran = run_chunked(exp, target, chunk_size=2, pool=DaskPool(client))
    assert ran == 1 and _values(resumed) == _values(local)


def test_cli_sweep_on_a_local_dask_cluster(tmp_path):
    args = ["sweep", "k", "--config", str(CFG), "--n", "2", "--horizon", "15", "--gnss", "dgnss", "--chunk-size", "1",
            "--quiet"]
    plain = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "plain")])
    dask = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "dask"), "--dask", "local", "--workers", "1"])
    assert plain.exit_code == 0 and dask.exit_code == 0, plain.output + dask.output
    a = pd.read_csv(tmp_path / "plain" / "torben_fig3_sweep_k_dgnss_n2_15s" / "metrics.csv")
    b = pd.read_csv(tmp_path / "dask" / "torben_fig3_sweep_k_dgnss_n2_15s" / "metrics.csv")
    assert _values(a) == _values(b)
    assert "dask local cluster, 1 worker" in (tmp_path / "dask" / "torben_fig3_sweep_k_dgnss_n2_15s" / "manifest.json").read_text()


def test_cli_sweep_through_a_scheduler_address(tmp_path):
    from distributed import LocalCluster

    args = ["sweep", "k", "--config", str(CFG), "--n", "2", "--horizon", "15", "--gnss", "dgnss", "--quiet"]
    plain = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "plain")])
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        remote = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "remote"), "--dask", cluster.scheduler_address])
    assert plain.exit_code == 0 and remote.exit_code == 0, plain.output + remote.output
    a = pd.read_csv(tmp_path / "plain" / "torben_fig3_sweep_k_dgnss_n2_15s" / "metrics.csv")
    b = pd.read_csv(tmp_path / "remote" / "torben_fig3_sweep_k_dgnss_n2_15s" / "metrics.csv")
    assert _values(a) == _values(b)
    assert f"dask scheduler {cluster.scheduler_address}" in (tmp_path / "remote" / "torben_fig3_sweep_k_dgnss_n2_15s" / "manifest.json").read_text()


def test_unreachable_scheduler_is_a_clear_error():
    with pytest.raises(ClusterError, match="cannot reach the scheduler"), dask_pool("tcp://127.0.0.1:9", timeout=1.0):
        pass


def test_missing_dask_is_one_line_exit_2_and_nothing_written(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if the 'dask' extra were not installed
    res = CliRunner().invoke(app, ["sweep", "k", "--config", str(CFG), "--n", "2", "--horizon", "15",
                                   "--out", str(tmp_path / "out"), "--dask", "local", "--quiet"])
    assert res.exit_code == 2 and res.output.strip().splitlines() == [
        "error: --dask: needs Dask's distributed scheduler: pip install -e '.[dask]'"]
    assert not any(tmp_path.iterdir())  # not even the --out folder the command made


class FakeClient:
    """Answers ``client.run`` per function as given workers would (a value or an exception per worker)."""

    def __init__(self, versions: dict, digests: dict, joined: bool = True) -> None:
        self.answers = {"version": versions, "package_digest": digests}
        self.joined = joined

    def wait_for_workers(self, n: int, timeout: float) -> None:
        if not self.joined:
            raise TimeoutError

    def run(self, function, *args, on_error="raise"):
        assert on_error == "return"
        return self.answers[function.__name__]


def test_a_local_cluster_checks_its_workers_and_is_shut_down_with_the_pool(monkeypatch):
    import os

    import distributed

    from marinebench.experiments import cluster

    closed = []

    class Recorded(distributed.LocalCluster):
        def close(self, *args, **kwargs):
            closed.append(True)
            return super().close(*args, **kwargs)

    monkeypatch.setattr(distributed, "LocalCluster", Recorded)
    with dask_pool("local", workers=1) as pool:
        assert pool.describe() == "dask local cluster, 1 worker process(es)"
    assert closed == [True]
    # a digest that differs between processes (each worker's pid) stands for workers running another source
    monkeypatch.setattr(cluster, "package_digest", os.getpid)
    with pytest.raises(ClusterError, match="run another marinebench source"), dask_pool("local", workers=1):
        pass
    assert closed == [True, True]


def test_workers_must_run_this_marinebench():
    mine = package_digest()
    check_workers(FakeClient({"w1": "0.1.0", "w2": "0.1.0"}, {"w1": mine, "w2": mine}))  # accepted
    missing = FakeClient({"w1": "0.1.0", "w2": ModuleNotFoundError("marinebench")}, {"w1": mine})
    with pytest.raises(ClusterError, match=r"not installed on 1 of 2 worker\(s\) \(e.g. w2\)"):
        check_workers(missing)
    other = FakeClient({"w1": "0.1.0", "w2": "0.1.0"}, {"w1": mine, "w2": "0" * 64})
    with pytest.raises(ClusterError, match=r"1 of 2 worker\(s\) run another marinebench source"):
        check_workers(other)
    with pytest.raises(ClusterError, match="no worker joined"):
        check_workers(FakeClient({}, {}, joined=False), timeout=0.1)


def test_a_chunk_failing_on_a_worker_keeps_the_finished_chunks_and_a_rerun_resumes(tmp_path, monkeypatch):
    from distributed import Client

    base, _ = load_experiment(CFG)
    exp = sweep_experiment(base, ["k"], None, 3, 15.0, CFG)  # 6 runs, 3 chunks of 2
    reference, _, _ = run_chunked(exp, tmp_path / "local", chunk_size=2)
    real = chunks.run_chunk

    def failing(e, variants, progress=None):
        if variants[0].name == exp.variants[2].name:
            raise MemoryError("worker ran out of memory")
        return real(e, variants, progress)

    target, partial = tmp_path / "dask", tmp_path / ".dask.partial"
    with Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=None) as client:
        monkeypatch.setattr(chunks, "run_chunk", failing)
        with pytest.raises(ClusterError, match=r"chunk 1 failed on a worker \(MemoryError: worker ran out of memory\)"):
            run_chunked(exp, target, chunk_size=2, pool=DaskPool(client))
        assert not (partial / "chunk-0001.csv").exists()
        monkeypatch.setattr(chunks, "run_chunk", real)
        resumed, _, ran = run_chunked(exp, target, chunk_size=2, pool=DaskPool(client))
    assert ran >= 1 and _values(resumed) == _values(reference)
