"""Where the tasks run: `SerialEngine` (this process, one task after another: the baseline and
the small case) or `DaskEngine` (a Dask cluster: a local one of one worker process (one task
at a time) per two cores by default, each pinned to its cores (`_pinning.py`), or an existing one
by its scheduler address).

Why Dask (`distributed`) and not Ray: its workers are plain long-lived Python processes that
keep whatever a task compiled (our JAX programs) for the next task, which is what a fleet of
bogies of one layout needs; it installs from PyPI as pure Python wheels (no object store or
raylet binaries); a local cluster and a remote one are the same `Client` API; its scheduler
hands a task to whichever worker is free (bogies take different times), and when a worker
process dies its tasks go to another worker, up to a limit, after which the task's future
raises (`KilledWorker`) and the fleet records that bogie-date as failed and goes on.
"""

import logging
from collections.abc import Callable, Iterable, Iterator

from ..runtime.cores import available_cores, core_count
from . import _pinning
from ._task import JudgeTask, Outcome
from ._worker import error_line


CORES_PER_WORKER = 2
"""A local cluster's default: one worker per this many cores. `monitor` keeps two cores busy
itself (a Jacobian's columns in two blocks, the track records' refits two at a time): on a
2-core CPU, two workers of one core each judged 0.65 times as many bogies a minute as one
process (`benchmarks/results/fleet_throughput/serial_vs_dask_two_8s_runs.md`)."""


class EngineError(ValueError):
    """An engine that cannot start (one line)."""


WORKER_ENVIRONMENT = {
    "XLA_FLAGS": "--xla_force_host_platform_device_count=1",
    "EQX_ON_ERROR": "nan",
    "MPLBACKEND": "Agg",
    "OMP_NUM_THREADS": "1",
}
"""Set in each local worker process before it starts (`_worker.prepare_process` sets the same
where JAX is not yet imported, for workers of a remote cluster)."""


class SerialEngine:
    """Every task in this process, in order."""

    name = "serial (this process)"

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def run(self, fn: Callable[[JudgeTask], Outcome], tasks: Iterable[JudgeTask]):
        for task in tasks:
            yield fn(task)


class DaskEngine:
    """A Dask cluster: `address` (`tcp://HOST:8786`) of a running scheduler, or `None` for a
    local cluster of `workers` worker processes, one task at a time each (default: one per
    `CORES_PER_WORKER` cores), each pinned to its share of the cores (`_pinning.py`)."""

    def __init__(self, address: str | None = None, workers: int | None = None):
        if workers is not None and workers < 1:
            raise EngineError(f"`--workers` = {workers!r} must be >= 1")
        self.address, self.workers = address, workers
        self._cluster = self._client = None

    @property
    def name(self) -> str:
        if self.address:
            return f"dask cluster at {self.address}"
        return f"local dask cluster of {self._n_workers()} worker processes"

    def _n_workers(self) -> int:
        if self.workers:
            return self.workers
        return max(1, core_count() // CORES_PER_WORKER)

    def __enter__(self):
        try:
            from distributed import Client, LocalCluster
        except ModuleNotFoundError:
            raise EngineError(
                'the dask engine needs `distributed`: pip install "bogie-jax[fleet]" (or use '
                "--engine serial)"
            ) from None
        try:
            if self.address:
                self._client = Client(self.address, timeout="10s")
            else:
                self._cluster = LocalCluster(
                    n_workers=self._n_workers(), threads_per_worker=1, processes=True,
                    dashboard_address=None, silence_logs=logging.ERROR, env=self._environment(),
                    preload=[_pinning.__name__] if _pinning.can_pin() else [],
                )  # fmt: skip
                self._client = Client(self._cluster)
        except OSError as e:  # no scheduler at the address, a timeout
            self.__exit__(None, None, None)
            raise EngineError(f"cannot reach the dask scheduler {self.address}: {e}") from None
        return self

    def _environment(self) -> dict:
        """`WORKER_ENVIRONMENT` and the cores each worker is pinned to (`_pinning.py`)."""
        if not _pinning.can_pin():
            return WORKER_ENVIRONMENT
        groups = _pinning.core_groups(available_cores(), self._n_workers())
        return {**WORKER_ENVIRONMENT, _pinning.WORKER_CORES: _pinning.encode(groups)}

    def __exit__(self, *exc):
        for thing in (self._client, self._cluster):
            if thing is not None:
                thing.close()
        self._client = self._cluster = None
        return False

    def run(self, fn, tasks) -> Iterator[Outcome]:
        """The tasks' outcomes as they finish (any order); a task whose worker died too often
        comes back as a failed `Outcome`."""
        from distributed import as_completed

        tasks = list(tasks)
        if not tasks:
            return
        futures = self._client.map(fn, tasks, pure=False)
        by_key = {f.key: t for f, t in zip(futures, tasks)}
        for future in as_completed(futures):
            try:
                yield future.result()
            except Exception as e:  # KilledWorker, a task that could not be unpickled, ...
                yield Outcome(by_key[future.key], None, error_line(e), 0.0, "dask")
            future.release()
