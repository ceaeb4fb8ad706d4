"""What runs in a worker process (a Dask worker, or this process for `--engine serial`): the
process set up once (before JAX is imported there: one host device, `EQX_ON_ERROR=nan` so that
the programs go to the persistent compilation cache, float64, the cache), then one task at a
time. The compiled programs stay in the process between bogies; every exception of a task
becomes its `Outcome.error`, so one bad bogie never stops the fleet."""

import os
import sys
import time
import traceback

from ._task import JudgeTask, Outcome


def prepare_process(cache_dir: str | None) -> None:
    """Set this process up for judging (idempotent; JAX's settings only where it is not yet
    imported, as in a fresh worker)."""
    if "equinox" not in sys.modules:
        os.environ.setdefault("EQX_ON_ERROR", "nan")
    if "jax" not in sys.modules:
        os.environ["XLA_FLAGS"] = "--xla_force_host_platform_device_count=1"
    os.environ.setdefault("MPLBACKEND", "Agg")
    import jax

    jax.config.update("jax_enable_x64", True)
    if cache_dir is not None:
        from ..runtime.compilation_cache import use_compilation_cache

        use_compilation_cache(cache_dir)


def error_line(e: BaseException) -> str:
    """The exception as one line: its type, message and where it was raised."""
    message = " ".join(str(e).split()) or "(no message)"
    frames = traceback.extract_tb(e.__traceback__)
    where = f" (at {os.path.basename(frames[-1].filename)}:{frames[-1].lineno})" if frames else ""
    return f"{type(e).__name__}: {message}{where}"


def run_task(task: JudgeTask, judge=None) -> Outcome:
    """`judge(task)` (default `_judge.judge_visit`) in this process, as an `Outcome`."""
    prepare_process(task.cache_dir)
    if judge is None:
        from ._judge import judge_visit as judge
    tic = time.perf_counter()
    worker = f"pid {os.getpid()}"
    try:
        record = judge(task)
    except Exception as e:  # recorded as the task's failure; the fleet goes on
        return Outcome(task, None, error_line(e), time.perf_counter() - tic, worker)
    return Outcome(task, record, None, time.perf_counter() - tic, worker)
