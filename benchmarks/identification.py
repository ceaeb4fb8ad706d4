# long: one driver for every method, scenario and table of the identification study;
# its parts share the run records.
"""Identification benchmark (issue 4, item 7).

Scenarios with 3, 6 and 10 selected parameters (`primary3`, `primary6`, `all10` of
`bogie_jax.identify._scenarios`: Manchester bogie, true values offset 10-15 % from nominal, search
inside the +-50 % tolerance band), noise-free and with 2 % noise (Gaussian, standard deviation 2 %
of each channel's RMS, weighted by its inverse variance). Per trial (new noise and a new start
design per trial) and method:

- success: every selected parameter within 1 % of the truth (noise-free), or every truth inside
  its reported 95 % interval (noisy; for simulated annealing the interval is computed at its
  best point by the same Gauss-Newton statistics);
- global: the final cost within 1e-2 (in noise variances) + 1e-6 relative of the lowest cost
  any method reached in that trial;
- forward solves (cost/residual evaluations; for the least-squares methods each also carries the
  forward-mode Jacobian) and wall time (after compilation).

Methods: single-start LM (from the nominal values), multistart LM (`--starts`, LHS design, one
batch sharded over the 2 CPU devices: a queue with `--lanes` fits in flight per device,
or `--lanes 0` every start at once in lock-step), BFGS and Nelder-Mead and pattern search (from the
nominal values), simulated annealing (one chain of `--sa-iter` evaluations from the nominal
values) and the hybrid (`--hybrid-chains` annealing chains of `--hybrid-iter`, then LM from each
best point). Finally the batched multistart against a Python loop of the same fits (same starts).

The batched fits take the objective as a (broadcast) batch input rather than a closure, so one
compilation serves every trial of a scenario.

Run: `python benchmarks/identification.py [--trials 20] [--duration S] [--scenarios primary3,...]`
(writes results/identification/NAME.json and .md; NAME: `--name`, default `every_method`).
"""

import os


os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=2")
# Runtime checks become NaNs rather than host callbacks, so the persistent compilation cache
# below keeps every program and a re-run (or a run resumed after an interruption) skips
# compiling; failures still show, as a non-successful solver status or a non-finite cost.
os.environ.setdefault("EQX_ON_ERROR", "nan")

import argparse
import sys
import time
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)
# Compiled programs are kept in the repository's (git-ignored) cache directory.
jax.config.update(
    "jax_compilation_cache_dir", str(Path(__file__).resolve().parents[1] / ".jax_cache")
)
jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)

import equinox as eqx
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from bogie_jax.identify import (
    LOCAL_METHODS,
    BatchedFits,
    SimulatedAnnealing,
    anneal_start,
    anneal_steps,
    as_problem,
    batched_fits,
    design_starts,
    relative_errors,
    scenario_problem,
    stack_objectives,
    start_theta,
    statistics,
    supports_queue,
)


sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks._common import RESULTS, write_outputs  # noqa: E402


METHODS = ("lm", "multistart-lm", "bfgs", "nelder-mead", "pattern", "annealing", "hybrid")


_stats = eqx.filter_jit(statistics)


def _summary(problem, theta, fevs, jevs, wall, truth, noisy):
    # on the host first: a member of a sharded batch output would recompile the statistics
    s = _stats(problem, jnp.asarray(np.asarray(theta)), 1e-6)
    est = np.asarray(s["estimates"])
    ci = np.asarray(s["ci95"])
    inside = bool(np.all((ci[:, 0] <= truth) & (truth <= ci[:, 1])))
    rel = relative_errors(est, truth)
    return dict(
        cost=float(s["cost"]),
        max_rel_error=float(rel.max()),
        success=inside if noisy else bool(rel.max() < 0.01),
        inside_ci=inside,
        forward_solves=int(fevs),
        jacobians=int(jevs),
        # a forward-mode Jacobian carries n tangents: count it as n more solves
        solve_equivalents=int(fevs) + truth.size * int(jevs),
        wall_time=float(wall),
    )


def run_trial(sc, names, trial, noisy, args, cache):
    key = jr.PRNGKey(1000 * trial + 7)
    sp = scenario_problem(
        sc,
        names,
        key=key if noisy else None,
        relative_noise=0.02 if noisy else None,
        duration=args.duration,
        rtol=args.rtol,
    )
    obj, truth = sp.objective, sp.truth
    problem = as_problem(obj)
    n = truth.size
    theta_nom = start_theta(problem.transform, None)
    out = {}
    for m in ("lm", "bfgs", "nelder-mead", "pattern"):
        if m not in args.methods:
            continue
        steps = args.max_steps if m in ("lm", "bfgs") else args.dfo_steps
        r, wall = _timed_local(problem, theta_nom, m, steps, cache)
        out[m] = _summary(problem, r.theta, r.num_fn_evals, r.num_jac_evals, wall, truth, noisy)
    if "annealing" in args.methods:
        tag = dict(scenario=sc, noise_percent=2 if noisy else 0, trial=trial)
        out["annealing"] = run_annealing(
            problem, theta_nom, jr.fold_in(key, 1), truth, noisy, args, cache, tag
        )
    design_key = jr.fold_in(key, 2)
    if "multistart-lm" in args.methods:
        if ("ms", n) not in cache:
            cache[("ms", n)] = BatchedFits(obj, "lm", args.max_steps, lanes=_lanes(args))
        bf = cache[("ms", n)]
        thetas = design_starts(problem, design_key, args.starts, "lhs")
        keys = jr.split(key, args.starts)
        bf.compile(obj, thetas, keys)  # ahead of time (once per shape), outside the timing
        batch, wall, lo, costs, b = _timed_batch(bf, obj, thetas, keys)
        out["multistart-lm"] = _summary(
            problem,
            lo.theta[b],
            np.asarray(lo.num_fn_evals).sum(),
            np.asarray(lo.num_jac_evals).sum(),
            wall,
            truth,
            noisy,
        )
        out["multistart-lm"]["failed_starts"] = int(np.asarray(batch.failed).sum())
        # how many single starts got there: the chance that all of them miss follows from it
        ms = out["multistart-lm"]
        ms["starts_at_global"] = int(np.sum(costs <= costs[b] * (1 + 1e-6) + GLOBAL_TOL))
        if not noisy:
            ends = np.asarray(jax.vmap(problem.transform.to_physical)(np.asarray(lo.theta)))
            within = (relative_errors(ends, truth) < 0.01).all(axis=1) & np.isfinite(costs)
            ms["starts_within_1pct"] = int(within.sum())
        ms["start_costs"] = [float(c) if np.isfinite(c) else None for c in costs]
        if trial == 0 and args.loop:
            out["_loop"] = loop_vs_batch(problem, thetas, wall, args, cache)
    if "hybrid" in args.methods:
        sched = SimulatedAnnealing(n_iter=args.hybrid_iter, step_size=0.5)
        bf = cache.setdefault(("hy", n), BatchedFits(obj, "lm", args.max_steps, schedule=sched))
        thetas = design_starts(problem, jr.fold_in(key, 3), args.hybrid_chains, "lhs")
        keys = jr.split(jr.fold_in(key, 4), args.hybrid_chains)
        bf.compile(obj, thetas, keys)  # ahead of time (once per shape), outside the timing
        batch, wall, lo, costs, b = _timed_batch(bf, obj, thetas, keys)
        fevs = np.asarray(lo.num_fn_evals).sum() + args.hybrid_chains * (args.hybrid_iter + 1)
        out["hybrid"] = _summary(
            problem, lo.theta[b], fevs, np.asarray(lo.num_jac_evals).sum(), wall, truth, noisy
        )
    mark_global(out)
    return out


ACCURACIES = (1e-2, 1e-3, 1e-4, 1e-5)


def run_annealing(problem, theta0, key, truth, noisy, args, cache, tag):
    """One annealing chain of `--sa-iter` proposals, run in pieces of `--sa-piece`: after every
    piece the chain's progress (evaluations, wall time, best cost and error, evaluations to
    each accuracy so far) is appended to `results/identification/NAME_annealing.jsonl`, so an
    interrupted long chain keeps what it has measured."""
    import json

    sched = SimulatedAnnealing(n_iter=args.sa_iter, step_size=0.5, min_step=args.sa_min_step)
    piece = min(args.sa_piece or sched.n_iter, sched.n_iter)
    n = theta0.size
    if ("sa", n) not in cache:  # compile only (ahead of time), outside the timing
        start = eqx.filter_jit(anneal_start)
        steps = eqx.filter_jit(lambda p, st, k, sc: anneal_steps(p, st, k, sc, piece))
        st0 = start(problem, theta0, sched)
        cache[("sa", n)] = (start, steps.lower(problem, st0, key, sched).compile())
    start, steps = cache[("sa", n)]
    tic = time.perf_counter()
    state = jax.block_until_ready(start(problem, theta0, sched))
    wall = time.perf_counter() - tic
    hits = {f"{tol:g}": None for tol in ACCURACIES}
    log = RESULTS / "identification" / f"{args.name}_annealing.jsonl"
    log.parent.mkdir(parents=True, exist_ok=True)
    while int(state.k) < sched.n_iter:
        done = int(state.k)
        tic = time.perf_counter()
        state, path = jax.block_until_ready(steps(problem, state, key, sched))
        wall += time.perf_counter() - tic
        for tol, evals in evals_to_accuracy(problem, path, truth, done).items():
            hits[tol] = hits[tol] or evals
        best = np.asarray(problem.transform.to_physical(state.best))
        record = dict(
            **tag,
            evaluations=int(state.k) + 1,
            wall_s=round(wall, 2),
            best_cost=float(state.best_cost),
            max_rel_error=float(relative_errors(best, truth).max()),
            evals_to_accuracy=hits,
        )
        with log.open("a") as f:
            f.write(json.dumps(record) + "\n")
    out = _summary(problem, state.best, int(state.k) + 1, 0, wall, truth, noisy)
    out["evals_to_accuracy"] = hits
    return out


def evals_to_accuracy(problem, path, truth, done=0):
    """`{tol: evaluations}`: how many cost evaluations an annealing chain took until its best
    point had every parameter within `tol` (relative) of the truth; `None`: not within this
    `path` (its best point after each of proposals `done + 1, done + 2, ...`)."""
    est = np.asarray(jax.vmap(problem.transform.to_physical)(path))
    worst = relative_errors(est, truth).max(axis=1)
    out = {}
    for tol in ACCURACIES:
        hit = np.flatnonzero(worst < tol)
        # row k: the start and the first done + k + 1 proposals
        out[f"{tol:g}"] = done + int(hit[0]) + 2 if hit.size else None
    return out


# Costs are in noise variances (residuals weighted by 1/sigma). Two fits whose costs differ by
# less than this reached the same minimum as far as the solves can tell: with 2 % noise and PID
# rtol 1e-8 the cost is rough at the 1e-3 level (along a segment through the minimum of a
# `primary3` trial it jumped by up to 3.3e-3, while at rtol 1e-11 it was smooth), so a method that
# samples many points (annealing, pattern search) can land on such a jump, below the minimum.
# Statistically these differences are nothing: one parameter's 95 % interval ends 1.92 above.
GLOBAL_TOL = 1e-2


def mark_global(out):
    """Flag the methods of one trial whose final cost is the trial's lowest (within
    `GLOBAL_TOL` plus 1e-6 relative)."""
    methods = {k: v for k, v in out.items() if not k.startswith("_")}
    best = min(v["cost"] for v in methods.values())
    for v in methods.values():
        v["global"] = bool(v["cost"] <= best * (1 + 1e-6) + GLOBAL_TOL)


def _timed_batch(fits, obj, thetas, keys):
    """Run a compiled batch of fits: (batch, wall time, local outputs, costs with failed
    members at +inf, index of the best member)."""
    tic = time.perf_counter()
    batch = fits(obj, thetas, keys)
    wall = time.perf_counter() - tic
    lo, costs = batch.outputs
    costs = np.where(np.asarray(batch.failed), np.inf, np.asarray(costs))
    return batch, wall, lo, costs, int(np.argmin(costs))


@eqx.filter_jit
def _local_solve(problem, theta0, method, max_steps):
    return method.solve(problem, theta0, max_steps)


def _compiled_local(problem, theta0, method, max_steps, cache):
    """`solve(problem, theta, method, max_steps) -> LocalOutput`: one local fit without
    statistics, compiled ahead of time once per method, parameter count and step budget (the
    LM: its evaluation program for one fit on one device, the problem an input)."""
    key = ("local", method, theta0.size, max_steps)
    if key not in cache:
        m = LOCAL_METHODS[method]
        if supports_queue(m):
            fits = batched_fits(problem, m, max_steps, lanes=1, devices=jax.devices()[:1])
            fits.compile(problem, theta0[None])
            first = lambda batch: jax.tree.map(lambda x: x[0], batch.outputs[0])
            cache[key] = lambda p, theta, _m, _s: first(fits(p, jnp.asarray(theta)[None]))
        else:
            cache[key] = _local_solve.lower(problem, theta0, m, max_steps).compile()
    return cache[key]


def _timed_local(problem, theta0, method, max_steps, cache):
    """One local solve and its wall time (compilation outside the timing)."""
    solve = _compiled_local(problem, theta0, method, max_steps, cache)
    tic = time.perf_counter()
    out = jax.block_until_ready(solve(problem, theta0, LOCAL_METHODS[method], max_steps))
    return out, time.perf_counter() - tic


def loop_vs_batch(problem, thetas, batch_wall, args, cache):
    """The same LM fits from the same starts, one after the other (one compiled solve, the
    program single-start LM uses)."""
    solve = _compiled_local(problem, thetas[0], "lm", args.max_steps, cache)
    tic = time.perf_counter()
    for theta in thetas:
        jax.block_until_ready(solve(problem, theta, LOCAL_METHODS["lm"], args.max_steps))
    loop = time.perf_counter() - tic
    return dict(n_starts=len(thetas), batched_s=batch_wall, loop_s=loop, speedup=loop / batch_wall)


def coverage(sc, args, cache):
    """How often the reported 95 % intervals contain the truth under 2 % noise: `--starts`
    trials (new noise each), one LM fit from the nominal values per trial, all run as one batch
    with one data set per member (the compiled multistart program: same member count)."""
    sps = [
        scenario_problem(
            sc,
            None,
            key=jr.PRNGKey(5000 + k),
            relative_noise=0.02,
            duration=args.duration,
            rtol=args.rtol,
        )
        for k in range(args.starts)
    ]
    objs = [sp.objective for sp in sps]
    n = sps[0].truth.size
    if ("ms", n) not in cache:
        cache[("ms", n)] = BatchedFits(objs[0], "lm", args.max_steps, lanes=_lanes(args))
    thetas = jnp.stack([start_theta(as_problem(o).transform, None) for o in objs])
    batch = cache[("ms", n)](stack_objectives(objs), thetas, stacked=True)
    failed = np.asarray(batch.failed)
    ends = np.asarray(batch.outputs[0].theta)  # on the host (see `_summary`)
    inside = []
    for obj, sp, end in zip(objs, sps, ends):
        ci = np.asarray(_stats(as_problem(obj), jnp.asarray(end), 1e-6)["ci95"])
        inside.append((ci[:, 0] <= sp.truth) & (sp.truth <= ci[:, 1]))
    inside = np.asarray(inside)[~failed]
    return dict(
        trials=len(objs),
        failed=int(failed.sum()),
        all_inside=float(inside.all(axis=1).mean()),
        per_parameter=dict(zip(objs[0].selection.names, inside.mean(axis=0).tolist())),
    )


def aggregate(trials):
    rows = {}
    for out in trials:
        for m, v in out.items():
            if m.startswith("_"):
                continue
            rows.setdefault(m, []).append(v)
    agg = {}
    for m, vs in rows.items():
        agg[m] = dict(
            trials=len(vs),
            success_rate=float(np.mean([v["success"] for v in vs])),
            global_rate=float(np.mean([v["global"] for v in vs])),
            forward_solves=float(np.median([v["forward_solves"] for v in vs])),
            solve_equivalents=float(np.median([v["solve_equivalents"] for v in vs])),
            wall_time=float(np.median([v["wall_time"] for v in vs])),
            max_rel_error=float(np.median([v["max_rel_error"] for v in vs])),
        )
        if all("starts_within_1pct" in v for v in vs):  # multistart LM, noise-free
            agg[m]["starts_within_1pct"] = [v["starts_within_1pct"] for v in vs]
            agg[m]["failed_starts"] = [v["failed_starts"] for v in vs]
        if all("evals_to_accuracy" in v for v in vs):
            agg[m]["evals_to_accuracy"] = {
                tol: [v["evals_to_accuracy"][tol] for v in vs] for tol in vs[0]["evals_to_accuracy"]
            }
    return agg


def _sa_accuracy_lines(results, budget):
    """Rows of the same-accuracy comparison: the evaluations annealing needed to bring every
    parameter within each accuracy (median over trials; a trial that never got there counts as
    more than its budget) against multistart LM's solve equivalents and final error."""
    lines = []
    for (sc, n, noise), agg in results.items():
        sa, ms = agg.get("annealing"), agg.get("multistart-lm")
        if noise != "0%" or sa is None or ms is None or "evals_to_accuracy" not in sa:
            continue
        for tol, per_trial in sa["evals_to_accuracy"].items():
            reached = [k for k in per_trial if k is not None]
            med = np.median([np.inf if k is None else k for k in per_trial])
            ratio = min(med, budget) / ms["solve_equivalents"]
            if np.isfinite(med):
                sa_txt, ratio_txt = f"{med:.0f}", f"{ratio:.2f}"
            else:
                sa_txt, ratio_txt = f"> {budget}", f"> {ratio:.2f}"
            lines.append(
                f"| {sc} | {tol} | {sa_txt} ({len(reached)}/{len(per_trial)} trials) | "
                f"{ms['solve_equivalents']:.0f} ({ms['max_rel_error']:.0e}) | {ratio_txt} |"
            )
    return lines


def _start_share_lines(results, n_starts):
    lines = []
    for (sc, n, noise), agg in results.items():
        ms = agg.get("multistart-lm", {})
        if "starts_within_1pct" not in ms:
            continue
        hits, failed = ms["starts_within_1pct"], ms["failed_starts"]
        share = sum(hits) / (n_starts * len(hits))
        lines.append(
            f"| {sc} | {len(hits)} | {sum(hits)} of {n_starts * len(hits)} (per trial "
            f"{min(hits)}-{max(hits)}) | {sum(failed)} | {share:.0%} | "
            f"{(1 - share) ** n_starts:.0e} |"
        )
    return lines


def _batch_kind(settings):
    lanes = settings.get("lanes")  # absent in runs before the queue: lock-step
    if lanes in (None, "0", 0):
        return "lock-step: every start at once"
    auto = ", `queue_lanes`: 1 on CPU devices, else ceil(32 / (n + 1))" if lanes == "auto" else ""
    return f"queued: {lanes} lanes per device{auto}"


def markdown(results, loops, covers, settings):
    lines = [
        "# Identification benchmark",
        "",
        "Settings: " + ", ".join(f"{k}={v}" for k, v in settings.items()),
        "",
        "Success: all parameters within 1 % (noise-free) / truth inside every 95 % interval (2 % "
        f"noise). Global: final cost within {GLOBAL_TOL:g} (noise variances) of the lowest cost "
        "any method reached in the trial. A run writes its tables after every trial; the trials "
        "column says how many finished. "
        "Forward solves (residual or cost evaluations; each least-squares step or BFGS gradient "
        "also takes a forward-mode Jacobian of n tangents), solve equivalents (forward solves + "
        "n x Jacobians) and wall time: medians per trial (wall time after compilation).",
        "",
        "| scenario | n | noise | method | trials | success | global | forward solves "
        "| solve equivalents | wall [s] | median max rel. error |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for (sc, n, noise), agg in results.items():
        for m in METHODS:
            if m in agg:
                a = agg[m]
                lines.append(
                    f"| {sc} | {n} | {noise} | {m} | {a['trials']} | {a['success_rate']:.0%} | "
                    f"{a['global_rate']:.0%} | {a['forward_solves']:.0f} | "
                    f"{a['solve_equivalents']:.0f} | {a['wall_time']:.2f} | "
                    f"{a['max_rel_error']:.1e} |"
                )
    lines += [
        "",
        "Solve equivalents of simulated annealing relative to multistart LM "
        "(target: multistart LM needs at most 1/10 of what SA needs for the same accuracy; "
        "where SA falls short of multistart LM's success rate, its budget is a lower bound "
        "of what it needs):",
        "",
        "| scenario | noise | SA / multistart-LM solve equivalents | SA success | "
        "multistart-LM success |",
        "| --- | --- | --- | --- | --- |",
    ]
    for (sc, n, noise), agg in results.items():
        if "annealing" in agg and "multistart-lm" in agg:
            a, b = agg["annealing"], agg["multistart-lm"]
            lines.append(
                f"| {sc} | {noise} | {a['solve_equivalents'] / b['solve_equivalents']:.2f} | "
                f"{a['success_rate']:.0%} | {b['success_rate']:.0%} |"
            )
    sa_rows = _sa_accuracy_lines(results, settings["sa_iter"] + 1)
    if sa_rows:
        lines += [
            "",
            "The same accuracy (noise-free): evaluations of one annealing chain until its best "
            "point had every parameter within the accuracy (median over trials, from the chain's "
            "path), against multistart LM's solve equivalents per trial (its median worst error "
            "in brackets). Target: SA / multistart LM >= 10.",
            "",
            "| scenario | accuracy | SA evaluations | multistart-LM solve equivalents (error) | "
            "SA / multistart LM |",
            "| --- | --- | --- | --- | --- |",
            *sa_rows,
        ]
    share_rows = _start_share_lines(results, settings["starts"]) if "starts" in settings else []
    if share_rows:
        lines += [
            "",
            "Single starts of multistart LM (noise-free) that reached the truth (every parameter "
            "within 1 %), summed over the trials, and the chance that all starts of a trial miss "
            "if each reaches it independently with the pooled share (an estimate of how often "
            "the multistart can fail, far below what the trials alone can show):",
            "",
            "| scenario | trials | starts within 1 % | failed starts | pooled share | "
            "P(all starts miss) |",
            "| --- | --- | --- | --- | --- | --- |",
            *share_rows,
        ]
    if covers:
        lines += [
            "",
            "Coverage of the 95 % intervals with 2 % noise: one LM fit from the nominal values per "
            "trial, new noise per trial (all trials one batch). With independent estimates all n "
            "intervals hold together in about 0.95^n of the trials:",
            "",
            "| scenario | trials | failed | all truths inside | per parameter |",
            "| --- | --- | --- | --- | --- |",
        ]
        for sc, c in covers.items():
            per = ", ".join(f"{k} {v:.0%}" for k, v in c["per_parameter"].items())
            lines.append(
                f"| {sc} | {c['trials']} | {c['failed']} | {c['all_inside']:.0%} | {per} |"
            )
    if loops:
        lines += [
            "",
            "Multistart LM: one vmapped batch sharded over 2 CPU devices ("
            + _batch_kind(settings)
            + ") against a "
            "Python loop of the same fits (target >= 1.7x):",
            "",
            "| scenario | noise | starts | batched [s] | loop [s] | speedup |",
            "| --- | --- | --- | --- | --- | --- |",
        ]
        for (sc, n, noise), lp in loops.items():
            lines.append(
                f"| {sc} | {noise} | {lp['n_starts']} | {lp['batched_s']:.2f} | "
                f"{lp['loop_s']:.2f} | {lp['speedup']:.2f}x |"
            )
    return "\n".join(lines) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=20)
    p.add_argument(
        "--duration", type=float, default=None, help="simulated time [s] (default: scenario's)"
    )
    p.add_argument("--scenarios", default="primary3,primary6,all10")
    p.add_argument("--noise", default="0,2", help="noise levels in %% (0 and/or 2)")
    p.add_argument("--methods", default=",".join(METHODS))
    p.add_argument("--starts", type=int, default=32)
    p.add_argument("--max-steps", type=int, default=100)
    p.add_argument(
        "--lanes",
        default="auto",
        help="multistart LM fits in flight per device, queued (default auto: ceil(32 / (n + 1))); "
        "0: lock-step batch",
    )
    p.add_argument(
        "--dfo-steps", type=int, default=400, help="steps of Nelder-Mead / pattern search"
    )
    p.add_argument("--sa-iter", type=int, default=2000)
    p.add_argument(
        "--sa-piece",
        type=int,
        default=2000,
        help="annealing proposals per compiled piece; progress is saved after each "
        "(must divide --sa-iter)",
    )
    p.add_argument(
        "--sa-min-step",
        type=float,
        default=1e-6,
        help="smallest annealing proposal scale (fraction of the bounds' width)",
    )
    p.add_argument("--hybrid-chains", type=int, default=4)
    p.add_argument("--hybrid-iter", type=int, default=200)
    p.add_argument("--rtol", type=float, default=1e-8)
    p.add_argument("--no-loop", dest="loop", action="store_false")
    p.add_argument(
        "--no-coverage",
        dest="coverage",
        action="store_false",
        help="skip the interval-coverage block (--starts noisy trials per scenario)",
    )
    p.add_argument("--name", default="every_method")
    p.add_argument(
        "--from-json",
        action="store_true",
        help="solve nothing: rebuild the tables of results/identification/NAME.json from its "
        "per-trial records",
    )
    p.add_argument(
        "--merge",
        default=None,
        help="solve nothing: merge the per-trial records of the runs results/identification/"
        "A.json,B.json,... "
        "(comma-separated names; e.g. methods run separately on the same trials) into NAME",
    )
    args = p.parse_args(argv)
    if args.from_json or args.merge:
        return report_from_json(args.name, args.merge and args.merge.split(","))
    args.methods = tuple(m.strip() for m in args.methods.split(","))
    if args.sa_piece < 1 or args.sa_iter % min(args.sa_piece, args.sa_iter):
        p.error(
            f"--sa-piece must be >= 1 and divide --sa-iter = {args.sa_iter}, got {args.sa_piece}"
        )
    settings = {k: v for k, v in vars(args).items() if k != "name"}
    settings["devices"] = jax.device_count()
    results, loops, raw, covers = {}, {}, [], {}
    t_all = time.perf_counter()

    def write():  # so a run cut short keeps what is finished
        settings["total_wall_s"] = round(time.perf_counter() - t_all, 1)
        records = [
            dict(scenario=k[0], n_params=k[1], noise=k[2], methods=v) for k, v in results.items()
        ]
        write_outputs(
            f"identification/{args.name}",
            records,
            markdown(results, loops, covers, settings),
            extra=dict(
                settings=settings,
                trials=raw,
                loop_vs_batch=[dict(scenario=k[0], noise=k[2], **v) for k, v in loops.items()],
                coverage=covers,
            ),
        )

    for sc in args.scenarios.split(","):
        cache = {}
        for noise in (int(x) for x in args.noise.split(",")):
            trials = []
            for t in range(args.trials):
                tic = time.perf_counter()
                out = run_trial(sc, None, t, noise > 0, args, cache)
                trials.append(out)
                if "_loop" in out:
                    loops[(sc, _n_params(sc), f"{noise}%")] = out.pop("_loop")
                raw.append(dict(scenario=sc, noise_percent=noise, trial=t, methods=out))
                print(
                    f"{sc} noise {noise}% trial {t}: {time.perf_counter() - tic:.1f} s; "
                    + ", ".join(f"{m}: {'ok' if v['success'] else 'FAIL'}" for m, v in out.items()),
                    flush=True,
                )
                results[(sc, _n_params(sc), f"{noise}%")] = aggregate(trials)
                write()  # after every trial: an interrupted run keeps what is finished
        if args.coverage:
            tic = time.perf_counter()
            covers[sc] = coverage(sc, args, cache)
            print(f"{sc} coverage: {covers[sc]} ({time.perf_counter() - tic:.1f} s)", flush=True)
            write()


def report_from_json(name, sources=None):
    """Re-aggregate saved per-trial records into `results/identification/NAME.{json,md}`:
    those of `NAME` itself (a possibly interrupted run), or merged from the runs `sources`.
    Trial `t` of a scenario and noise level has the same noise and start design in every run
    (its key is `1000 t + 7`), so runs of different methods merge into the trials of one
    table."""
    import json

    from benchmarks._common import RESULTS

    folder = RESULTS / "identification"
    runs = [json.loads((folder / f"{src}.json").read_text()) for src in sources or [name]]
    merged = {}
    for src, saved in zip(sources or [name], runs):
        for t in saved["trials"]:
            key = (t["scenario"], t["noise_percent"], t["trial"])
            methods = merged.setdefault(key, {})
            twice = set(methods) & set(t["methods"])
            if twice:
                raise SystemExit(f"{src}: {key} already has {sorted(twice)} from another run")
            methods.update(t["methods"])
    blocks = {}
    for (sc, noise, _), methods in sorted(merged.items(), key=lambda kv: kv[0][2]):
        mark_global(methods)
        blocks.setdefault((sc, _n_params(sc), f"{noise}%"), []).append(methods)
    results = {k: aggregate(v) for k, v in blocks.items()}
    loops = {
        (lp["scenario"], _n_params(lp["scenario"]), lp["noise"]): lp
        for saved in runs
        for lp in saved.get("loop_vs_batch", [])
    }
    covers = {k: v for saved in runs for k, v in saved.get("coverage", {}).items()}
    records = [
        dict(scenario=k[0], n_params=k[1], noise=k[2], methods=v) for k, v in results.items()
    ]
    if sources is None:
        extra = {k: v for k, v in runs[0].items() if k != "records"}  # keeps the run's environment
        settings = runs[0]["settings"]
    else:
        # the settings all runs share; each run's own are kept under `source_settings`
        first = runs[0]["settings"]
        settings = {k: v for k, v in first.items() if all(r["settings"].get(k) == v for r in runs)}
        settings["merged_from"] = list(sources)
        methods = [m for saved in runs for m in saved["settings"]["methods"]]
        settings["methods"] = tuple(dict.fromkeys(methods))
        for saved in runs:  # the annealing budget comes from the run that annealed
            if "annealing" in saved["settings"]["methods"]:
                settings["sa_iter"] = saved["settings"]["sa_iter"]
        trials = [
            dict(scenario=k[0], noise_percent=k[1], trial=k[2], methods=v)
            for k, v in merged.items()
        ]
        extra = dict(
            settings=settings,
            source_settings={src: saved["settings"] for src, saved in zip(sources, runs)},
            trials=trials,
            loop_vs_batch=[lp for saved in runs for lp in saved.get("loop_vs_batch", [])],
            coverage=covers,
        )
    write_outputs(
        f"identification/{name}", records, markdown(results, loops, covers, settings), extra=extra
    )
    return 0


def _lanes(args):
    return None if args.lanes == "0" else args.lanes if args.lanes == "auto" else int(args.lanes)


def _n_params(sc):
    from bogie_jax.identify import SCENARIOS

    return len(SCENARIOS[sc].offsets)


if __name__ == "__main__":
    sys.exit(main())
