"""Where a sweep's batches run: in this process, side by side in local worker processes, or on Dask.

Chunks of the sweep are the unit of work (``experiments.chunks.run_chunked``); results come back to this
process, which writes them, so an interrupted sweep resumes the same way wherever its chunks ran, and runs
are seeded per run, so the numbers do not depend on where or in which batch a run was simulated.

- :class:`LocalPool` (``marinebench sweep --jobs N``, by default one process per core; ``run`` puts whole
  experiments on it the same way): worker processes
  forked from this one, so they share its imported modules and need nothing installed or pickled but the
  chunk. The engine is one single-threaded Python loop over time, so a sweep of several batches on a
  2-core machine takes the longest batch's time instead of their sum.
- :class:`DaskPool` (``--dask local`` or ``--dask tcp://host:8786``): a ``distributed.Client`` on a local
  cluster or a running scheduler whose workers can import marinebench. Before anything is submitted, every
  worker must import marinebench with the same source as this process (:func:`check_workers`, a digest of
  the package's files), since chunks are pickled experiments and "the same numbers as in one process" holds
  only for the same code. Dask is an optional extra: ``pip install -e '.[dask]'``.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import signal
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from contextlib import contextmanager
from importlib.metadata import version

from marinebench.errors import ClusterError
from marinebench.provenance import package_digest

WORKER_TRIM_THRESHOLD = 2**30  # bytes; glibc keeps freed memory below this instead of returning it at once
POLL_S = 0.25  # how often the progress bar hears from local workers
PARENT_POLL_S = 0.5  # how often a local worker checks that the process that made its pool is still there


def available_cores() -> int:
    """CPU cores this process may run on (its affinity mask where the OS has one)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


class ChunkFailed(Exception):
    """A chunk raised on a worker (or its worker died): ``chunk`` is its index, ``cause`` what it raised."""

    def __init__(self, chunk: int, cause: BaseException) -> None:
        super().__init__(chunk, cause)
        self.chunk, self.cause = chunk, cause


_steps = None  # in a LocalPool worker: the pool's shared count of simulated steps


def _exit_with(parent: int) -> None:
    """End this worker as soon as ``parent``, the process that made its pool, is gone (``kill -9``, the OOM
    killer): the results come back to the parent, so nothing is lost, and an orphan would otherwise finish its
    chunk for nobody and then wait on the pool's queue for ever."""
    while os.getppid() == parent:
        time.sleep(PARENT_POLL_S)
    os._exit(1)


def _init_worker(counter, parent: int) -> None:
    from threadpoolctl import threadpool_limits

    global _steps
    _steps = counter
    threading.Thread(target=_exit_with, args=(parent,), name="exit-with-parent", daemon=True).start()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the whole process group: the parent stops us
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # not the CLI's handler (forked): the parent's terminate() ends us
    # One BLAS thread per worker, as Dask's and joblib's workers have: the workers fill the cores already, and
    # BLAS threads that outnumber the cores spin-wait against each other.
    threadpool_limits(1)


def _count(k: int) -> None:
    with _steps.get_lock():
        _steps.value += k


def _in_worker(fn: Callable, args: tuple):
    return fn(*args, progress=_count)


class LocalPool:
    """Chunks side by side in ``workers`` processes on this machine.

    The workers are forked when the pool is made (where the OS can fork; elsewhere they start afresh and
    import marinebench), so make it before starting threads such as a progress bar: a forked child would
    inherit any lock another thread held. They report simulated steps through a shared counter, so the
    progress bar moves while the chunks run, not only when one finishes.
    """

    option = "--jobs"

    def __init__(self, workers: int) -> None:
        ctx = multiprocessing.get_context("fork" if sys.platform == "linux" else None)
        self.workers = workers
        self.steps = ctx.Value("q", 0)
        self.pool = ProcessPoolExecutor(workers, mp_context=ctx, initializer=_init_worker,
                                        initargs=(self.steps, os.getpid()))
        self.pool.submit(int).result()  # start every worker now (fork launches them all on the first task)

    def describe(self) -> str:
        return f"{self.workers} local worker process(es)"

    def results(self, fn: Callable, tasks: dict[int, tuple], progress=None, task_steps: dict[int, int] | None = None,
                name: str = "") -> Iterator[tuple[int, object]]:
        """``(task, fn(*args))`` as the tasks finish; :class:`ChunkFailed` for the first that raises."""
        futures = {self.pool.submit(_in_worker, fn, args): c for c, args in tasks.items()}
        pending, reported = set(futures), 0
        while pending:
            done, pending = wait(pending, timeout=POLL_S, return_when=FIRST_COMPLETED)
            if progress is not None:
                now = self.steps.value
                progress(now - reported)
                reported = now
            failed = [f for f in done if f.exception() is not None]  # whatever a chunk raised, or BrokenProcessPool
            for future in done.difference(failed):  # first: a chunk that finished beside a failed one is kept
                yield futures[future], future.result()
            if failed:
                for other in pending:
                    other.cancel()
                first = min(failed, key=futures.__getitem__)
                raise ChunkFailed(futures[first], first.exception())

    def close(self, abort: bool = False) -> None:
        """Shut the workers down; ``abort``: stop the chunks they are running instead of waiting for them."""
        if abort:
            stop = getattr(self.pool, "terminate_workers", None)  # Python >= 3.14
            if stop is not None:
                stop()
            else:
                for process in list((self.pool._processes or {}).values()):
                    process.terminate()
        self.pool.shutdown(wait=True, cancel_futures=True)


@contextmanager
def local_pool(workers: int):
    """Yield a :class:`LocalPool` of ``workers`` processes, shut down on exit; on an error or Ctrl-C the
    running chunks are stopped at once (the finished ones are already saved, so a rerun resumes)."""
    pool = LocalPool(workers)
    try:
        yield pool
    except BaseException:
        pool.close(abort=True)
        raise
    pool.close()


class DaskPool:
    """Chunks submitted at once to a Dask ``client``'s workers; each comes back as it finishes."""

    option = "--dask"

    def __init__(self, client, address: str = "local") -> None:
        self.client, self.address = client, address

    def describe(self) -> str:
        n = len(self.client.scheduler_info()["workers"])
        return (f"dask local cluster, {n} worker process(es)" if self.address == "local"
                else f"dask scheduler {self.address}, {n} worker(s)")

    def results(self, fn: Callable, tasks: dict[int, tuple], progress=None, task_steps: dict[int, int] | None = None,
                name: str = "task") -> Iterator[tuple[int, object]]:
        from distributed import as_completed

        # Readable task names, unique per attempt: a chunk cancelled by a failed attempt must not be reused.
        attempt = uuid.uuid4().hex[:8]
        futures = {self.client.submit(fn, *args, key=f"marinebench-{name}-chunk-{c:04d}-{attempt}"): c
                   for c, args in tasks.items()}
        for future in as_completed(futures):
            try:
                value = future.result()
            except Exception as exc:  # noqa: BLE001 -- whatever a worker raised
                self.client.cancel(list(futures))
                raise ChunkFailed(futures[future], exc) from None
            if progress is not None:
                progress((task_steps or {}).get(futures[future], 0))
            yield futures[future], value


@contextmanager
def dask_pool(address: str, workers: int | None = None, timeout: float = 10.0):
    """Yield a :class:`DaskPool` on a ``distributed.Client`` for ``address`` ('local' or a scheduler address,
    reached within ``timeout`` seconds); closed on exit (a local cluster is shut down with it)."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ClusterError("--dask: needs Dask's distributed scheduler: pip install -e '.[dask]'") from None
    if address == "local":
        import dask

        # Dask's workers default to MALLOC_TRIM_THRESHOLD_=65536, which turns the engine's per-step numpy
        # temporaries into mmap/munmap system calls (measured: a chunk 1.5x slower than in this process).
        # And their statistical profiler samples the task thread's stack every 10 ms under the GIL (measured:
        # two 300-run chunks side by side 1.7x slower than in one process with it, 1.2x without).
        with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": WORKER_TRIM_THRESHOLD,
                              "distributed.worker.profile.enabled": False}):
            # silence_logs: a chunk that raises is reported by this process in one line (ChunkFailed); its worker
            # would log it too, with its traceback, and the chunks cancelled after it as warnings.
            cluster = LocalCluster(n_workers=workers or available_cores(), threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.CRITICAL)
        client = Client(cluster)
    else:
        cluster = None
        try:
            client = Client(address, timeout=f"{timeout}s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise ClusterError(f"--dask: cannot reach the scheduler at {address!r}: {exc}") from None
    try:
        check_workers(client, timeout)
        yield DaskPool(client, address)
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
