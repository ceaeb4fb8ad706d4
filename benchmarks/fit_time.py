"""Fit time of `bogie-jax identify`'s batch against its LM steps x one residual + Jacobian.

Issue 15, item 5: per start, the measured fit time should be within 1.5x of (LM steps x
(residual + Jacobian) time measured alone). One process, set up as the command line sets up a
2-core CPU (2 devices, float64, `EQX_ON_ERROR=nan`): the default scenario's data (noise seed 1,
ODE rtol 1e-6), `fit_multistart_chunked` with identify's defaults (8 LHS starts, key 0, LM,
100 steps, chunks of 2 per device, `lanes="auto"`), then the residuals and their forward-mode
Jacobian at each start's end, compiled alone (`residual_jacobian`, one device) and timed as the
median of 5 calls. A fit evaluates the residuals and the Jacobian once at its start and once per
step, at its trial point (`num_fn_evals`); each LM iteration evaluates every lane's fit at once
(one lane per device), and a lane whose fit has ended takes the chunk's next start. So a chunk's
predicted time is its queue's iterations (`queue_iterations`) x the evaluation time. The queue
does not time its starts one by one, so the check is per chunk.

Run (from the repository root): `python benchmarks/fit_time.py` (about 2 minutes on 2 cores).
"""

import os
import sys
from pathlib import Path


sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=2")
os.environ.setdefault("EQX_ON_ERROR", "nan")
import jax  # noqa: E402


jax.config.update("jax_enable_x64", True)
import equinox as eqx  # noqa: E402
import jax.random as jr  # noqa: E402
import numpy as np  # noqa: E402

from benchmarks._common import median_time, write_outputs  # noqa: E402
from bogie_jax.cost import residual_jacobian  # noqa: E402
from bogie_jax.identify import (  # noqa: E402
    default_chunk,
    fit_multistart_chunked,
    queue_lanes,
    scenario_problem,
)


N_STARTS = 8


def queue_iterations(evaluations, lanes: int) -> int:
    """Iterations of the LM's queue over fits of `evaluations` each, in order: a fit takes the
    lane that frees first (the lowest-numbered among equal ones)."""
    load = [0] * lanes
    for e in evaluations:
        load[int(np.argmin(load))] += int(e)
    return max(load)


def main() -> None:
    problem = scenario_problem("default", key=jr.PRNGKey(1), rtol=1e-6)
    objective = problem.objective
    chunk = default_chunk("auto", objective.selection.n_params)  # identify's default
    chunk_times = []

    def on_chunk(progress):
        chunk_times.append(progress.run_time)

    run = fit_multistart_chunked(
        objective,
        key=jr.PRNGKey(0),
        n_starts=N_STARTS,
        chunk=chunk,
        max_steps=100,
        on_chunk=on_chunk,
    )
    records = run.result.records()
    steps = np.array([r["num_steps"] for r in records])
    evaluations = np.array([r["num_fn_evals"] for r in records])
    evaluate = eqx.filter_jit(residual_jacobian)
    ends = np.asarray(jax.vmap(objective.selection.to_theta)(run.result.ends))
    jax.block_until_ready(evaluate(objective, ends[0]))  # compile
    eval_times = [
        median_time(lambda: jax.block_until_ready(evaluate(objective, e)))[0] for e in ends
    ]
    per_eval = float(np.median(eval_times))
    rows = []
    measured_chunks = np.diff([0.0, *chunk_times])
    lanes = queue_lanes("auto", objective.selection.n_params) * jax.device_count()
    for k, measured in enumerate(measured_chunks):
        idx = np.arange(k * chunk, min((k + 1) * chunk, N_STARTS))
        iterations = queue_iterations(evaluations[idx], lanes)
        predicted = iterations * per_eval
        rows.append(
            dict(
                chunk=k,
                starts=idx.tolist(),
                steps=steps[idx].tolist(),
                evaluations=evaluations[idx].tolist(),
                iterations=iterations,
                predicted_s=predicted,
                measured_s=float(measured),
                ratio=float(measured / predicted),
            )
        )
    lines = [
        "# Fit time against LM steps x (residual + Jacobian) (issue 15, item 5)",
        "",
        f"{jax.device_count()} CPU devices, default scenario, {N_STARTS} starts in chunks of "
        f'{chunk}, `lanes="auto"`; one residual + Jacobian evaluation alone: median '
        f"{per_eval:.3f} s (per end point {min(eval_times):.3f}-{max(eval_times):.3f} s).",
        "",
        "| chunk | starts | LM steps | evaluations | queue iterations | predicted s | measured s "
        "| ratio |",
        "| ---: | --- | --- | --- | ---: | ---: | ---: | ---: |",
    ]
    for r in rows:
        lines.append(
            f"| {r['chunk']} | {r['starts']} | {r['steps']} | {r['evaluations']} "
            f"| {r['iterations']} "
            f"| {r['predicted_s']:.2f} | {r['measured_s']:.2f} | {r['ratio']:.2f} |"
        )
    total_pred = sum(r["predicted_s"] for r in rows)
    total = sum(r["measured_s"] for r in rows)
    lines += ["", f"All chunks: predicted {total_pred:.2f} s, measured {total:.2f} s, "
              f"ratio {total / total_pred:.2f}."]  # fmt: skip
    extra = dict(
        per_eval_s=per_eval, eval_times_s=eval_times, steps=steps.tolist(),
        evaluations=evaluations.tolist(),
    )  # fmt: skip
    write_outputs("fit_time/fit_vs_steps_x_evaluation", rows, "\n".join(lines) + "\n", extra=extra)


if __name__ == "__main__":
    main()
