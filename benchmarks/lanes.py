"""Fits in flight per device: one lane (stepped without `vmap`) against ceil(32 / (n + 1)).

Each case runs in a fresh process without a compilation cache, set up as the command line sets
up a 2-core CPU (2 devices, float64, `EQX_ON_ERROR=nan`; on a GPU machine its one GPU is the
device): the scenario's noisy data (seed 1, ODE rtol 1e-6, as `bogie-jax identify`), then
`fit_multistart_chunked` (LM, 100 steps, LHS starts, key 0) with the given lanes. It records
the batch's compile time, the fits' wall time, the statistics, the best and median cost and the
failed starts; the two lane counts alternate case by case, so that a drift of the machine falls
on both.

Run (from the repository root): `python benchmarks/lanes.py` (about 10 minutes on 2 cores);
`--cases default:8:4,default:32:32,all10:16:16` (scenario:starts:chunk) and `--name`;
`--render` rewrites `results/lanes/NAME.md` from `results/lanes/NAME.json` (a run copied from
another machine).
"""

import argparse
import json
import math
import os
import subprocess
import sys
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
# before JAX is imported, here and in the children
os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=2")
os.environ.setdefault("EQX_ON_ERROR", "nan")


def _setup_jax() -> None:
    import jax

    jax.config.update("jax_enable_x64", True)


def child(scenario: str, starts: int, chunk: int, lanes: int) -> dict:
    """One case in this (fresh) process; returns its record."""
    _setup_jax()
    import jax.random as jr
    import numpy as np

    from bogie_jax.identify import fit_multistart_chunked, scenario_problem

    problem = scenario_problem(scenario, key=jr.PRNGKey(1), rtol=1e-6)
    run = fit_multistart_chunked(
        problem.objective,
        key=jr.PRNGKey(0),
        n_starts=starts,
        chunk=chunk,
        method="lm",
        max_steps=100,
        lanes=lanes,
    )
    costs = np.asarray(run.result.costs)
    return dict(
        scenario=scenario,
        n_params=len(problem.objective.selection.names),
        starts=starts,
        chunk=chunk,
        lanes=lanes,
        compile_s=run.compile_time,
        fits_s=run.wall_time - run.compile_time - run.statistics_time,
        statistics_s=run.statistics_time,
        best_cost=float(np.min(costs)),
        median_cost=float(np.median(costs)),
        failed=int(np.sum(run.result.failed)),
    )


def markdown(records, env) -> str:
    kind = "CPU" if env["device"] == "cpu" else env["device"]
    lines = [
        "# Fits in flight per device: 1 lane against ceil(32 / (n + 1))",
        "",
        f"{env['n_devices']} {kind} device(s) ({env['platform']}), jax {env['jax']}, commit "
        f"{env['commit']}; each case in a fresh process, no compilation cache; LM, 100 steps, "
        "ODE rtol 1e-6, noisy data (seed 1). Times in seconds.",
        "",
        "| scenario | n | starts | chunk | lanes per device | compile | fits | statistics "
        "| best cost | median cost | failed |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in records:
        lines.append(
            f"| {r['scenario']} | {r['n_params']} | {r['starts']} | {r['chunk']} | {r['lanes']} "
            f"| {r['compile_s']:.1f} | {r['fits_s']:.1f} | {r['statistics_s']:.1f} "
            f"| {r['best_cost']:.4f} | {r['median_cost']:.4f} | {r['failed']} |"
        )
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", default="default:8:4,default:32:32,all10:16:16")
    parser.add_argument("--name", default="one_vs_many_lanes_cpu")
    parser.add_argument("--render", action="store_true", help="NAME.md from NAME.json")
    parser.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.render:
        folder = ROOT / "benchmarks" / "results" / "lanes"
        payload = json.loads((folder / f"{args.name}.json").read_text())
        text = markdown(payload["records"], payload["environment"])
        (folder / f"{args.name}.md").write_text(text)
        print(text)
        return
    if args.child:
        scenario, starts, chunk, lanes = args.child.split(":")
        print(json.dumps(child(scenario, int(starts), int(chunk), int(lanes))))
        return
    _setup_jax()  # the children's devices, for the environment record
    from benchmarks._common import environment, write_outputs
    from bogie_jax.identify import SCENARIOS

    records = []
    for case in args.cases.split(","):
        scenario, starts, chunk = case.split(":")
        n = len(SCENARIOS[scenario].offsets)
        for lanes in (1, max(1, math.ceil(32 / (n + 1)))):
            spec = f"{scenario}:{starts}:{chunk}:{lanes}"
            out = subprocess.run(
                [sys.executable, __file__, "--child", spec],
                capture_output=True,
                text=True,
                check=True,
                cwd=ROOT,
            )
            records.append(json.loads(out.stdout.strip().splitlines()[-1]))
            print(json.dumps(records[-1]), flush=True)
        # written after every case: an interrupted run keeps what it measured
        env = environment()
        write_outputs(f"lanes/{args.name}", records, markdown(records, env), env=env)


if __name__ == "__main__":
    main()
