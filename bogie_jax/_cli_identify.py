"""`bogie-jax identify`: multistart identification of bogie parameters from measured or
synthetic data.

Registered in `bogie_jax.cli` by `add_parser(subparsers)` and `COMMANDS["identify"] = run`.
The starts run in chunks of one compiled, vmapped and sharded batch each; after every chunk its
records are appended (and flushed) to `OUT/starts.jsonl`, so an interrupted run loses no finished
start, and `OUT/results.json` is written from what is finished.
"""

import json
import math
import sys
import time
from pathlib import Path


def add_parser(subparsers):
    """Add the `identify` subcommand to `subparsers` (from `ArgumentParser.add_subparsers`)."""
    p = subparsers.add_parser(
        "identify",
        help="identify suspension parameters (multistart least squares)",
        description="Identify the selected parameters by local fits from many space-filling "
        "starts inside their tolerance band (one vmapped batch per chunk of starts). Without "
        "--data or --scenario the 'default' synthetic scenario (known true parameters) is used.",
    )
    src = p.add_mutually_exclusive_group()
    src.add_argument("--data", default=None, help="measurement FILE.npz or FILE.csv (bogie_jax.io)")
    src.add_argument(
        "--scenario",
        default=None,
        help="synthetic scenario: default, primary3, primary6, all10 (default: default)",
    )
    p.add_argument(
        "--params",
        default=None,
        help="comma-separated names, e.g. primary.kz,yaw_dampers.c (default: the "
        "scenario's; see --list-params)",
    )
    p.add_argument("--starts", type=int, default=8, help="number of starts (default 8)")
    p.add_argument(
        "--method",
        default="lm",
        help="lm | gauss-newton | dogleg | bfgs | nelder-mead | pattern (default lm)",
    )
    p.add_argument("--design", default="lhs", help="start design: lhs | sobol (default lhs)")
    p.add_argument(
        "--chunk",
        type=int,
        default=None,
        help="starts per chunk (default: 2 per device); results are saved per chunk",
    )
    p.add_argument("--out", default="identify_out", help="output directory (default identify_out)")
    p.add_argument(
        "--list-params",
        action="store_true",
        help="print every parameter name with unit, nominal value and bounds, then exit",
    )
    p.add_argument(
        "--vehicle", default="manchester", help="named parameter set (default manchester)"
    )
    p.add_argument(
        "--noise",
        type=float,
        default=1.0,
        help="synthetic data: noise as a multiple of each sensor's noise std "
        "(default 1; 0 = noise-free)",
    )
    p.add_argument(
        "--seed", type=int, default=0, help="PRNG seed of the noise and the start design"
    )
    p.add_argument(
        "--duration",
        type=float,
        default=None,
        help="synthetic data: simulated time [s] (default: the scenario's)",
    )
    p.add_argument(
        "--band",
        type=float,
        default=0.5,
        help="tolerance band of the search, relative to nominal (default 0.5: +-50 %%)",
    )
    p.add_argument(
        "--rtol",
        type=float,
        default=1e-8,
        help="solver relative tolerance (atol = 1e-3 rtol; default 1e-8)",
    )
    p.add_argument(
        "--max-steps", type=int, default=100, help="local solver steps per start (default 100)"
    )
    p.add_argument(
        "--track",
        default=None,
        help="--data: track run over (erri-low | erri-high | fra-1..fra-6 | perfect | "
        "PATH.csv; default: the file's track reference 'NAME seed=N')",
    )
    p.add_argument("--no-plots", action="store_true", help="do not write the PNGs")
    return p


# --- validation ------------------------------------------------------------------------------


def _usage(message):
    from .cli import UsageError

    return UsageError(message)


def _split(text):
    return [t.strip() for t in text.split(",") if t.strip()]


def _check_args(args):
    from .identify import DESIGNS, LOCAL_METHODS
    from .identify._scenarios import SCENARIOS
    from .params import PARAMETER_SETS

    if args.vehicle not in PARAMETER_SETS:
        raise _usage(
            f"`--vehicle` must be one of {', '.join(sorted(PARAMETER_SETS))}, got {args.vehicle!r}"
        )
    if args.list_params:
        return
    if args.scenario is not None and args.scenario not in SCENARIOS:
        raise _usage(
            f"unknown `--scenario` {args.scenario!r}; choose one of {', '.join(SCENARIOS)}"
        )
    if not 1 <= args.starts <= 100_000:
        raise _usage(f"`--starts` must be in [1, 100000], got {args.starts}")
    if args.method not in LOCAL_METHODS:
        raise _usage(
            f"unknown `--method` {args.method!r}; choose one of {', '.join(LOCAL_METHODS)}"
        )
    if args.design not in DESIGNS:
        raise _usage(f"unknown `--design` {args.design!r}; choose one of {', '.join(DESIGNS)}")
    if args.chunk is not None and args.chunk < 1:
        raise _usage(f"`--chunk` must be >= 1, got {args.chunk}")
    if not (math.isfinite(args.noise) and args.noise >= 0):
        raise _usage(f"`--noise` must be >= 0, got {args.noise:g}")
    if args.duration is not None and not (0 < args.duration <= 60):
        raise _usage(f"`--duration` must be in (0, 60] s, got {args.duration:g}")
    if not 0 < args.band < 1:
        raise _usage(f"`--band` must be in (0, 1), got {args.band:g}")
    if not 0 < args.rtol < 1:
        raise _usage(f"`--rtol` must be in (0, 1), got {args.rtol:g}")
    if not 1 <= args.max_steps <= 100_000:
        raise _usage(f"`--max-steps` must be in [1, 100000], got {args.max_steps}")
    if args.data is not None and not Path(args.data).is_file():
        raise _usage(f"`--data` file {args.data!r} does not exist")
    if Path(args.out).exists() and not Path(args.out).is_dir():
        raise _usage(f"`--out` {args.out!r} exists and is not a directory")
    if args.params is not None and not _split(args.params):
        raise _usage(
            "`--params` is empty: give comma-separated parameter names (see --list-params)"
        )


# --- problem ---------------------------------------------------------------------------------


def list_params(vehicle="manchester", file=None) -> str:
    """The table printed by `--list-params`: name, unit, nominal value, plausible bounds."""
    import numpy as np

    from .cost import get_parameter
    from .params import PARAMETER_SETS, parameter_specs

    params = PARAMETER_SETS[vehicle]()
    rows = [("parameter", "unit", "nominal", "lower", "upper", "description")]
    for name, spec in parameter_specs(params).items():
        p0 = float(np.asarray(get_parameter(params, name)))
        rows.append(
            (
                name,
                spec.unit,
                f"{p0:.6g}",
                f"{spec.bounds[0]:.6g}",
                f"{spec.bounds[1]:.6g}",
                spec.doc,
            )
        )
    return _table(rows)


def _table(rows) -> str:
    widths = [max(len(str(r[i])) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(str(c).ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def _data_problem(args, names):
    import diffrax as dfx

    from ._tracks import run_track
    from .cost import make_objective
    from .identify._scenarios import SCENARIOS, tolerance_bounds
    from .io import load_measurement
    from .params import PARAMETER_SETS

    measurement = load_measurement(args.data)
    params = PARAMETER_SETS[args.vehicle]()
    names = names or tuple(SCENARIOS["default"].offsets)
    track_name, seed = args.track, args.seed
    if track_name is None:
        ref = measurement.track.split()
        track_name = ref[0] if ref else "erri-low"
        for item in ref[1:]:
            if item.startswith("seed="):
                seed = int(item[5:])
    duration = float(measurement.times[-1])
    track = run_track(
        track_name, params, seed=seed, speed=float(measurement.speed), duration=duration
    )
    controller = dfx.PIDController(rtol=args.rtol, atol=1e-3 * args.rtol)
    objective = make_objective(
        measurement,
        params,
        track,
        names,
        bounds=tolerance_bounds(params, names, args.band),
        stepsize_controller=controller,
        adjoint=dfx.ForwardMode(),
    )
    return objective, None, f"data {args.data} (track {track_name} seed={seed})"


def build_problem(args):
    """`(objective, truth or None, description)` from the parsed arguments."""
    import dataclasses

    import jax.random as jr

    from .identify._scenarios import as_scenario, scenario_problem

    names = tuple(_split(args.params)) if args.params is not None else None
    if args.data is not None:
        return _data_problem(args, names)
    sc = dataclasses.replace(as_scenario(args.scenario or "default"), band=args.band)
    key = None if args.noise == 0 else jr.PRNGKey(args.seed + 1)
    problem = scenario_problem(
        sc,
        names,
        key=key,
        noise_scale=args.noise or 1.0,
        duration=args.duration,
        rtol=args.rtol,
        vehicle=args.vehicle,
    )
    noise = "noise-free" if args.noise == 0 else f"noise x{args.noise:g}"
    desc = f"scenario {sc.name}: {problem.scenario.duration:g} s at {sc.speed:g} m/s, {noise}"
    return problem.objective, problem.truth, desc


# --- chunked multistart ----------------------------------------------------------------------


def _progress(done, total, chunk_result, elapsed):
    """Printed after every chunk (tests replace it to interrupt a run)."""
    import numpy as np

    costs = np.where(chunk_result.failed, np.inf, chunk_result.costs)
    print(
        f"  starts {done}/{total} done, chunk best cost {np.min(costs):.6g}, "
        f"{int(np.sum(chunk_result.failed))} failed, {elapsed:.1f} s",
        flush=True,
    )


def run_chunked(
    objective,
    *,
    key,
    n_starts,
    method="lm",
    design="lhs",
    chunk=None,
    max_steps=100,
    on_chunk=None,
    jsonl=None,
):
    """Multistart in chunks of `chunk` starts (one compiled batch, reused for every chunk).

    After each chunk, its records (with the global start `index`) are appended to the open file
    `jsonl` (flushed) and `on_chunk(done, total, chunk_result, elapsed)` is called. On
    `KeyboardInterrupt` the finished chunks are kept. **Returns** `(result, interrupted)`:
    a `MultistartResult` over the finished starts (`None` if none finished) and a flag.
    """
    import jax
    import jax.numpy as jnp

    from .batch import BatchResult
    from .identify._batched import batched_fits
    from .identify._multistart import collect, design_starts
    from .identify._problem import as_problem

    problem = as_problem(objective)
    thetas = design_starts(problem, key, n_starts, design)
    n_dev = jax.device_count()
    chunk = chunk or 2 * n_dev
    runner = batched_fits(objective, method, max_steps)  # compiled once per structure
    n_chunks = math.ceil(n_starts / chunk)
    padded = jnp.concatenate([thetas, jnp.repeat(thetas[-1:], n_chunks * chunk - n_starts, 0)])
    finished, interrupted = [], False
    tic = time.perf_counter()
    try:
        for k in range(n_chunks):
            lo, hi = k * chunk, min((k + 1) * chunk, n_starts)
            batch = runner(objective, padded[k * chunk : (k + 1) * chunk])
            batch = jax.tree.map(lambda x: x[: hi - lo], batch)
            finished.append(batch)
            part = collect(
                problem, thetas[lo:hi], batch, 0.0, cluster_tol=1e-4, bound_tol=1e-6, throw=False
            )
            if jsonl is not None:
                for i, rec in enumerate(part.records()):
                    jsonl.write(json.dumps({"index": lo + i, **rec}) + "\n")
                jsonl.flush()
            if on_chunk is not None:
                on_chunk(hi, n_starts, part, time.perf_counter() - tic)
    except KeyboardInterrupt:
        interrupted = True
    wall = time.perf_counter() - tic
    if not finished:
        return None, interrupted
    n_done = sum(b.failed.shape[0] for b in finished)
    merged = BatchResult(
        outputs=jax.tree.map(lambda *xs: jnp.concatenate(xs), *[b.outputs for b in finished]),
        failed=jnp.concatenate([b.failed for b in finished]),
    )
    result = collect(
        problem, thetas[:n_done], merged, wall, cluster_tol=1e-4, bound_tol=1e-6, throw=False
    )
    return result, interrupted


# --- reporting -------------------------------------------------------------------------------


def parameter_records(objective, result, truth):
    """`[{name, unit, true, nominal, estimate, ci95, std_error, on_bound}]` (JSON-ready)."""
    import numpy as np

    sel = objective.selection
    best = None if result is None else result.best
    out = []
    for i, (name, unit) in enumerate(zip(sel.names, sel.units)):
        est = None if best is None else float(best.estimates[i])
        ci = None if best is None else [float(v) for v in np.asarray(best.ci95[i])]
        out.append(
            dict(
                name=name,
                unit=unit,
                true=None if truth is None else float(truth[i]),
                nominal=float(sel.nominal[i]),
                lower=float(sel.lower[i]),
                upper=float(sel.upper[i]),
                estimate=est,
                ci95=ci,
                std_error=None if best is None else float(best.std_errors[i]),
                on_bound=None if best is None else bool(best.on_bound[i]),
            )
        )
    return out


def results_table(parameters) -> str:
    def f(x):
        return "-" if x is None else f"{x:.6g}"

    rows = [
        (
            "parameter",
            "true" if parameters and parameters[0]["true"] is not None else "nominal",
            "estimate",
            "95% interval",
            "unit",
        )
    ]
    for p in parameters:
        ref = p["true"] if p["true"] is not None else p["nominal"]
        ci = "-" if p["ci95"] is None else f"[{f(p['ci95'][0])}, {f(p['ci95'][1])}]"
        flag = " (on bound)" if p["on_bound"] else ""
        rows.append((p["name"], f(ref), f(p["estimate"]) + flag, ci, p["unit"]))
    return _table(rows)


def write_plots(out, result, parameters):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from ._plot_identify import plot_estimates, plot_waterfall

    paths = []
    ax = plot_waterfall(result.costs, failed=result.failed)
    ax.figure.savefig(out / "waterfall.png", dpi=110)
    plt.close(ax.figure)
    paths.append(out / "waterfall.png")
    if result.best is not None:
        truth = None if parameters[0]["true"] is None else np.array([p["true"] for p in parameters])
        ax = plot_estimates(
            [p["name"] for p in parameters],
            np.array([p["estimate"] for p in parameters]),
            np.array([p["ci95"] for p in parameters]),
            truth=truth,
            nominal=np.array([p["nominal"] for p in parameters]),
        )
        ax.figure.savefig(out / "estimates.png", dpi=110)
        plt.close(ax.figure)
        paths.append(out / "estimates.png")
    return paths


def run(args) -> int:
    """Run `bogie-jax identify` with parsed `args`; returns the exit code (130 if interrupted)."""
    import jax.random as jr

    _check_args(args)
    if args.list_params:
        print(list_params(args.vehicle))
        return 0
    try:
        objective, truth, desc = build_problem(args)
    except ValueError as e:  # unknown/empty names, bad data file (MeasurementError), bad track
        raise _usage(str(e)) from None
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    names = objective.selection.names
    print(f"identify {len(names)} parameters ({', '.join(names)}) from {desc}")
    print(
        f"{args.starts} starts ({args.design}), method {args.method}, results in {out}/", flush=True
    )
    with open(out / "starts.jsonl", "w") as jsonl:
        result, interrupted = run_chunked(
            objective,
            key=jr.PRNGKey(args.seed),
            n_starts=args.starts,
            method=args.method,
            design=args.design,
            chunk=args.chunk,
            max_steps=args.max_steps,
            on_chunk=_progress,
            jsonl=jsonl,
        )
    parameters = parameter_records(objective, result, truth)
    summary = dict(
        source=desc,
        method=args.method,
        design=args.design,
        n_starts=args.starts,
        n_finished=0 if result is None else len(result.costs),
        interrupted=interrupted,
        wall_time=None if result is None else result.wall_time,
        best_cost=None if result is None or result.best is None else float(result.best.cost),
        parameters=parameters,
        correlation=None
        if result is None or result.best is None
        else [[float(v) for v in row] for row in result.best.correlation],
        clusters=[]
        if result is None
        else [
            dict(
                estimates=c.estimates.tolist(), cost=c.cost, count=c.count, members=list(c.members)
            )
            for c in result.clusters
        ],
        starts=[]
        if result is None
        else [dict(index=i, **r) for i, r in enumerate(result.records())],
    )
    (out / "results.json").write_text(json.dumps(summary, indent=1))
    if interrupted:
        print(
            f"interrupted: {summary['n_finished']} of {args.starts} starts finished and saved",
            file=sys.stderr,
        )
    if result is None:
        print(f"wrote {out / 'results.json'} (no start finished)")
        return 130
    n_fail = int(result.failed.sum())
    print(
        f"{len(result.clusters)} distinct minima; best reached by "
        f"{result.clusters[0].count if result.clusters else 0} of {len(result.costs)} starts; "
        f"{n_fail} failed; {result.wall_time:.1f} s"
    )
    print(results_table(parameters))
    print(f"wrote {out / 'results.json'}, {out / 'starts.jsonl'}")
    if not args.no_plots:
        paths = write_plots(out, result, parameters)
        print("wrote " + ", ".join(str(p) for p in paths))
    return 130 if interrupted else 0
