"""The CPU cores this process may run on: its affinity where the OS tells it (Linux), else
every core the machine has. Imports only the standard library, so that the command line can use
it before JAX is loaded."""

import os


def available_cores() -> list[int]:
    """The cores this process may run on, in order."""
    if hasattr(os, "sched_getaffinity"):
        return sorted(os.sched_getaffinity(0))
    return list(range(os.cpu_count() or 1))


def core_count() -> int:
    """How many cores this process may run on (at least 1)."""
    return max(1, len(available_cores()))
