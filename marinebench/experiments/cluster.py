"""Dask for sweeps that outgrow one process: a ``distributed.Client`` on a local cluster or a running scheduler.

``marinebench sweep ... --dask local`` starts a local cluster of worker processes (one single-threaded
worker per core by default); ``--dask tcp://host:8786`` connects to a scheduler whose workers can import
marinebench. Before anything is submitted, every worker must import marinebench with the same source as
this process (:func:`check_workers`, a digest of the package's files), since chunks are pickled experiments
and "the same numbers as in one process" holds only for the same code. Chunks of the sweep are the unit of
work (``experiments.sweep.run_chunked``); results come back to the client, which writes them, so workers
need no shared file system. Dask is an optional extra: ``pip install -e '.[dask]'``.
"""

from __future__ import annotations

import os
from contextlib import contextmanager
from importlib.metadata import version

from marinebench.errors import ClusterError
from marinebench.provenance import package_digest

WORKER_TRIM_THRESHOLD = 2**30  # bytes; glibc keeps freed memory below this instead of returning it at once


@contextmanager
def dask_client(address: str, workers: int | None = None, timeout: float = 10.0):
    """Yield a ``distributed.Client`` for ``address`` ('local' or a scheduler address, reached within
    ``timeout`` seconds); closed on exit (a local cluster is shut down with it)."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ClusterError("--dask: needs Dask's distributed scheduler: pip install -e '.[dask]'") from None
    if address == "local":
        import dask

        # Dask's workers default to MALLOC_TRIM_THRESHOLD_=65536, which turns the engine's per-step numpy
        # temporaries into mmap/munmap system calls (measured: a chunk 1.5x slower than in this process).
        with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": WORKER_TRIM_THRESHOLD}):
            cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                                   dashboard_address=None)
        client = Client(cluster)
    else:
        cluster = None
        try:
            client = Client(address, timeout=f"{timeout}s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise ClusterError(f"--dask: cannot reach the scheduler at {address!r}: {exc}") from None
    try:
        check_workers(client, timeout)
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def check_workers(client, timeout: float = 10.0) -> None:
    """Refuse a cluster without workers, or whose workers cannot import marinebench or run other code than
    this process. ``importlib.metadata.version`` is sent first because it unpickles on any worker, where a
    marinebench function would not."""
    try:
        client.wait_for_workers(1, timeout=timeout)
    except TimeoutError:
        raise ClusterError(f"--dask: no worker joined the scheduler within {timeout:g} s") from None
    installed = client.run(version, "marinebench", on_error="return")
    missing = sorted(w for w, v in installed.items() if isinstance(v, BaseException))
    if missing:
        raise ClusterError(f"--dask: marinebench is not installed on {len(missing)} of {len(installed)} worker(s) "
                           f"(e.g. {missing[0]}); install this marinebench there")
    mine = package_digest()
    digests = client.run(package_digest, on_error="return")
    differ = sorted(w for w, d in digests.items() if d != mine)
    if differ:
        raise ClusterError(f"--dask: {len(differ)} of {len(digests)} worker(s) run another marinebench source than this "
                           f"process (e.g. {differ[0]}); install the same revision there")


def describe(address: str | None, client) -> str:
    """Where the batches run, for the manifest: this process, or the Dask cluster with its live worker count."""
    if client is None:
        return "this process"
    n = len(client.scheduler_info()["workers"])
    return f"dask local cluster, {n} worker process(es)" if address == "local" else f"dask scheduler {address}, {n} worker(s)"
