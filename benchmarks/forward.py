"""Forward-model benchmark.

1. One run: 10 s at 50 m/s, 200 Hz output, rtol 1e-6 (atol 1e-8 on every state), ERRI-low
   track. JAX (Tsit5, after compilation; compile time reported separately) against
   `scipy.integrate.solve_ivp` RK45 and LSODA on the independent numpy twin of the same
   equations (`tests/reference/bogie_twin.py`), median of >= 5 runs, step and RHS-evaluation
   counts, and each method's error against a tight JAX reference (rtol 1e-10).
2. A batch of 64 solves (parameter sets with the primary lateral stiffness and the yaw damper
   varied +-20 %) through `runtime.batch.batch_runner`: on one device, sharded over the 2 CPU
   cores, against a Python loop of single jitted solves. Throughputs as ratios from one run.

3. `--contact`: the same single run with the S1002/UIC60 1:40 contact table against
   the cone: median time, compile time apart, steps, and the time ratio (target <= 1.5).

Run: `python benchmarks/forward.py` (writes results/forward/jax_vs_scipy_and_batch.{json,md});
`python benchmarks/forward.py --contact` writes results/forward/profile_vs_cone_contact.{json,md}.
"""

import os


os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=2")

import sys
import time
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)

import diffrax as dfx
import equinox as eqx
import jax.random as jr
import numpy as np
from scipy.integrate import solve_ivp

import bogie_jax as bj
from bogie_jax.params import get_parameter
from bogie_jax.runtime.batch import batch_runner
from bogie_jax.simulation import simulate
from bogie_jax.track import ERRIB176Spectrum, synthesise_track


sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks._common import median_time, write_outputs  # noqa: E402
from tests.reference.bogie_twin import BogieTwin  # noqa: E402
from tests.reference.track_twin import track_inputs_fn  # noqa: E402


SPEED, DURATION, RATE, RTOL, ATOL = 50.0, 10.0, 200.0, 1e-6, 1e-8
BATCH = 64


def controller(rtol=RTOL, atol=ATOL):
    return dfx.PIDController(rtol=rtol, atol=atol)


def jax_single(params, track):
    run = jax.jit(
        lambda p: simulate(
            p,
            track,
            speed=SPEED,
            duration=DURATION,
            sample_rate=RATE,
            stepsize_controller=controller(),
        )
    )
    t0 = time.perf_counter()
    out = jax.block_until_ready(run(params))
    first = time.perf_counter() - t0
    median, _ = median_time(lambda: jax.block_until_ready(run(params)), repeats=7)
    return out, median, first - median


def reference(params, track):
    run = jax.jit(
        lambda p: simulate(
            p,
            track,
            speed=SPEED,
            duration=DURATION,
            sample_rate=RATE,
            solver=dfx.Tsit5(),
            stepsize_controller=controller(1e-10, 1e-13),
            max_steps=2_000_000,
        )
    )
    return jax.block_until_ready(run(params))


def scipy_runs(params, track, ts):
    """RK45 and LSODA on the numpy twin, fed the same C2 spline track as the JAX model."""
    x_axles = [float(params.geometry.semi_wheelbase), -float(params.geometry.semi_wheelbase)]
    twin = BogieTwin(params, SPEED, track_inputs_fn(track, SPEED, x_axles))
    out = {}
    for method in ("RK45", "LSODA"):
        holder = {}

        def solve():
            holder["sol"] = solve_ivp(
                twin.rhs,
                (0.0, DURATION),
                np.zeros(20),
                method=method,
                t_eval=np.asarray(ts),
                rtol=RTOL,
                atol=ATOL,
            )

        median, _ = median_time(solve, repeats=5)
        out[method] = (holder["sol"], median)
    return out


def rel_error(q, q_ref):
    q, q_ref = np.asarray(q), np.asarray(q_ref)
    return float(np.max(np.abs(q - q_ref)) / np.max(np.abs(q_ref)))


def batch_members(params, key):
    scales = jr.uniform(key, (BATCH, 2), minval=0.8, maxval=1.2)
    ky = get_parameter(params, "primary.ky") * scales[:, 0]
    c = get_parameter(params, "yaw_dampers.c") * scales[:, 1]
    return ky, c


def batch_benchmark(params, track):
    def one(member):
        ky, c = member
        p = eqx.tree_at(lambda p: (p.primary.ky, p.yaw_dampers.c), params, (ky, c))
        traj = simulate(
            p,
            track,
            speed=SPEED,
            duration=DURATION,
            sample_rate=RATE,
            stepsize_controller=controller(),
            throw=False,
        )
        return traj.q[:, 6], traj.successful

    members = batch_members(params, jr.PRNGKey(1))
    single = jax.jit(one)
    jax.block_until_ready(single((members[0][0], members[1][0])))

    def loop():
        for i in range(BATCH):
            jax.block_until_ready(single((members[0][i], members[1][i])))

    loop_time, _ = median_time(loop, repeats=3)
    rows = {"loop": loop_time}
    for label, devices in (
        ("vmap, 1 device", jax.devices()[:1]),
        ("sharded, 2 devices", jax.devices()[:2]),
    ):
        run = batch_runner(one, devices=devices, failure_fn=lambda out: ~out[1])
        t0 = time.perf_counter()
        jax.block_until_ready(run(members).outputs)
        compile_time = time.perf_counter() - t0
        median, _ = median_time(lambda: jax.block_until_ready(run(members).outputs), repeats=3)
        rows[label] = median
        rows[label + " compile"] = compile_time - median
    return rows


def main():
    params = bj.manchester_benchmark()
    track = synthesise_track(
        ERRIB176Spectrum.low(), key=jr.PRNGKey(0), length=SPEED * DURATION + 100
    )
    out, jax_time, jax_compile = jax_single(params, track)
    ref = reference(params, track)
    scipy_out = scipy_runs(params, track, out.ts)
    records = [
        {
            "method": "JAX Tsit5 (diffrax)",
            "time_s": jax_time,
            "compile_s": jax_compile,
            "steps": int(out.num_steps),
            "rhs_evals": 6 * int(out.num_steps),
            "rel_error": rel_error(out.q, ref.q),
        }
    ]
    for method, (sol, t) in scipy_out.items():
        records.append(
            {
                "method": f"scipy {method} (numpy twin)",
                "time_s": t,
                "compile_s": 0.0,
                "steps": None,
                "rhs_evals": int(sol.nfev),
                "rel_error": rel_error(sol.y[:10].T, ref.q),
            }
        )
    fastest_scipy = min(t for _, t in scipy_out.values())
    batch = batch_benchmark(params, track)
    lines = [
        f"## Forward solve: {DURATION:g} s at {SPEED:g} m/s, {RATE:g} Hz, "
        f"rtol {RTOL:g}, atol {ATOL:g}",
        "",
        "| method | median time [s] | compile [s] | steps | RHS evals | rel. error vs rtol 1e-10 |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for r in records:
        lines.append(
            f"| {r['method']} | {r['time_s']:.3f} | {r['compile_s']:.1f} | {r['steps'] or '-'} | "
            f"{r['rhs_evals']} | {r['rel_error']:.1e} |"
        )
    lines += [
        "",
        f"JAX speed-up over the fastest scipy method: **{fastest_scipy / jax_time:.1f}x**",
        "",
        f"## Batch of {BATCH} solves (same run, throughput relative to a Python loop)",
        "",
        "| runner | time [s] | compile [s] | throughput vs loop |",
        "| --- | --- | --- | --- |",
        f"| Python loop of jitted solves | {batch['loop']:.2f} | - | 1.00 |",
    ]
    for label in ("vmap, 1 device", "sharded, 2 devices"):
        lines.append(
            f"| batch runner, {label} | {batch[label]:.2f} | {batch[label + ' compile']:.1f} | "
            f"{batch['loop'] / batch[label]:.2f} |"
        )
    write_outputs(
        "forward/jax_vs_scipy_and_batch",
        records,
        "\n".join(lines) + "\n",
        extra={"batch": batch, "speedup_vs_fastest_scipy": fastest_scipy / jax_time},
    )


def contact_case():
    """10 s at 50 m/s on the ERRI-low track: the cone against the S1002/UIC60 1:40 table."""
    track = synthesise_track(
        ERRIB176Spectrum.low(), key=jr.PRNGKey(0), length=SPEED * DURATION + 100
    )
    records = []
    for contact in ("cone", "s1002-uic60"):
        out, median, compile_s = jax_single(bj.manchester_benchmark(contact=contact), track)
        records.append(
            {
                "contact": contact,
                "time_s": median,
                "compile_s": compile_s,
                "steps": int(out.num_steps),
            }
        )
    cone, table = records
    ratio = table["time_s"] / cone["time_s"]
    per_step = ratio * cone["steps"] / table["steps"]
    lines = [
        f"## Contact geometry: one {DURATION:g} s run at {SPEED:g} m/s, {RATE:g} Hz, rtol {RTOL:g}",
        "",
        "| contact | median time [s] | compile [s] | steps |",
        "| --- | --- | --- | --- |",
        *(
            f"| {r['contact']} | {r['time_s']:.3f} | {r['compile_s']:.1f} | {r['steps']} |"
            for r in records
        ),
        "",
        f"Time ratio table / cone: **{ratio:.2f}** (target <= 1.5); per step {per_step:.2f}.",
    ]
    write_outputs(
        "forward/profile_vs_cone_contact",
        records,
        "\n".join(lines) + "\n",
        extra={"time_ratio": ratio, "time_per_step_ratio": per_step},
    )


if __name__ == "__main__":
    if "--contact" in sys.argv:
        contact_case()
    else:
        main()
