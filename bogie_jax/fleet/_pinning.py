"""One core per local Dask worker process.

XLA's CPU client sizes its thread pool by the cores the process may run on (its CPU affinity,
read when JAX first uses the CPU) and runs one evaluation of a forward-mode solve on one core
while its other threads wait, busy. Two unpinned worker processes on two cores therefore
slow each other down: one monitor Jacobian (two 8 s runs) took 11.5-12 s in each of two
processes at once, against 6.7-7.1 s with each process pinned to a core of its own and 7.8 s in
one process alone. A local cluster's workers load this module as a Dask preload
(`dask_setup`, run as each worker starts, a restarted one included, before its first task):
worker `name` k goes on core k modulo the cores in `WORKER_CORES` (the parent's). Linux only
(`os.sched_setaffinity`); elsewhere the workers are left as they are.
"""

import os


WORKER_CORES = "BOGIE_JAX_WORKER_CORES"  # comma-separated core numbers, set by `DaskEngine`


def can_pin() -> bool:
    """Whether this platform lets a process choose its cores (Linux)."""
    return hasattr(os, "sched_setaffinity") and os.path.isdir("/proc/self/task")


def pin_process(core: int) -> None:
    """Every thread of this process, and every thread it starts later, on `core`."""
    for tid in os.listdir("/proc/self/task"):
        try:
            os.sched_setaffinity(int(tid), {core})
        except ProcessLookupError:  # a thread that ended meanwhile
            pass


def dask_setup(worker) -> None:
    """Dask's preload hook: this worker on its core (module docstring); a worker whose name is
    not a number (not one of a local cluster's) is left as it is."""
    cores = [int(c) for c in os.environ.get(WORKER_CORES, "").split(",") if c.strip()]
    try:
        index = int(worker.name)
    except (TypeError, ValueError):
        return
    if can_pin() and cores:
        pin_process(cores[index % len(cores)])
