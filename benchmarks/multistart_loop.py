"""Diagnostic: the 32 starts of an identification benchmark trial, fitted one after the other.

Same scenario, noise-free data, LHS design and compiled single-start LM program as trial 0 of
`identification.py`; prints one JSON line per start (wall time, LM steps, solver status, worst
relative error against the truth, final cost, start / nominal) and a summary: which starts of a
multistart reach the truth and where the others end.

Run (from the repository root):
`python benchmarks/multistart_loop.py primary6 >
benchmarks/results/multistart_loop/primary6_starts_one_by_one.jsonl`
"""

import json
import sys
import time
from pathlib import Path


sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import benchmarks.identification as bench  # noqa: E402, I001  (first: XLA flags, float64, cache)
import jax  # noqa: E402
import jax.random as jr  # noqa: E402
import numpy as np  # noqa: E402

from bogie_jax.identify import LOCAL_METHODS  # noqa: E402
from bogie_jax.identify import design_starts  # noqa: E402
from bogie_jax.identify import as_problem  # noqa: E402
from bogie_jax.identify import relative_errors, scenario_problem  # noqa: E402


def main(scenario="primary6", starts=32, max_steps=100, duration=0.5, rtol=1e-8):
    key = jr.PRNGKey(7)  # trial 0 of the benchmark
    sp = scenario_problem(scenario, None, duration=duration, rtol=rtol)
    problem = as_problem(sp.objective)
    thetas = design_starts(problem, jr.fold_in(key, 2), starts, "lhs")
    tic = time.perf_counter()
    solve = bench._compiled_local(problem, thetas[0], "lm", max_steps, {})
    print(json.dumps({"compile_s": time.perf_counter() - tic}), flush=True)
    nominal = np.asarray(problem.transform.to_physical(np.zeros(thetas.shape[1])))
    walls = []
    for i, theta in enumerate(thetas):
        tic = time.perf_counter()
        out = jax.block_until_ready(solve(problem, theta, LOCAL_METHODS["lm"], max_steps))
        walls.append(time.perf_counter() - tic)
        est = np.asarray(problem.transform.to_physical(out.theta))
        start = np.asarray(problem.transform.to_physical(theta)) / nominal
        row = dict(
            start=i,
            wall_s=walls[-1],
            steps=int(out.num_steps),
            status=int(out.result),
            max_rel_error=float(relative_errors(est, sp.truth).max()),
            cost=float(problem.cost(out.theta)),
            start_over_nominal=start.round(3).tolist(),
        )
        print(json.dumps(row), flush=True)
    print(json.dumps({"total_s": sum(walls), "median_s": float(np.median(walls))}), flush=True)


if __name__ == "__main__":
    main(*sys.argv[1:2])
