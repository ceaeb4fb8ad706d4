# long: one program builder per measured program (about 20 short functions) plus the parent's
# scheduling, tables and comparison; splitting them would scatter one benchmark over files.
"""Compile cost of the library's programs (issue 15, "measure first").

Every program runs in a fresh Python subprocess with no persistent compilation cache, and is
measured in stages: tracing (`jax.jit(f).trace`), lowering to StableHLO (`.lower()`), XLA
compilation (`.compile()`, wall and CPU time), the size of the lowered module (operations) and
of the optimised HLO (instructions, fusion and loop bodies included), and the run time per call
(first call, then the median of a few). The optimised HLO's instructions are charged to the part
of the model they come from by the call stack XLA keeps for each of them (`stack_frame_id`):
the innermost frame in a known file decides (vector field, track evaluation, sensor readings,
linear solve, ODE solver, optimiser loop, ...). Small parts are also compiled on their own.

    python benchmarks/compile.py --label now
    python benchmarks/compile.py --repo /path/to/older/checkout --label before
    python benchmarks/compile.py --label x --programs residuals3,jacfwd3
    python benchmarks/compile.py --label x --no-run        # trace, lower and compile only
    python benchmarks/compile.py --compare before,now

Writes `results/compile/LABEL.json` and `.md` (`results/compile/A_vs_B.md` for `--compare`).
Times are in seconds unless the column says ms; they grow with the machine's load, which is
recorded (1-minute load average before and after every program).
"""

import argparse
import datetime
import importlib
import importlib.util
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import lineax as lx
import numpy as np


HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results" / "compile"
N_STARTS = 4  # multistart starts, spread over 2 CPU devices
MULTISTART_MAX_STEPS = 20  # LM steps per start: bounds the run time, not the program
ANNEAL_PIECE = 20  # proposals per annealing piece

# name: (what it is, scenario or None, host devices)
PROGRAMS = {
    "simulation": ("forward solve of the default run (2 s, 100 Hz)", "default", 1),
    "residuals3": ("objective.residuals, 3 parameters", "default", 1),
    "residuals10": ("objective.residuals, 10 parameters (all10, 3 s)", "all10", 1),
    "jacfwd3": ("jacfwd(JacobianResiduals), 3 parameters", "default", 1),
    "jacfwd10": ("jacfwd(JacobianResiduals), 10 parameters", "all10", 1),
    "grad3": ("grad(cost), full checkpoints, 3 parameters", "default", 1),
    "grad10": ("grad(cost), full checkpoints, 10 parameters", "all10", 1),
    "fit3": ("fit's LM program (one residual-Jacobian evaluation), 3 parameters", "default", 1),
    "multistart3": (f"multistart LM program, {N_STARTS} starts, 3 parameters", "default", 2),
    "multistart10": (f"multistart LM program, {N_STARTS} starts, 10 parameters", "all10", 2),
    "anneal3": (f"annealing piece of {ANNEAL_PIECE} proposals, 3 parameters", "default", 1),
    "stability_sweep": ("stability_sweep over 30 speeds", None, 1),
    "critical_speed": ("critical_speed (grid + bisection)", None, 1),
    "part_vector_field": ("part: vector_field(t, y, model)", "default", 1),
    "part_track": ("part: track_inputs(model, t)", "default", 1),
    "part_sensors": ("part: sensor_readings of 13 channels at 201 samples", "default", 1),
    "part_linear_solve": ("part: HouseholderQR least-squares step (2616 x 3)", "default", 1),
}


# ---------------------------------------------------------------- child: the programs


def internal(module: str, name: str):
    """A private name of bogie_jax. This benchmark instruments the library's internals on
    purpose (the program `fit` compiles, the annealing piece): looked up at run time so that a
    checkout without it fails that program only."""
    return getattr(importlib.import_module(module), name)


def jit_module_fn(fn, module, *args):
    """`(jax.jit(g), (dynamic, *args))` with `g(dynamic, *args) = fn(module, *args)`: a module's
    arrays become arguments, its functions and settings stay static."""
    dynamic, static = eqx.partition(module, eqx.is_array)
    return jax.jit(lambda d, *a: fn(eqx.combine(d, static), *a)), (dynamic, *args)


def scenario_objective(scenario: str):
    """The scenario's objective and the nominal start (theta = 0)."""
    from bogie_jax.identify import scenario_problem

    objective = scenario_problem(scenario).objective
    return objective, jnp.zeros(objective.n_params)


def build_simulate(scenario):
    objective, theta = scenario_objective(scenario)
    return jit_module_fn(lambda o, th: o.simulate(th).q, objective, theta)


def build_residuals(scenario):
    objective, theta = scenario_objective(scenario)
    return jit_module_fn(lambda o, th: o.residuals(th), objective, theta)


def build_jacfwd(scenario):
    from bogie_jax.identify import JacobianResiduals

    objective, theta = scenario_objective(scenario)
    forward = objective.with_adjoint(dfx.ForwardMode())  # as the fits do (explicit since fc1cbbc)
    return jit_module_fn(lambda o, th: jax.jacfwd(JacobianResiduals(o))(th), forward, theta)


def build_grad(scenario):
    from bogie_jax.gradients import full_checkpoints

    objective, theta = scenario_objective(scenario)
    reverse = objective.with_adjoint(full_checkpoints(objective.residual_model.max_steps))
    return jit_module_fn(lambda o, th: jax.grad(o.cost)(th), reverse, theta)


def build_fit(scenario):
    """The program `fit` compiles for the LM: the residual Jacobian and free parameters that
    each LM iteration evaluates (older checkouts: the compiled LM solve and its statistics)."""
    from bogie_jax.identify import LOCAL_METHODS, as_problem

    objective, theta = scenario_objective(scenario)
    problem = as_problem(objective)
    try:
        evaluation = internal("bogie_jax.identify._lm_fits", "evaluation")
    except ModuleNotFoundError:  # the LM as an optimistix solver, compiled whole
        fit_program = internal("bogie_jax.identify._local", "_fit_jit")
        fit_program = getattr(fit_program, "__wrapped__", fit_program)
        return jit_module_fn(
            lambda pm, th: fit_program(pm[0], th, pm[1], 256, 1e-6),
            (problem, LOCAL_METHODS["lm"]),
            theta,
        )
    return jit_module_fn(lambda pm, th: evaluation(pm, th, 1e-6), problem, theta)


def build_multistart(scenario):
    """The sharded program `BatchedFits` compiles ahead of time (the LM's: the evaluation of the
    fits in flight; older checkouts: the queued LM loop), captured at its runner's
    `BatchRunner.compile(batch)` as `BatchRunner.program(batch)` (older still: at their
    `ahead_of_time(jitted)` call): the runner's own inputs, already placed on the devices."""
    import bogie_jax.runtime.batch
    from bogie_jax.identify import LatinHypercube

    objective, _ = scenario_objective(scenario)
    batched_fits = internal("bogie_jax.identify._batched", "BatchedFits")
    captured = []

    class Captured(Exception):
        pass

    def capture(jitted):
        def executable(args):
            captured.append((jitted, (args,)))
            raise Captured

        return executable

    def capture_compile(runner, batch):
        captured.append(runner.program(batch))
        raise Captured

    if hasattr(bogie_jax.runtime.batch, "BatchRunner"):
        bogie_jax.runtime.batch.BatchRunner.compile = capture_compile
    for name in ("bogie_jax.runtime.batch", "bogie_jax.runtime.queued_batch"):
        module = importlib.util.find_spec(name) and importlib.import_module(name)
        if module and hasattr(module, "ahead_of_time"):
            module.ahead_of_time = capture
    selection = objective.selection
    lower, upper = np.asarray(selection.lower), np.asarray(selection.upper)
    u = LatinHypercube().sample(jr.PRNGKey(0), N_STARTS, lower.size)
    thetas = jax.vmap(selection.to_theta)(jnp.asarray(lower + (upper - lower) * u))
    fits = batched_fits(objective, "lm", MULTISTART_MAX_STEPS, lanes="auto")
    try:
        fits.compile(objective, thetas)
    except Captured:
        pass
    if not captured:
        raise RuntimeError("BatchedFits.compile did not reach its runner's compile")
    return captured[0]


def build_anneal(scenario):
    """`anneal_steps` of one piece, as the identification benchmark compiles it."""
    from bogie_jax.identify import SimulatedAnnealing, as_problem

    objective, theta = scenario_objective(scenario)
    start = internal("bogie_jax.identify._annealing", "anneal_start")
    steps = internal("bogie_jax.identify._annealing", "anneal_steps")
    problem = as_problem(objective)
    schedule = SimulatedAnnealing(n_iter=2000, step_size=0.5)
    state = start(problem, theta, schedule)
    return jit_module_fn(
        lambda ps, st, key: steps(ps[0], st, key, ps[1], ANNEAL_PIECE),
        (problem, schedule),
        state,
        jr.PRNGKey(0),
    )


def build_stability_sweep(_):
    from bogie_jax import manchester_benchmark
    from bogie_jax.model import stability_sweep

    speeds = jnp.linspace(5.0, 150.0, 30)
    return jit_module_fn(
        lambda p, v: stability_sweep(p, v).max_real_part, manchester_benchmark(), speeds
    )


def build_critical_speed(_):
    from bogie_jax import manchester_benchmark
    from bogie_jax.model import critical_speed

    return jit_module_fn(lambda p: critical_speed(p).speed, manchester_benchmark())


def scenario_model(scenario):
    """The objective's `BogieModel` at nominal parameters, and the objective."""
    from bogie_jax.model import build_model

    objective, _ = scenario_objective(scenario)
    rm = objective.residual_model
    return build_model(objective.params, speed=rm.speed, track=rm.track), objective


def build_part_vector_field(scenario):
    from bogie_jax.model import vector_field

    model, _ = scenario_model(scenario)
    y = jnp.full(20, 1e-4)
    return jit_module_fn(lambda m, t, y_: vector_field(t, y_, m), model, jnp.asarray(0.3), y)


def build_part_track(scenario):
    from bogie_jax.model import track_inputs

    model, _ = scenario_model(scenario)
    return jit_module_fn(track_inputs, model, jnp.asarray(0.3))


def build_part_sensors(scenario):
    from bogie_jax.measure import sensor_readings

    model, objective = scenario_model(scenario)
    n = objective.residual_model.data.shape[0]
    ts = jnp.linspace(0.0, objective.residual_model.duration, n)
    q = jnp.full((n, 10), 1e-4)
    sensors = objective.residual_model.sensors
    return jit_module_fn(
        lambda ms, t, a, b, c: sensor_readings(ms[1], ms[0], t, a, b, c),
        (model, sensors),
        ts,
        q,
        q,
        q,
    )


def build_part_linear_solve(scenario):
    """One least-squares step of a damped Gauss-Newton step's size, `[J; sqrt(lambda) I]` of the
    3-parameter fit, by the `HouseholderQR` of optimistix's least-squares methods."""
    from bogie_jax.identify import HouseholderQR

    objective, _ = scenario_objective(scenario)
    qr = HouseholderQR()
    m, n = objective.n_residuals + objective.n_params, objective.n_params
    a = jax.random.normal(jax.random.PRNGKey(0), (m, n))
    b = jnp.ones(m)
    solve = lambda a_, b_: lx.linear_solve(lx.MatrixLinearOperator(a_), b_, qr).value
    return jax.jit(solve), (a, b)


BUILDERS = {
    "simulation": build_simulate,
    "residuals": build_residuals,
    "jacfwd": build_jacfwd,
    "grad": build_grad,
    "fit": build_fit,
    "multistart": build_multistart,
    "anneal": build_anneal,
    "stability_sweep": build_stability_sweep,
    "critical_speed": build_critical_speed,
    "part_vector_field": build_part_vector_field,
    "part_track": build_part_track,
    "part_sensors": build_part_sensors,
    "part_linear_solve": build_part_linear_solve,
}


# a source file (as `file_label` gives it) -> the part of the program it belongs to; first
# matching prefix wins
PART_RULES = (
    ("bogie_jax/track/", "track evaluation"),
    ("bogie_jax/model/_stability", "stability"),
    ("bogie_jax/model/", "vector field"),
    ("bogie_jax/contact/", "vector field"),
    ("bogie_jax/params/", "vector field"),
    ("bogie_jax/measure/", "sensor readings"),
    ("bogie_jax/_householder", "linear solve"),
    ("bogie_jax/identify/_jacobian", "Jacobian rule"),
    ("bogie_jax/identify/", "optimiser loop"),
    ("bogie_jax/batch", "optimiser loop"),
    ("bogie_jax/cost/", "objective"),
    ("bogie_jax/gradients", "objective"),
    ("bogie_jax/simulation", "ODE solver"),
    ("lineax/", "linear solve"),
    ("diffrax/", "ODE solver"),
    ("optimistix/", "optimiser loop"),
    ("(no stack)", "(no stack)"),
)
PARTS = (
    *("vector field", "track evaluation", "sensor readings", "linear solve", "Jacobian rule"),
    *("ODE solver", "optimiser loop", "objective", "stability", "other", "(no stack)"),
)
LABELLED = ("bogie_jax", "lineax", "diffrax", "optimistix")  # packages named in file labels
WRAPPERS = ("equinox", "jax", "jaxlib")  # their frames are skipped: the caller is charged


def file_label(file: str, function: str) -> str | None:
    """`package/path.py` of a stack frame's file, its name outside packages, `None` for a
    wrapper frame (JAX, equinox)."""
    del function
    path = file.replace("\\", "/")
    for package in LABELLED + WRAPPERS:
        if f"/{package}/" in path:
            rel = package + "/" + path.rsplit(f"/{package}/", 1)[1]
            return None if package in WRAPPERS else rel
    return Path(path).name


def parts(per_file: dict[str, int]) -> dict[str, int]:
    """Instruction counts per file grouped into the parts of `PART_RULES`."""
    out: dict[str, int] = {}
    for label, count in per_file.items():
        part = next((part for prefix, part in PART_RULES if label.startswith(prefix)), "other")
        out[part] = out.get(part, 0) + count
    return out


def timed(fn):
    """`(result, wall s, cpu s)` of `fn()` (CPU time of this process, all threads)."""
    wall, cpu = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - wall, time.process_time() - cpu


def run_times(compiled, args, budget: float | None) -> dict:
    """First call, then up to 5 more within about `budget` seconds: their median (nothing run
    where `budget` is None: `--no-run`)."""
    if budget is None:
        return {"run_first_s": None, "run_s": None, "run_calls": None}
    call = lambda: jax.block_until_ready(compiled(*args))
    _, first, _ = timed(call)
    repeats = max(0, min(5, int(budget / max(first, 1e-6))))
    later = [timed(call)[1] for _ in range(repeats)]
    return {
        "run_first_s": first,
        "run_s": statistics.median(later) if later else first,
        "run_calls": len(later),
    }


def measure_program(name: str, budget: float) -> dict:
    """Build, trace, lower, compile, count and run one program (in this process)."""
    from _common import hlo_attribution, hlo_instruction_lines, mlir_op_count

    _, scenario, _ = PROGRAMS[name]
    kind = name.rstrip("0123456789") if not name.startswith("part_") else name
    (jitted, args), setup_s, _ = timed(lambda: BUILDERS[kind](scenario))
    traced, trace_s, _ = timed(lambda: jitted.trace(*args))
    lowered, lower_s, _ = timed(traced.lower)
    compiled, compile_s, compile_cpu_s = timed(lowered.compile)
    hlo = compiled.as_text()
    return {
        "setup_s": setup_s,
        "trace_s": trace_s,
        "lower_s": lower_s,
        "compile_s": compile_s,
        "compile_cpu_s": compile_cpu_s,
        "stablehlo_ops": mlir_op_count(lowered.as_text()),
        "hlo_instructions": len(hlo_instruction_lines(hlo)),
        "hlo_files": hlo_attribution(hlo, file_label),
        **run_times(compiled, args, budget),
    }


def child(name: str, result_path: str, repo: str | None, budget: float) -> None:
    """Entry point of a child process: measure `name`, write its JSON record."""
    if repo:
        sys.path.insert(0, repo)

    jax.config.update("jax_enable_x64", True)
    jax.config.update("jax_enable_compilation_cache", False)
    import bogie_jax

    record = {"bogie_jax_file": bogie_jax.__file__, "devices": jax.device_count()}
    record |= measure_program(name, budget)
    record["versions"] = {
        m: getattr(importlib.import_module(m), "__version__", "?")
        for m in ("jax", "jaxlib", "diffrax", "optimistix", "equinox", "lineax")
    }
    Path(result_path).write_text(json.dumps(record))


# ---------------------------------------------------------------- parent: schedule and tables


def child_env(repo: str | None, devices: int) -> dict:
    """The environment of a child: no persistent compilation cache, `devices` CPU devices,
    `repo` first on the import path."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("JAX_COMPILATION_CACHE")}
    env["JAX_ENABLE_COMPILATION_CACHE"] = "false"
    env.pop("XLA_FLAGS", None)
    if devices > 1:
        env["XLA_FLAGS"] = f"--xla_force_host_platform_device_count={devices}"
    if repo:
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [repo, env.get("PYTHONPATH")]))
    return env


def run_child(name: str, args) -> dict:
    """One program in a fresh interpreter; a failure or timeout becomes a failed record."""
    _, _, devices = PROGRAMS[name]
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "result.json"
        cmd = [sys.executable, str(Path(__file__).resolve()), "--child", name, "--result", str(out)]
        cmd += ["--run-budget", str(args.run_budget)] + (["--repo", args.repo] if args.repo else [])
        cmd += ["--no-run"] if args.no_run else []
        tic = time.perf_counter()
        try:
            proc = subprocess.run(
                cmd, env=child_env(args.repo, devices), capture_output=True, text=True,
                timeout=args.timeout,
            )  # fmt: skip
            error = (
                None if proc.returncode == 0 else f"exit {proc.returncode}: {proc.stderr[-2000:]}"
            )
        except subprocess.TimeoutExpired as exc:
            tail = (exc.stderr or b"")[-2000:]
            error = f"timeout after {args.timeout} s: " + (
                tail.decode(errors="replace") if isinstance(tail, bytes) else tail
            )
        record = json.loads(out.read_text()) if error is None and out.exists() else {}
    record |= {
        "program": name,
        "description": PROGRAMS[name][0],
        "ok": error is None and bool(record),
        "error": error,
        "wall_s": time.perf_counter() - tic,
        "load_before": load_before,
        "load_after": os.getloadavg(),
    }
    return record


def machine(repo: str | None) -> dict:
    """Facts of this machine and the measured checkout."""
    where = repo or str(HERE.parent)
    git = lambda *a: subprocess.run(
        ["git", "-C", where, *a], capture_output=True, text=True, check=False
    ).stdout.strip()
    return {
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "repo": where,
        "commit": git("rev-parse", "--short", "HEAD"),
        "dirty": bool(git("status", "--porcelain", "--", "bogie_jax")),
    }


def fmt(x, scale=1.0, digits=1):
    return "-" if x is None else f"{x * scale:.{digits}f}"


def program_table(records) -> str:
    rows = [
        "| program | trace s | lower s | compile s | compile cpu s | StableHLO ops "
        "| HLO instructions | run ms/call | load 1 min |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for r in records:
        load = f"{r['load_before'][0]:.1f} -> {r['load_after'][0]:.1f}"
        if not r["ok"]:
            rows.append(f"| {r['program']} | failed | | | | | | | {load} |")
            continue
        first = " (1st call)" if r["run_calls"] == 0 else ""
        rows.append(
            f"| {r['program']} | {fmt(r['trace_s'], digits=2)} | {fmt(r['lower_s'], digits=2)} "
            f"| {fmt(r['compile_s'])} | {fmt(r['compile_cpu_s'])} | {r['stablehlo_ops']} "
            f"| {r['hlo_instructions']} | {fmt(r['run_s'], 1e3, 2)}{first} | {load} |"
        )
    return "\n".join(rows)


def attribution_table(records) -> str:
    ok = [r for r in records if r["ok"]]
    grouped = {r["program"]: parts(r["hlo_files"]) for r in ok}
    used = [p for p in PARTS if any(g.get(p) for g in grouped.values())]
    rows = [
        "| program | " + " | ".join(used) + " |",
        "| --- |" + " ---: |" * len(used),
    ]
    for r in ok:
        count, total = grouped[r["program"]], r["hlo_instructions"]
        cells = [f"{count.get(p, 0)} ({100 * count.get(p, 0) / total:.0f} %)" for p in used]
        rows.append(f"| {r['program']} | " + " | ".join(cells) + " |")
    return "\n".join(rows)


def files_table(records, top: int = 12) -> str:
    """The files charged with the most instructions, per program (largest programs)."""
    big = sorted((r for r in records if r["ok"]), key=lambda r: -r["hlo_instructions"])[:4]
    out = []
    for r in big:
        out.append(f"**{r['program']}** ({r['hlo_instructions']} instructions): " + ", ".join(
            f"`{f}` {n}" for f, n in list(r["hlo_files"].items())[:top]
        ))  # fmt: skip
    return "\n\n".join(out)


def markdown(label: str, payload: dict) -> str:
    m, recs = payload["machine"], payload["records"]
    versions = next((r["versions"] for r in recs if r.get("versions")), {})
    failed = [r for r in recs if not r["ok"]]
    lines = [
        f"# Compile cost: `{label}` (commit {m['commit']}{', modified' if m['dirty'] else ''})",
        "",
        f"{m['date']}, {m['cpu_count']} CPUs, {m['platform']}; "
        + ", ".join(f"{k} {v}" for k, v in versions.items())
        + ". Each program in a fresh process, no compilation cache. Times in seconds "
        "(wall; compile also as CPU time of the process); run time: median of up to 5 calls "
        "after the first, within a budget (the first call where none fit). **The machine was "
        "shared** with other work: the load column gives the 1-minute load average before and "
        "after each program; on this 2-CPU machine a load above 2 inflates wall times.",
        "",
        *[f"- {note}" for note in payload.get("notes", [])],
        "",
        program_table(recs),
        "",
        "## Optimised HLO instructions by part",
        "",
        "Each instruction of the optimised HLO is charged to the innermost frame of its call "
        "stack outside JAX and equinox (XLA keeps a stack per instruction: `stack_frame_id`), "
        "and that frame's file to a part: vector field = `bogie_jax/model` (equations of "
        "motion, kinematics, suspension, `track_inputs`), `contact`, `params`; track evaluation "
        "= `bogie_jax/track`; sensor readings = `bogie_jax/measure`; linear solve = "
        "`_householder.py` and lineax; ODE solver = diffrax and `simulation.py`; "
        "optimiser loop = optimistix and the rest of `bogie_jax/identify` (queue, batch, "
        "statistics); objective = `bogie_jax/cost`, `gradients.py`. Jacobian rule = "
        "`identify/_jacobian.py`: under `jax.linearize` (optimistix's LM) the instructions of "
        "the forward-mode (tangent) solve keep only the stack of `JacobianResiduals`' JVP rule, "
        "so they cannot be split further; they are the tangent solve (vector field and ODE "
        "solver). (no stack): parameters, tuples, copies and loop plumbing that XLA creates "
        "without a source.",
        "",
        attribution_table(recs),
        "",
        "Files charged with the most instructions:",
        "",
        files_table(recs),
    ]
    if failed:
        lines += ["", "## Failed", ""]
        for r in failed:
            text = [x.strip() for x in r["error"].splitlines() if any(c.isalnum() for c in x)]
            lines.append(f"- `{r['program']}`: {text[0][:200]} ... {text[-1][-300:]}")
    return "\n".join(lines) + "\n"


def compare(labels: str) -> None:
    """Merge two labels' results into one before/after table (`results/compile/A_vs_B.md`)."""
    a, b = labels.split(",")
    payloads = {lab: json.loads((RESULTS / f"{lab}.json").read_text()) for lab in (a, b)}
    load = lambda lab: {r["program"]: r for r in payloads[lab]["records"]}
    ra, rb = load(a), load(b)
    value = lambda r, k: r[k] if r is not None and r.get("ok") else None
    ratio = lambda x, y: "-" if not x or y is None else f"{y / x:.2f}"
    rows = [
        f"| program | trace s {a} | {b} | ratio | compile s {a} | {b} | ratio "
        f"| compile cpu s {a} | {b} | ratio | HLO {a} | {b} | ratio | run ms {a} | {b} | ratio |",
        "| --- |" + " ---: |" * 15,
    ]
    for name in [*ra, *(n for n in rb if n not in ra)]:
        x, y = ra.get(name), rb.get(name)
        cells = []
        keys = ("trace_s", "compile_s", "compile_cpu_s", "hlo_instructions", "run_s")
        for key, scale in zip(keys, (1.0, 1.0, 1.0, 1.0, 1e3)):
            u, v = value(x, key), value(y, key)
            digits = 0 if key == "hlo_instructions" else 1
            cells += [fmt(u, scale, digits), fmt(v, scale, digits), ratio(u, v)]
        rows.append(f"| {name} | " + " | ".join(cells) + " |")
    where = "; ".join(
        f"`{lab}`: commit {p['machine']['commit']}, {p['machine']['date']}"
        for lab, p in payloads.items()
    )
    text = f"# Compile cost: `{a}` against `{b}` (ratio = {b} / {a})\n\n{where}.\n\n"
    text += "\n".join(rows) + "\n"
    (RESULTS / f"{a}_vs_{b}.md").write_text(text)
    print(text)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--label", default="all_programs")
    parser.add_argument("--programs", default=",".join(PROGRAMS), help="comma-separated names")
    parser.add_argument("--repo", default=None, help="checkout whose bogie_jax is measured")
    parser.add_argument("--timeout", type=float, default=900.0, help="per program [s]")
    parser.add_argument("--run-budget", type=float, default=20.0, help="timed calls [s]")
    parser.add_argument("--no-run", action="store_true", help="trace, lower, compile; no calls")
    parser.add_argument("--compare", default=None, help="A,B: merge two labels")
    parser.add_argument("--render", action="store_true", help="rewrite LABEL's .md from its .json")
    parser.add_argument("--child", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--result", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.repo:
        args.repo = str(Path(args.repo).resolve())
    if args.child:
        return child(args.child, args.result, args.repo, None if args.no_run else args.run_budget)
    if args.compare:
        return compare(args.compare)
    if args.render:
        payload = json.loads((RESULTS / f"{args.label}.json").read_text())
        return (RESULTS / f"{args.label}.md").write_text(markdown(args.label, payload))
    names = [n.strip() for n in args.programs.split(",") if n.strip()]
    unknown = [n for n in names if n not in PROGRAMS]
    if unknown:
        parser.error(f"unknown programs {unknown}; choose from {', '.join(PROGRAMS)}")
    RESULTS.mkdir(parents=True, exist_ok=True)
    payload = {"machine": machine(args.repo), "settings": vars(args), "records": []}
    for name in names:
        print(f"[{datetime.datetime.now():%H:%M:%S}] {name} ...", flush=True)
        record = run_child(name, args)
        payload["records"].append(record)
        status = f"compile {record['compile_s']:.1f} s" if record["ok"] else "FAILED"
        print(f"    {status}, {record['wall_s']:.0f} s in all", flush=True)
        # written after every program: an interrupted run keeps what it measured
        (RESULTS / f"{args.label}.json").write_text(json.dumps(payload, indent=2))
        (RESULTS / f"{args.label}.md").write_text(markdown(args.label, payload))
    print(markdown(args.label, payload))


if __name__ == "__main__":
    main()
