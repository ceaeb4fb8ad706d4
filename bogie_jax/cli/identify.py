"""`bogie-jax identify`: multistart identification of bogie parameters from measured or
synthetic data.

The starts run in chunks of one compiled batch (`bogie_jax.identify.fit_multistart_chunked`);
after every chunk its records are appended to `OUT/starts.jsonl`, so an interrupted run loses no
finished start (`--resume` continues it), and `OUT/results.json` is written from what is
finished. With `--data`, the best start is then fitted again with the monitor's noise model
(`bogie_jax.identify.fit_noise_model`: the sensor bias removed, each channel's noise estimated
and the fit reweighted, the sandwich covariance), and its estimates and intervals are reported.
The end prints the wall time and the compile share.
"""

import dataclasses
import json
import math
import sys
from pathlib import Path

import jax
import jax.random as jr
import numpy as np

from ..cost import make_objective
from ..identify import (
    fit_multistart_chunked,
    fit_noise_model,
    scenario_problem,
    tolerance_bounds,
)
from ..io import load_measurement
from ..track import TrackReference
from ._common import UsageError, split_names
from ._identify_report import list_params, parameter_records, results_table, write_plots
from ._names import default_parameters, lookup, names
from ._track import TRACK_HELP, build_track, track_reference


def add_parser(subparsers):
    """Add the `identify` subcommand to `subparsers` (from `ArgumentParser.add_subparsers`)."""
    p = subparsers.add_parser(
        "identify",
        help="identify suspension parameters (multistart least squares)",
        description="Identify the selected parameters by local fits from many space-filling "
        "starts inside their tolerance band (one compiled batch per chunk of starts). Without "
        "--data or --scenario the 'default' synthetic scenario (known true parameters) is used.",
    )
    src = p.add_mutually_exclusive_group()
    src.add_argument("--data", default=None, help="measurement FILE.npz or FILE.csv (bogie_jax.io)")
    src.add_argument(
        "--scenario",
        default=None,
        help=f"synthetic scenario: {', '.join(names('scenario'))} (default: default)",
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
        help=f"{' | '.join(names('method'))} (default lm)",
    )
    p.add_argument(
        "--design", default="lhs", help=f"start design: {' | '.join(names('design'))} (default lhs)"
    )
    p.add_argument(
        "--chunk",
        type=int,
        default=None,
        help=(
            "starts per chunk (default: 2 per CPU device, one per fit in flight on an "
            "accelerator); results are saved per chunk"
        ),
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
        default=1e-6,
        help="ODE solver relative tolerance of the data and the fits (atol = 1e-3 rtol; "
        "default 1e-6, as the library's SolveSettings: atol 1e-9)",
    )
    p.add_argument(
        "--max-steps", type=int, default=100, help="local solver steps per start (default 100)"
    )
    p.add_argument(
        "--track",
        default=None,
        help=f"--data: track run over ({TRACK_HELP}; default: the file's track reference)",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="keep OUT/starts.jsonl of an interrupted run with the same settings and run only "
        "the starts it lacks",
    )
    p.add_argument("--no-plots", action="store_true", help="do not write the PNGs")
    return p


# --- validation ------------------------------------------------------------------------------


def _check_args(args):
    """Every check that needs no evaluation; returns the method and design objects."""
    lookup("vehicle", args.vehicle)
    if args.list_params:
        return None, None
    if args.scenario is not None:
        lookup("scenario", args.scenario)
    if not 1 <= args.starts <= 100_000:
        raise UsageError(f"`--starts` must be in [1, 100000], got {args.starts}")
    method, design = lookup("method", args.method), lookup("design", args.design)
    if args.chunk is not None and args.chunk < 1:
        raise UsageError(f"`--chunk` must be >= 1, got {args.chunk}")
    if not (math.isfinite(args.noise) and args.noise >= 0):
        raise UsageError(f"`--noise` must be >= 0, got {args.noise:g}")
    if args.duration is not None and not (0 < args.duration <= 60):
        raise UsageError(f"`--duration` must be in (0, 60] s, got {args.duration:g}")
    if not 0 < args.band < 1:
        raise UsageError(f"`--band` must be in (0, 1), got {args.band:g}")
    if not 0 < args.rtol < 1:
        raise UsageError(f"`--rtol` must be in (0, 1), got {args.rtol:g}")
    if not 1 <= args.max_steps <= 100_000:
        raise UsageError(f"`--max-steps` must be in [1, 100000], got {args.max_steps}")
    if args.data is not None and not Path(args.data).is_file():
        raise UsageError(f"`--data` file {args.data!r} does not exist")
    if Path(args.out).exists() and not Path(args.out).is_dir():
        raise UsageError(f"`--out` {args.out!r} exists and is not a directory")
    if args.params is not None and not split_names(args.params):
        raise UsageError(
            "`--params` is empty: give comma-separated parameter names (see --list-params)"
        )
    return method, design


# --- problem ---------------------------------------------------------------------------------


def _data_track(args, measurement, params) -> TrackReference:
    """`--track` for the file's run, else the track reference the file stores."""
    if args.track is not None:
        duration = float(measurement.times[-1])
        speed = float(measurement.speed)
        return track_reference(args.track, params, seed=args.seed, speed=speed, duration=duration)
    if measurement.track is None:
        raise UsageError(f"`--data` file {args.data!r} stores no track reference: give `--track`")
    return measurement.track


def _data_problem(args, names):
    import diffrax as dfx

    measurement = load_measurement(args.data)
    params = lookup("vehicle", args.vehicle)()
    names = names or default_parameters()
    reference = _data_track(args, measurement, params)
    objective = make_objective(
        measurement,
        params,
        build_track(reference),
        names,
        bounds=tolerance_bounds(params, names, args.band),
        stepsize_controller=dfx.PIDController(rtol=args.rtol, atol=1e-3 * args.rtol),
    )  # default adjoint: the fits switch the objective to forward mode themselves
    return objective, None, f"data {args.data} (track {reference.describe()})"


def build_problem(args):
    """`(objective, truth or None, description)` from the parsed arguments."""
    names = tuple(split_names(args.params)) if args.params is not None else None
    if args.data is not None:
        return _data_problem(args, names)
    sc = dataclasses.replace(lookup("scenario", args.scenario or "default"), band=args.band)
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


# --- run -------------------------------------------------------------------------------------


def _on_chunk(progress):
    """After every chunk: starts done / total, the chunk's best cost and failures, an ETA."""

    def report(chunk):
        costs = np.where(chunk.failed, np.inf, chunk.costs)
        note = f"chunk best cost {np.min(costs):.6g}, {int(np.sum(chunk.failed))} failed"
        progress.done(chunk.done, chunk.total, "starts", note, eta=chunk.eta())

    return report


def _summary(args, desc, run, parameters) -> dict:
    result = run.result
    best = None if result is None else result.best
    return dict(
        source=desc,
        method=args.method,
        design=args.design,
        n_starts=args.starts,
        n_finished=0 if result is None else len(result.costs),
        n_resumed=run.resumed,
        interrupted=run.interrupted,
        wall_time=run.wall_time,
        compile_time=run.compile_time,
        best_cost=None if best is None else float(best.cost),
        parameters=parameters,
        correlation=None if best is None else [[float(v) for v in row] for row in best.correlation],
        clusters=[]
        if result is None
        else [
            dict(
                estimates=c.estimates.tolist(),
                cost=c.cost,
                count=c.count,
                members=[run.indices[m] for m in c.members],
            )
            for c in result.clusters
        ],
        starts=[]
        if result is None
        else [dict(index=i, **r) for i, r in zip(run.indices, result.records())],
    )


def _noise_model(objective, best, parameters, progress) -> dict:
    """The best start fitted again with the monitor's noise model (module docstring); its
    estimates and intervals replace the start's in `parameters`; returns its summary."""
    progress.compiling("the fit with the noise model (sensor bias, per-channel noise)")
    model = fit_noise_model(objective, start=np.asarray(best.estimates))
    for p, est, se, ci in zip(parameters, model.estimates, model.std_errors, model.ci95):
        p.update(estimate=float(est), std_error=float(se), ci95=[float(v) for v in ci])
    noise = ", ".join(f"{x:.3g}" for x in model.channel_noise)
    progress.say(
        f"noise model: sensor bias removed, channel noise x stated [{noise}], {model.reweights} "
        f"refits, {model.covariance_rule} covariance ({model.status})"
    )
    return dict(
        status=model.status, noise=model.noise, covariance=model.covariance_rule,
        bias_removed=model.bias_removed, reweights=model.reweights,
        channel_noise=[float(x) for x in model.channel_noise],
        noise_variance=model.noise_variance, dof=model.dof, bandwidth=model.bandwidth,
    )  # fmt: skip


def run(args, progress) -> int:
    """Run `bogie-jax identify`; returns the exit code (130 if interrupted)."""
    method, design = _check_args(args)
    if args.list_params:
        progress.say(list_params(lookup("vehicle", args.vehicle)()))
        return 0
    source = "the data" if args.data is not None else "the synthetic measurement"
    progress.compiling(f"{source} and the objective")
    try:
        objective, truth, desc = build_problem(args)
        data_time = progress.elapsed()
    except ValueError as e:  # unknown/empty names, bad data file (MeasurementError), bad track
        raise UsageError(str(e)) from None
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    record = out / "starts.jsonl"
    if not args.resume:
        record.unlink(missing_ok=True)
    sel_names = objective.selection.names
    progress.say(f"identify {len(sel_names)} parameters ({', '.join(sel_names)}) from {desc}")
    progress.say(f"{args.starts} starts ({args.design}), method {args.method}, results in {out}/")

    def on_compile(width):
        per_device = math.ceil(width / jax.device_count())
        progress.compiling(
            f"the {width}-start {args.method.upper()} batch ({per_device} per device)"
        )

    try:
        chunked = fit_multistart_chunked(
            objective,
            key=jr.PRNGKey(args.seed),
            n_starts=args.starts,
            method=method,
            design=design,
            chunk=args.chunk,
            max_steps=args.max_steps,
            record=record,
            on_compile=on_compile,
            on_chunk=_on_chunk(progress),
        )
    except ValueError as e:  # a record of another run (--resume)
        raise UsageError(str(e)) from None
    if chunked.resumed:
        progress.say(f"resumed {chunked.resumed} finished starts from {record}")
    parameters = parameter_records(objective, chunked.result, truth)
    model = None
    if args.data is not None and chunked.result is not None and chunked.result.best is not None:
        model = _noise_model(objective, chunked.result.best, parameters, progress)
    summary = _summary(args, desc, chunked, parameters)
    if model is not None:
        summary["noise_model"] = model
    (out / "results.json").write_text(json.dumps(summary, indent=1))
    result = chunked.result
    if chunked.interrupted:
        print(
            f"interrupted: {summary['n_finished']} of {args.starts} starts finished and saved "
            f"(continue with --resume)",
            file=sys.stderr,
        )
    if result is None:
        progress.say(f"wrote {out / 'results.json'} (no start finished)")
        return 130
    n_fail = int(result.failed.sum())
    progress.say(
        f"{len(result.clusters)} distinct minima; best reached by "
        f"{result.clusters[0].count if result.clusters else 0} of {len(result.costs)} starts; "
        f"{n_fail} failed"
    )
    progress.say(results_table(parameters))
    progress.say(f"wrote {out / 'results.json'}, {record}")
    if not args.no_plots:
        paths = write_plots(out, result, parameters)
        progress.say("wrote " + ", ".join(str(p) for p in paths))
    total = progress.elapsed()
    share = chunked.compile_time / total if total > 0 else 0.0
    fits = chunked.wall_time - chunked.compile_time - chunked.statistics_time
    progress.say(
        f"total {total:.1f} s: compiling the batch {chunked.compile_time:.1f} s "
        f"({100 * share:.0f} %), data and objective {data_time:.1f} s, fits {fits:.1f} s, "
        f"statistics {chunked.statistics_time:.1f} s"
    )
    return 130 if chunked.interrupted else 0
