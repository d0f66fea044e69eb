"""Execute a study's independent runs serially or on a Dask cluster.

A task is a module-level function and its keyword arguments (picklable: scene names, integrator
names, numbers), so the same call runs in this process or on any Dask worker. Results come back
in the order the tasks were given, whichever way they ran.

The default cluster is a :class:`distributed.LocalCluster` with one *single-threaded worker
process per core*: no two runs share a core through threads, which keeps the per-run wall-clock
times of the cost study honest (see :mod:`thermonet.studies.cost` for the rest of that story).
With ``scheduler="tcp://host:8786"`` the same tasks go to an existing cluster instead.
"""

from __future__ import annotations

import os
from typing import Callable, Iterable, Mapping


class Runner:
    """Runs tasks; use as a context manager (it owns the cluster it starts).

    serial: run in this process, one task after another (no Dask needed).
    scheduler: address of an existing Dask scheduler; default: start a local cluster.
    n_workers: worker processes of the local cluster (default: one per core).
    client: an existing ``distributed.Client`` to use (e.g. a test's shared cluster).
    """

    def __init__(self, serial: bool = False, scheduler: str | None = None, n_workers: int | None = None,
                 client=None):
        self.serial = serial and client is None
        self.scheduler = scheduler
        self.n_workers = n_workers or os.cpu_count() or 1
        self._client = client
        self._owned: list = []
        self._cluster = None  # the local cluster this runner started, if any

    # -- lifecycle ---------------------------------------------------------------------------
    def __enter__(self) -> "Runner":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Close the client and cluster this runner started (never a client it was given).

        A local cluster's logs are silenced while it closes: every result is in by then, and a
        worker whose periodic heartbeat meets the scheduler already gone (a race in closing a
        cluster on a loaded machine) logs an error with a traceback that a user would take for
        a failed study. Errors of the runs themselves reach the caller through their results.
        """
        import logging

        ours = logging.getLogger("distributed")  # the nannies live in this process
        level = ours.level
        if self._cluster is not None:
            self._silence_workers()
            _silence_distributed_logs()
        try:
            for thing in reversed(self._owned):
                thing.close()
        finally:
            ours.setLevel(level)
        if self._owned:
            self._client = None
        self._owned.clear()
        self._cluster = None

    def _silence_workers(self) -> None:
        try:
            self._client.run(_silence_distributed_logs)
        except Exception:  # a worker already gone has nothing left to log
            pass

    @property
    def client(self):
        """The Dask client, started on first use (None when serial)."""
        if self.serial:
            return None
        if self._client is None:
            from distributed import Client, LocalCluster

            if self.scheduler:
                self._client = Client(self.scheduler)
                self._owned.append(self._client)
            else:
                cluster = LocalCluster(n_workers=self.n_workers, threads_per_worker=1, processes=True,
                                       # (its HTTP server on any free port: two studies at once
                                       # do not contend for 8787)
                                       dashboard_address=":0",
                                       # one numba/BLAS thread per worker: one core per run
                                       env={"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
                                            "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"})
                self._client = Client(cluster)
                self._owned += [cluster, self._client]
                self._cluster = cluster
        return self._client

    @property
    def description(self) -> str:
        if self.serial:
            return "serial (this process)"
        c = self.client
        workers = c.scheduler_info().get("workers", {})
        threads = sum(w.get("nthreads", 0) for w in workers.values())
        return f"dask at {c.scheduler.address} ({len(workers)} workers, {threads} threads)"

    # -- running -----------------------------------------------------------------------------
    def map(self, function: Callable, tasks: Iterable[Mapping], **options) -> list:
        """``[function(**kw) for kw in tasks]``; see :meth:`run`."""
        return self.run([(function, kw) for kw in tasks], **options)

    def run(self, calls: Iterable[tuple[Callable, Mapping]], one_at_a_time: bool = False,
            progress: Callable[[int, int], None] | None = None) -> list:
        """``[function(**kw) for function, kw in calls]``, serially or on the cluster, results in
        call order.

        one_at_a_time: on a cluster, submit each call only when the previous one has finished,
        so that no two runs ever execute together (for timings on a shared machine).
        """
        calls = [(fn, dict(kw)) for fn, kw in calls]
        total = len(calls)
        if self.serial or one_at_a_time:
            out = []
            for i, (fn, kw) in enumerate(calls):
                out.append(fn(**kw) if self.serial else self.client.submit(fn, pure=False, **kw).result())
                if progress:
                    progress(i + 1, total)
            return out
        from distributed import as_completed

        client = self.client
        # pure=False: identical arguments are separate runs (timing repeats must not be merged)
        futures = [client.submit(fn, pure=False, **kw) for fn, kw in calls]
        index = {f.key: i for i, f in enumerate(futures)}
        out: list = [None] * total
        for done, future in enumerate(as_completed(futures), 1):
            out[index[future.key]] = future.result()
            if progress:
                progress(done, total)
        return out


def _silence_distributed_logs() -> None:
    import logging

    logging.getLogger("distributed").setLevel(logging.CRITICAL)
