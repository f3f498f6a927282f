"""Studies on Dask: an existing distributed cluster (``tcp://HOST:PORT``) or a LocalCluster.

Batches are the tasks (never single solves): the :class:`~.runners.StudyTask` is scattered
to every worker once, each batch is one ``solve_batch`` call, and a worker builds the
designer once per task (CasADi SX objects do not pickle, so workers rebuild from the
description). Results come back in batch order, so the study file is the same as with
the local engines. Workers of an existing cluster need counterpoise installed (the same
version) in their environment.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

from ..errors import CounterpoiseError
from .runners import Point, PointResult, StudyTask, _single_threaded, solve_batch

HOW_TO_START = (
    "start one with `dask scheduler` (it prints its address, tcp://HOST:8786) and at least one "
    "`dask worker tcp://HOST:8786` where counterpoise is installed, or use --scheduler local"
)


#: environment of LocalCluster workers: Dask's defaults without MALLOC_TRIM_THRESHOLD_ (see
#: :meth:`DaskRunner._client`); the workers then apply :data:`~.runners.MALLOC_SETTINGS`
WORKER_ENVIRON = {"OMP_NUM_THREADS": 1, "MKL_NUM_THREADS": 1, "OPENBLAS_NUM_THREADS": 1}


#: address schemes that need certificates (Dask's ``distributed.comm.tls`` configuration)
SECURE_SCHEMES = ("tls", "wss")
TLS_KEYS = "distributed.comm.tls.ca-file, distributed.comm.tls.client.cert and .key"
#: longest piece of a Dask error repeated in a message
REASON_LIMIT = 200


def _reason(exc: BaseException) -> str:
    return (" ".join(str(exc).split()) or type(exc).__name__)[:REASON_LIMIT]


class SchedulerError(CounterpoiseError):
    """The Dask scheduler cannot be reached (or Dask is not installed)."""


class DaskRunner:
    """Runs batches as Dask tasks on ``scheduler`` (an address, or ``local`` for a LocalCluster
    of ``jobs`` single-threaded worker processes)."""

    def __init__(self, scheduler: str, jobs: int | None = None, timeout: float = 10.0) -> None:
        self.scheduler = scheduler
        self.jobs = jobs
        self.timeout = timeout
        self._connection: tuple[Any, Any] | None = None

    def connect(self) -> None:
        """Connect now (a LocalCluster starts here): an unreachable scheduler fails before any work."""
        if self._connection is None:
            self._connection = self._client()

    def close(self) -> None:
        if self._connection is not None:
            client, cluster = self._connection
            self._connection = None
            client.close()
            if cluster is not None:
                cluster.close()

    def _client(self) -> tuple[Any, Any]:  # Any: distributed's Client and LocalCluster (or None), imported here only
        try:
            from distributed import Client, LocalCluster
        except ImportError as exc:  # pragma: no cover - a dependency
            raise SchedulerError(f"Dask is not installed ({exc}); pip install 'dask[distributed]'") from None
        if self.scheduler == "local":
            import os

            import dask

            n = self.jobs or os.cpu_count() or 1
            # Dask sets MALLOC_TRIM_THRESHOLD_ in its workers; setting it switches off glibc's
            # dynamic mmap threshold, so every large numpy buffer of the verification is
            # mmapped and unmapped again: a worker spent most of its time in page faults (3x
            # slower). The workers live as long as the study: keep glibc's defaults.
            with dask.config.set({"distributed.nanny.pre-spawn-environ": WORKER_ENVIRON}):
                cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None)
            return Client(cluster), cluster
        scheme = self.scheduler.partition("://")[0].lower()
        try:
            return Client(self.scheduler, timeout=f"{self.timeout}s"), None
        except TypeError as exc:  # Dask's connectors raise TypeError for a comm they cannot set up
            if scheme in SECURE_SCHEMES:
                raise SchedulerError(f"cannot connect to {self.scheduler}: {scheme}:// needs the Dask TLS configuration ({TLS_KEYS}), and none is set; or use tcp://") from None
            raise SchedulerError(f"cannot connect to {self.scheduler}: Dask cannot use {scheme}:// here ({_reason(exc)}); use tcp://") from None
        except (OSError, TimeoutError, ValueError, ImportError, RuntimeError) as exc:
            raise SchedulerError(f"cannot reach the Dask scheduler at {self.scheduler} ({_reason(exc)}); {HOW_TO_START}") from None

    def map_batches(self, task: StudyTask, batches: Sequence[Sequence[Point]]) -> Iterator[list[PointResult]]:
        owned = self._connection is None
        self.connect()
        client = self._connection[0]  # type: ignore[index]  # connect() has set it
        try:
            client.run(_single_threaded)
            shared = client.scatter(task, broadcast=True)
            futures = [client.submit(solve_batch, shared, list(batch), pure=False) for batch in batches]
            for future in futures:
                yield future.result()
        finally:
            if owned:
                self.close()
