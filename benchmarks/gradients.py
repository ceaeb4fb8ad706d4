"""Gradient methods on the bogie objective (paper sections 5.2-5.3, figure 5): time per gradient
over one forward solve, error against a tight forward-mode reference, peak memory, for
n = 2, 5, 10, 20 and all 39 parameters; plus the residual Jacobian by forward and reverse mode.

Scenario: Manchester bogie at 50 m/s on an ERRI-low track, the default 13-channel layout sampled
at 200 Hz, noisy synthetic data from the nominal parameters; gradients are taken where every
parameter is 10 % above nominal (one physical point for all n, so one reference serves every n:
the n = 39 forward-mode gradient at rtol 1e-12, of which each n takes its components).

    python benchmarks/gradients.py                  # about 10-15 min on a 2-core CPU
    python benchmarks/gradients.py --ns 2,5 --duration 0.25 --repeats 3   # smoke run

Writes benchmarks/results/gradients/cost_by_parameter_count.json (a list of records),
`.md` (tables) and `.png` (gradient components by method at n = 10, and cost against n).
"""

import os


# Runtime checks turn into NaNs instead of host callbacks, so every compiled program can be
# stored in the persistent compilation cache (`--cache`): a rerun with the same directory loads
# the programs instead of compiling them (its compile column then shows load times).
os.environ.setdefault("EQX_ON_ERROR", "nan")

import argparse  # noqa: E402
import datetime  # noqa: E402
import importlib.metadata  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import diffrax as dfx  # noqa: E402
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import jax.random as jr  # noqa: E402
import numpy as np  # noqa: E402


jax.config.update("jax_enable_x64", True)

from bogie_jax import manchester_benchmark  # noqa: E402
from bogie_jax.cost import make_objective  # noqa: E402
from bogie_jax.gradients import (  # noqa: E402  # noqa: E402
    METHODS,
    compiled_residuals,
    gradient_report,
    jacobian_by_mode,
    median_time,
    reference_gradient,
    report_table,
)
from bogie_jax.measure import Measurement, synthetic_measurement  # noqa: E402
from bogie_jax.params import parameter_names  # noqa: E402
from bogie_jax.track import ERRIB176Spectrum, synthesise_track  # noqa: E402


# Suspension first (what a monitoring system identifies), then the rest in tree order.
PRIORITY = (
    "primary.kz",
    "yaw_dampers.c",
    "primary.ky",
    "primary.kx",
    "primary.cz",
    "primary.cy",
    "secondary.ky",
    "secondary.kz",
    "secondary.cy",
    "secondary.cz",
    "primary.cx",
    "secondary.kx",
    "contact.creep_factor",
    "contact.cone_slope",
    "masses.frame.mass",
    "masses.frame.izz",
    "masses.wheelset.mass",
    "masses.carbody_mass",
    "geometry.semi_wheelbase",
    "contact.wheel_radius",
)
RESULTS = Path(__file__).parent / "results" / "gradients"
STEM = "cost_by_parameter_count"


def _scenario(args):
    truth = manchester_benchmark()
    names = PRIORITY + tuple(n for n in parameter_names(truth) if n not in PRIORITY)
    at = jax.tree.map(lambda x: x * (1.0 + args.offset), truth)  # where gradients are taken
    length = args.speed * args.duration + 30.0
    track = synthesise_track(
        ERRIB176Spectrum.low(),
        key=jr.PRNGKey(args.seed),
        length=length,
        fade_length=5.0,
        start=-10.0,
    )
    controller = dfx.PIDController(rtol=args.rtol, atol=1e-3 * args.rtol)
    data = synthetic_measurement(
        truth,
        track,
        speed=args.speed,
        duration=args.duration,
        key=jr.PRNGKey(args.seed + 1),
        stepsize_controller=controller,
    )  # the track (faded in from -10 m) is not a TrackReference: none is stored
    return names, at, track, data, controller


def _objective(names, at, track, data, controller):
    return make_objective(data, at, track, names, stepsize_controller=controller)


def _jacobian_problem(names, at, track, data, controller, n):
    """A small problem for the residual Jacobian (reverse mode needs one pass per residual):
    two channels over the first 0.25 s."""
    keep = [data.channels.index(c) for c in ("frame_1L_y", "axlebox_1L_y")]
    rows = data.times <= 0.25 + 1e-12
    small = Measurement(
        times=data.times[rows],
        data=data.data[rows][:, keep],
        channels=[data.channels[i] for i in keep],
        units=[data.units[i] for i in keep],
        speed=data.speed,
        track=data.track,
        layout=data.layout,
    )
    return make_objective(small, at, track, names[:n], stepsize_controller=controller)


def _jacobian_records(objective, theta, repeats):
    out = []
    for mode in ("fwd", "rev"):
        first, t = median_time(
            lambda: jacobian_by_mode(objective, theta, mode=mode).jacobian, repeats
        )
        out.append(
            dict(
                method=f"jacobian-{mode}",
                mode=mode,
                n_params=objective.n_params,
                n_residuals=objective.n_residuals,
                time_s=t,
                compile_s=max(first - t, 0.0),
            )
        )
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--ns", default="2,5,10,20,39", help="numbers of parameters (39 = all)")
    p.add_argument("--methods", default="reverse,forward,backsolve,direct,fd-forward,fd-central")
    p.add_argument(
        "--costly-ns",
        default="2,20",
        help="n values at which backsolve and direct run (their compile + run time is "
        "the bulk of the benchmark); 'all' for every n",
    )
    p.add_argument(
        "--jacobian-n",
        type=int,
        default=5,
        help="n of the residual-Jacobian timing (2 channels, 0.25 s: 102 residuals)",
    )
    p.add_argument("--speed", type=float, default=50.0)
    p.add_argument("--duration", type=float, default=0.5)
    p.add_argument("--rtol", type=float, default=1e-6)
    p.add_argument("--offset", type=float, default=0.1)
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=str(RESULTS))
    p.add_argument(
        "--cache",
        default=None,
        help="persistent compilation cache directory (default: a new temporary one; "
        "with a used one, re-runs skip compiling and compile times are cache-load times)",
    )
    p.add_argument(
        "--update",
        action="store_true",
        help="re-measure only the given --ns/--methods and replace those records in "
        "the existing STEM.json (the rest is kept)",
    )
    args = p.parse_args(argv)
    cache = args.cache or tempfile.mkdtemp(prefix="bogie_jax_gradients_cache_")
    jax.config.update("jax_compilation_cache_dir", cache)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    ns = [int(n) for n in args.ns.split(",")]
    methods = args.methods.split(",")
    costly = set(ns) if args.costly_ns == "all" else {int(n) for n in args.costly_ns.split(",")}
    costly = {min(n, 39) for n in costly}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()

    names, at, track, data, controller = _scenario(args)
    n_all = len(names)
    full = _objective(names, at, track, data, controller)
    t = time.perf_counter()
    g_ref_all = np.asarray(reference_gradient(full, jnp.zeros(n_all)))
    print(
        f"reference (n={n_all}, forward mode, rtol 1e-12): {time.perf_counter() - t:.1f} s",
        flush=True,
    )

    records = []
    for n in ns:
        n = min(n, n_all)
        objective = full if n == n_all else _objective(names[:n], at, track, data, controller)
        chosen = [m for m in methods if m not in ("backsolve", "direct") or n in costly]
        rows = gradient_report(
            objective, jnp.zeros(n), methods=chosen, repeats=args.repeats, reference=g_ref_all[:n]
        )
        for r in rows:
            r["names"] = list(names[:n])
        records += rows
        print(report_table(rows), flush=True)
        _release_compiled()
        if n == args.jacobian_n:
            small = _jacobian_problem(names, at, track, data, controller, n)
            _, solve = median_time(lambda: compiled_residuals(small, jnp.zeros(n)), args.repeats)
            jac = _jacobian_records(small, jnp.zeros(n), max(1, min(args.repeats, 3)))
            for r in jac:
                r["time_ratio"] = r["time_s"] / solve
            records += jac
            print(jac, flush=True)
            _release_compiled()

    meta = dict(
        device=str(jax.devices()[0]),
        cpu_count=os.cpu_count(),
        jax=jax.__version__,
        diffrax=importlib.metadata.version("diffrax"),
        python=platform.python_version(),
        commit=_commit(),
        date=datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d"),
        scenario=vars(args),
        n_residuals=full.n_residuals,
        total_s=time.perf_counter() - t_start,
    )
    for r in records:
        r["meta"] = meta
    if args.update:
        records = _merge(json.loads((out / f"{STEM}.json").read_text()), records)
    (out / f"{STEM}.json").write_text(json.dumps(records, indent=1))
    (out / f"{STEM}.md").write_text(_markdown(records, meta))
    _figure(records, out / f"{STEM}.png")
    print(f"wrote {out}/{STEM}.json, .md, .png in {meta['total_s']:.0f} s")
    return 0


def _merge(old, new):
    """`old` records with those of the same (method, n) replaced by `new` ones (each record
    keeps the `meta` of the run that measured it; time ratios are within-run)."""
    key = lambda r: (r["method"], r["n_params"])
    fresh = {key(r) for r in new}
    return [r for r in old if key(r) not in fresh] + new


def _release_compiled():
    """Drop compiled programs of the previous block: each holds JIT memory mappings, and a few
    dozen of these large programs in one process exhausted LLVM's section memory."""
    jax.clear_caches()


def _commit() -> str:
    try:
        return subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
            cwd=Path(__file__).parent,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return ""


SCENARIO_KEYS = ("speed", "duration", "rtol", "offset", "repeats", "seed")


def _markdown(records, meta) -> str:
    order = ["forward-solve", *METHODS]
    grads = sorted(
        (r for r in records if not r["method"].startswith("jacobian")),
        key=lambda r: (r["n_params"], order.index(r["method"])),
    )
    scenario = ", ".join(f"{k} {meta['scenario'][k]}" for k in SCENARIO_KEYS)
    lines = [
        f"# Gradient benchmark ({meta['device']}, {meta['cpu_count']} CPUs, jax {meta['jax']})",
        "",
        f"{meta['n_residuals']} residuals (13 channels, 200 Hz); {scenario}. Time / forward "
        "solve: median over the calls of each gradient's time over that of a forward solve "
        "timed right before it; compile: first call minus median; rel. error: against forward "
        "mode at rtol 1e-12.",
        "",
        "Runs (each record keeps its run's settings in the JSON): "
        + "; ".join(
            f"commit {m['commit']}, {m.get('date', 'date not recorded')}: "
            f"{', '.join(sorted({r['method'] for r in records if r['meta'] == m}))}"
            f" ({m['total_s']:.0f} s)"
            for m in _distinct(r["meta"] for r in records)
        ),
        "",
        report_table(grads),
        "",
        "| residual Jacobian | n | residuals | time [s] | time / forward solve |",
        "| --- | ---: | ---: | ---: | ---: |",
    ]
    for r in records:
        if r["method"].startswith("jacobian"):
            lines.append(
                f"| {r['mode']} | {r['n_params']} | {r['n_residuals']} | {r['time_s']:.3f} | "
                f"{r['time_ratio']:.1f} |"
            )
    return "\n".join(lines) + "\n"


def _distinct(metas):
    out = []
    for m in metas:
        if m not in out:
            out.append(m)
    return out


def _figure(records, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bogie_jax.plot import plot_gradient_components, plot_gradient_cost

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(15, 5), gridspec_kw={"width_ratios": [1.6, 1]})
    grads = [r for r in records if r.get("grad") is not None]
    n_show = 10 if any(r["n_params"] == 10 for r in grads) else max(r["n_params"] for r in grads)
    shown = [r for r in grads if r["n_params"] == n_show]
    plot_gradient_components(shown, shown[0]["names"], ax=ax1)
    ax1.set_title(f"gradient components by method (n = {n_show})")
    plot_gradient_cost([r for r in records if not r["method"].startswith("jacobian")], ax=ax2)
    ax2.set_title("cost of one gradient")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    sys.exit(main())
