"""Each local Dask worker process on its share of the cores.

XLA's CPU client sizes its thread pool by the cores the process may run on (its CPU affinity,
read when JAX first uses the CPU) and runs one evaluation of a forward-mode solve on one core
while its other threads wait, busy. Unpinned worker processes therefore slow each other down:
one monitor Jacobian (two 8 s runs, one block of columns) took 11.5-12 s in each of two
processes at once on two cores, against 6.7-7.1 s with each process pinned to a core of its
own and 7.8 s in one process alone. A local cluster's workers load this module as a Dask
preload (`dask_setup`, run as each worker starts, a restarted one included, before its first
task): worker `name` k is pinned to group k (modulo their number) of the core groups in
`WORKER_CORES`, which `DaskEngine` sets from its own cores (`core_groups`). Linux only
(`os.sched_setaffinity`); elsewhere the workers are left as they are.
"""

import os


WORKER_CORES = "BOGIE_JAX_WORKER_CORES"  # the workers' core groups, `encode`d


def can_pin() -> bool:
    """Whether this platform lets a process choose its cores (Linux)."""
    return hasattr(os, "sched_setaffinity") and os.path.isdir("/proc/self/task")


def core_groups(available, workers: int) -> list[list[int]]:
    """`available` cores split into `workers` groups of equal size (the last cores left over
    where they do not divide), or one core each, reused in turn, for more workers than cores."""
    available = list(available)
    size = max(1, len(available) // max(workers, 1))
    return [available[(k * size) % len(available) :][:size] for k in range(workers)]


def encode(groups) -> str:
    """`groups` as the value of `WORKER_CORES`: "0,1;2,3"."""
    return ";".join(",".join(str(c) for c in group) for group in groups)


def pin_process(to) -> None:
    """Every thread of this process, and every thread it starts later, on the cores `to`."""
    for tid in os.listdir("/proc/self/task"):
        try:
            os.sched_setaffinity(int(tid), set(to))
        except ProcessLookupError:  # a thread that ended meanwhile
            pass


def dask_setup(worker) -> None:
    """Dask's preload hook: this worker on its cores (module docstring); a worker whose name is
    not a number (not one of a local cluster's) is left as it is."""
    groups = [
        [int(c) for c in group.split(",")]
        for group in os.environ.get(WORKER_CORES, "").split(";")
        if group.strip()
    ]
    try:
        index = int(worker.name)
    except (TypeError, ValueError):
        return
    if can_pin() and groups:
        pin_process(groups[index % len(groups)])
