"""Timing, accuracy and memory of every gradient method on the user's own objective.

The harness behind `bogie-jax gradcheck` and `benchmarks/gradients.py`: each method's gradient is
timed against one forward solve (the compiled residuals) measured right before it, compared with
a tight-tolerance forward-mode reference, and sized by XLA's compiled memory analysis.
"""

import statistics
import time

import jax
import jax.numpy as jnp
import numpy as np

from ..cost import Objective
from ._methods import (
    METHODS,
    compiled_jacobian,
    compiled_residuals,
    gradient,
    reference_gradient,
    residuals_and_pullback,
    resolve_method,
)


def timed(fn) -> float:
    t = time.perf_counter()
    jax.block_until_ready(fn())
    return time.perf_counter() - t


def median_time(fn, repeats: int) -> tuple[float, float]:
    """(time of the first call, median of `repeats` further calls) [s]."""
    first = timed(fn)
    return first, statistics.median(timed(fn) for _ in range(repeats))


def _paired_times(fn, solve, repeats: int) -> tuple[float, float, float]:
    """(first call, median time, median of time / adjacent forward-solve time): each timed call
    is paired with a solve timed right before it, so load drift on a shared machine cancels."""
    first = timed(fn)
    pairs = [(timed(solve), timed(fn)) for _ in range(repeats)]
    return first, statistics.median(g for _, g in pairs), statistics.median(g / s for s, g in pairs)


def _peak_bytes(jitted, *args) -> int:
    """XLA's compiled memory analysis of `jitted(*args)`: arguments + outputs + temporaries."""
    stats = jitted.lower(*args).compile().compiled.memory_analysis()
    peak = getattr(stats, "peak_memory_in_bytes", 0)
    total = stats.argument_size_in_bytes + stats.output_size_in_bytes + stats.temp_size_in_bytes
    return int(max(peak, total - stats.alias_size_in_bytes))


def _core_memory(objective, theta, adjoint, mode) -> int:
    if mode == "fd":
        return _peak_bytes(compiled_residuals, objective, theta)
    objective = objective.with_adjoint(adjoint)
    if mode == "fwd":
        return _peak_bytes(compiled_jacobian, objective, theta)
    return _peak_bytes(
        residuals_and_pullback, objective, theta, jnp.zeros(objective.n_residuals), 1.0
    )


def gradient_report(
    objective: Objective, theta, *, methods=METHODS, repeats: int = 5, reference=None
) -> list[dict]:
    """Time, accuracy and memory of each gradient method on `objective` at `theta`.

    One record per method: `method`, `mode`, `n_params`, `time_s` (median of `repeats` calls
    after a first, compiling call), `time_ratio` (median over the calls of the time over that of
    one forward solve, the compiled residuals, timed right before each call), `compile_s` (first
    call minus median), `rel_error`
    (|g - g_ref| / |g_ref|, 2-norms, against `reference` or `reference_gradient`),
    `peak_memory_mb` (XLA's compiled memory analysis of the method's main compiled function:
    arguments + outputs + temporaries; finite differences: that of the residuals), `grad`.
    """
    theta = jnp.asarray(theta, dtype=float)
    g_ref = np.asarray(reference_gradient(objective, theta) if reference is None else reference)
    solve = lambda: compiled_residuals(objective, theta)
    solve_first, solve_time = median_time(solve, repeats)
    records = [
        dict(
            method="forward-solve",
            mode="-",
            n_params=int(theta.size),
            time_s=solve_time,
            time_ratio=1.0,
            compile_s=solve_first - solve_time,
            rel_error=0.0,
            peak_memory_mb=_core_memory(objective, theta, None, "fd") / 2**20,
            grad=None,
        )
    ]
    for method in methods:
        settings = objective.settings
        name, adjoint, mode = resolve_method(
            method, None, settings.max_steps, settings.stepsize_controller
        )
        call = lambda: gradient(objective, theta, method=method).grad
        first, t, ratio = _paired_times(call, solve, repeats)
        g = np.asarray(call())
        records.append(
            dict(
                method=name,
                mode=mode,
                n_params=int(theta.size),
                time_s=t,
                time_ratio=ratio,
                compile_s=max(first - t, 0.0),
                rel_error=float(np.linalg.norm(g - g_ref) / np.linalg.norm(g_ref)),
                peak_memory_mb=_core_memory(objective, theta, adjoint, mode) / 2**20,
                grad=[float(x) for x in g],
            )
        )
    return records


def report_table(records) -> str:
    """A markdown table of `gradient_report` records."""
    lines = [
        "| method | mode | n | time / forward solve | time [ms] | compile [s] | rel. error "
        "| peak memory [MB] |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in records:
        lines.append(
            f"| {r['method']} | {r['mode']} | {r['n_params']} | {r['time_ratio']:.2f} | "
            f"{1e3 * r['time_s']:.1f} | {r['compile_s']:.1f} | {r['rel_error']:.1e} | "
            f"{r['peak_memory_mb']:.1f} |"
        )
    return "\n".join(lines)
