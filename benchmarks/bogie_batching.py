"""Bogies batched: does judging several bogies of one sensor layout at once raise the throughput
over judging them one after another (issue 48, item 3)?

Two measurements on the machine's default device, in one process, on the detection benchmark's
cases (`benchmarks/detection.py`, seed 0, default imperfections, two runs of `--duration` s,
the 16 default candidates, run corrections, 0.3 mm record error told to `monitor`):

1. **The monitor's programs vmapped over bogies.** For N = 1, 2, 4 bogies (cases 1..N), the
   residuals (`JointProgram.residuals`' program) and the Jacobian's columns (all of them in one
   block, the small-motion model) of the N bogies as one `jax.vmap`ped program, against the
   one-bogie program evaluated N times. Gain: N times the one-bogie time over the batched time
   (medians of `--repeats`); compile time reported apart. Above 1, a batched program does more
   work per second than the loop.
2. **`monitor` on several bogies side by side.** `--bogies` cases (after one that compiles) one
   at a time, then the same cases two at a time on two threads of one process (the compiled
   programs shared): wall time, process CPU time and the cores kept busy (CPU over wall). The
   loop's cores busy bound what any batching of bogies can gain on this machine: at most the
   core count over them, unless a bogie's own work shrinks.

Run (from the repository root):
    python benchmarks/bogie_batching.py                  # N = 1, 2, 4; 4 bogies side by side
Writes `results/bogie_batching/vmap_and_threads.{json,md}`.
"""

import argparse
import json
import os
import statistics
import time
from concurrent.futures import ThreadPoolExecutor

import equinox as eqx
import jax
import jax.numpy as jnp
from _common import environment, result_path, write_outputs

from bogie_jax.cost import make_joint_objective, residual_jacobian
from bogie_jax.monitor import check_candidates, check_nuisance, monitor


NAME = "bogie_batching/vmap_and_threads"


def case_inputs(count: int, duration: float) -> list[dict]:
    """The detection benchmark's cases 1..count (seed 0, 0.3 mm told)."""
    import detection  # the sibling script: its case generator (it sets its process up)

    args = detection.parse_args(["--duration", f"{duration}", "--track-error", "0.3"])
    cfg = detection.config_of(args)
    return [detection.case_inputs(cfg, i) for i in range(1, count + 1)]


def objectives(case) -> tuple:
    """(residuals' objective, Jacobian's objective) of one case as `monitor` builds them at the
    nominal bogie: the joint objective of its runs over the candidates and nuisance parameters
    (forward mode, run corrections), and the same runs on the small-motion model."""
    o, params = case["options"], case["nominal"]
    names = check_candidates(params, o.candidates)
    names += check_nuisance(params, o.nuisance, names)
    joint = make_joint_objective(
        case["runs"], params, case["tracks"], names, options=o.model,
        settings=o.solve_settings(), weights=o.weights,
    ).forward_mode()  # fmt: skip
    objective = joint.with_run_corrections() if o.run_corrections else joint
    runs_of = (lambda c: c.objective.residual_model) if o.run_corrections else (
        lambda c: c.residual_model
    )  # fmt: skip
    return objective, eqx.tree_at(runs_of, objective, runs_of(objective).with_small_motion())


def _timed(fn, *args, repeats: int) -> tuple[float, float]:
    """(first call [s]: compile and one evaluation, median of `repeats` later calls [s])."""
    t0 = time.perf_counter()
    jax.block_until_ready(fn(*args))
    first = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append(time.perf_counter() - t0)
    return first, statistics.median(times)


def _one_and_batched(objectives, evaluate, repeats: int) -> dict:
    """`evaluate(objective)` of each bogie one after another against all of them vmapped: the
    objectives share one static part (one sensor layout), their arrays stacked."""
    parts = [eqx.partition(o, eqx.is_array) for o in objectives]
    static = parts[0][1]
    if not all(eqx.tree_equal(static, s) for _, s in parts[1:]):
        raise ValueError("the bogies' programs differ in structure: no one batched program")
    one = jax.jit(lambda d: evaluate(eqx.combine(d, static)))
    batched = jax.jit(jax.vmap(lambda d: evaluate(eqx.combine(d, static))))
    stacked = jax.tree.map(lambda *a: jnp.stack(a), *(d for d, _ in parts))
    first_one, t_one = _timed(one, parts[0][0], repeats=repeats)
    t_loop = sum(_timed(one, d, repeats=repeats)[1] for d, _ in parts)
    first_batched, t_batched = _timed(batched, stacked, repeats=repeats)
    n = len(objectives)
    return {
        "bogies": n, "one_s": t_one, "loop_s": t_loop, "batched_s": t_batched,
        "gain": t_loop / t_batched, "compile_one_s": first_one - t_one,
        "compile_batched_s": first_batched - t_batched,
    }  # fmt: skip


def vmap_records(pairs, sizes, repeats: int) -> list[dict]:
    """Part 1 (module docstring) for each N in `sizes`; `pairs`: `objectives` of the cases."""
    n_x = pairs[0][0].n_params
    x = jnp.zeros(n_x)
    directions = jnp.eye(n_x)
    programs_of = {
        "residuals": (0, lambda o: jnp.ravel(o.residuals(x, None))),
        "jacobian": (1, lambda o: residual_jacobian(o, x, None, directions)[1]),
    }
    records = []
    for name, (which, evaluate) in programs_of.items():
        for n in sizes:
            chosen = [pair[which] for pair in pairs[:n]]
            record = {"program": name, **_one_and_batched(chosen, evaluate, repeats)}
            print(record, flush=True)
            records.append(record)
    return records


def side_by_side(inputs) -> list[dict]:
    """Part 2 (module docstring): the first case compiles, the others judged one at a time and
    then two at a time."""

    def judge(case):
        result = monitor(
            case["runs"], case["tracks"], params=case["nominal"], options=case["options"]
        )
        return [v.verdict for v in result.verdicts]

    judge(inputs[0])
    records, verdicts = [], {}
    for mode, workers in (("one at a time", 1), ("two at a time", 2)):
        t0, c0 = time.perf_counter(), time.process_time()
        with ThreadPoolExecutor(workers) as pool:
            verdicts[mode] = list(pool.map(judge, inputs[1:]))
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        records.append({"mode": mode, "bogies": len(inputs) - 1, "wall_s": wall, "cpu_s": cpu})
        print(records[-1], flush=True)
    records[1]["same_verdicts"] = verdicts["one at a time"] == verdicts["two at a time"]
    return records


def markdown(vmapped, threads, duration: float, cores: int) -> str:
    lines = [
        "# Bogies batched: vmapped programs and `monitor` side by side",
        "",
        f"Detection cases (seed 0) with two {duration:g} s runs, 16 candidates, run "
        f"corrections, 0.3 mm record error; {cores} cores.",
        "",
        "**The monitor's programs vmapped over N bogies** (medians; gain: the one-bogie "
        "program N times over the batched one; compile apart):",
        "",
        "| program | N | one bogie [s] | N one after another [s] | N vmapped [s] | gain | "
        "compile vmapped [s] |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in vmapped:
        lines.append(
            f"| {r['program']} | {r['bogies']} | {r['one_s']:.3f} | {r['loop_s']:.3f} | "
            f"{r['batched_s']:.3f} | {r['gain']:.2f}x | {r['compile_batched_s']:.1f} |"
        )
    singles = [r for r in vmapped if r["bogies"] == 1]
    compiled = ", ".join(f"{r['program']} {r['compile_one_s']:.1f} s" for r in singles)
    lines += ["", f"The one-bogie programs' compile: {compiled}."] if singles else []
    lines += [
        "",
        "**`monitor` side by side** (the programs compiled by a first case; process CPU over "
        "wall = cores kept busy):",
        "",
        "| mode | bogies | wall [s] | per bogie [s] | CPU [s] | cores busy |",
        "| --- | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in threads:
        lines.append(
            f"| {r['mode']} | {r['bogies']} | {r['wall_s']:.1f} | "
            f"{r['wall_s'] / r['bogies']:.1f} | {r['cpu_s']:.1f} | "
            f"{r['cpu_s'] / r['wall_s']:.2f} |"
        )
    loop, pair = threads
    n, busy = loop["bogies"], loop["cpu_s"] / loop["wall_s"]
    lines += [
        "",
        f"Throughput two at a time over one at a time: **{loop['wall_s'] / pair['wall_s']:.2f}x** "
        f"(the same verdicts: {pair['same_verdicts']}). The loop keeps {busy:.2f} of {cores} "
        f"cores busy, so busier cores alone gain at most {cores / busy:.2f}x; it spends "
        f"{loop['cpu_s'] / n:.1f} s of CPU a bogie against {pair['cpu_s'] / n:.1f} s two at a "
        "time.",
    ]
    return "\n".join(lines)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--duration", type=float, default=8.0, help="run duration [s] (default 8)")
    p.add_argument("--sizes", default="1,2,4", help="bogies per vmapped program (default 1,2,4)")
    p.add_argument("--bogies", type=int, default=4, help="bogies side by side (default 4)")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--report", action="store_true", help="only rewrite the tables from the JSON")
    args = p.parse_args(argv)
    if args.report:
        return report()
    sizes = tuple(int(s) for s in args.sizes.split(","))
    if min(sizes) < 1 or args.bogies < 2 or args.repeats < 1:
        raise SystemExit("--sizes must be >= 1, --bogies >= 2 and --repeats >= 1")
    os.environ.setdefault("EQX_ON_ERROR", "nan")
    jax.config.update("jax_enable_x64", True)
    inputs = case_inputs(max(max(sizes), args.bogies + 1), args.duration)
    pairs = [objectives(c) for c in inputs[: max(sizes)]]
    vmapped = vmap_records(pairs, sizes, args.repeats)
    threads = side_by_side(inputs[: args.bogies + 1])
    cores = len(os.sched_getaffinity(0))
    config = {"duration_s": args.duration, "sizes": sizes, "repeats": args.repeats}
    write_outputs(
        NAME,
        {"vmapped": vmapped, "side_by_side": threads},
        markdown(vmapped, threads, args.duration, cores),
        extra={"config": config, "cores": cores},
        env=environment(),
    )


def report() -> None:
    """The markdown again from the stored JSON (its environment kept)."""
    stored = json.loads(result_path(NAME, ".json").read_text())
    records, cfg = stored["records"], stored["config"]
    text = markdown(records["vmapped"], records["side_by_side"], cfg["duration_s"], stored["cores"])
    write_outputs(NAME, records, text, extra={"config": cfg, "cores": stored["cores"]},
                  env=stored["environment"])  # fmt: skip


if __name__ == "__main__":
    main()
