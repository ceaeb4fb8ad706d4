"""`bogie-jax gradcheck`: every gradient method of the cost timed against one forward solve."""

import json
from pathlib import Path

import diffrax as dfx
import jax.random as jr

from ..cost import select_parameters, synthetic_objective
from ..gradients import METHODS, gradient_report, reference_gradient, report_table
from ..params import parameter_names
from ..plot import plot_gradient_components
from ._common import UsageError, require_suffix, split_names
from ._names import default_parameters, lookup
from ._track import TRACK_HELP, build_track, track_reference


def add_parser(sub):
    g = sub.add_parser(
        "gradcheck",
        help="compare gradient methods (AD modes, continuous adjoint, finite differences)",
        description="Synthetic data from the vehicle, the least-squares cost (paper eq. 12) over "
        "the selected parameters, and every gradient method timed against one forward solve, "
        "with its error against a forward-mode reference at rtol 1e-12.",
    )
    add = g.add_argument
    add(
        "--params",
        default=None,
        help="comma-separated parameter names (e.g. "
        "primary.kz,yaw_dampers.c) or 'all' (default: the default identification scenario's, "
        f"{','.join(default_parameters())})",
    )
    add(
        "--json",
        default="gradcheck.json",
        help="write the records (a JSON list) to this file (default gradcheck.json)",
    )
    add("--vehicle", default="manchester", help="named parameter set (default manchester)")
    add("--methods", default="all", help=f"comma-separated methods or 'all' ({', '.join(METHODS)})")
    add("--speed", type=float, default=50.0, help="forward speed [m/s] (default 50)")
    add("--duration", type=float, default=1.0, help="simulated time [s] (default 1)")
    add("--sample-rate", type=float, default=200.0, help="sample rate [Hz] (default 200)")
    add("--track", default="erri-low", help=f"{TRACK_HELP} (default erri-low)")
    add("--seed", type=int, default=0, help="PRNG seed of track and measurement noise")
    add(
        "--offset",
        type=float,
        default=0.1,
        help="relative offset from the true parameters "
        "at which the gradients are taken (default 0.1)",
    )
    add("--rtol", type=float, default=1e-6, help="solver relative tolerance (default 1e-6)")
    add("--repeats", type=int, default=5, help="timed calls per method (median; default 5)")
    add("--plot", default=None, help="write the gradient components by method to this PNG")
    return g


def _check(args):
    """Every check that needs no evaluation; returns (params, names, methods)."""
    params = lookup("vehicle", args.vehicle)()
    require_suffix("--plot", args.plot, ".png")
    if not (1 <= args.repeats <= 1000):
        raise UsageError(f"`--repeats` must be in [1, 1000], got {args.repeats}")
    if not (0 < args.rtol < 1):
        raise UsageError(f"`--rtol` must be in (0, 1), got {args.rtol:g}")
    if args.params is None:
        names = list(default_parameters())
    else:
        names = parameter_names(params) if args.params == "all" else split_names(args.params)
    methods = METHODS if args.methods == "all" else split_names(args.methods)
    if not methods:
        raise UsageError("`--methods` is empty: give comma-separated methods or 'all'")
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise UsageError(f"unknown `--methods` {', '.join(unknown)}; valid: {', '.join(METHODS)}")
    try:
        select_parameters(params, names)  # names checked before anything is compiled
    except ValueError as e:
        raise UsageError(str(e)) from None
    return params, names, methods


def run(args, progress) -> int:
    params, names, methods = _check(args)
    reference = track_reference(
        args.track, params, seed=args.seed, speed=args.speed, duration=args.duration
    )
    track = build_track(reference)
    progress.say(f"gradients of the cost over {len(names)} parameters ({', '.join(names)})")
    progress.compiling("the synthetic measurement")
    try:
        objective, theta = synthetic_objective(
            params, track, names, speed=args.speed, duration=args.duration,
            sample_rate=args.sample_rate, key=jr.PRNGKey(args.seed + 1), offset=args.offset,
            track_reference=reference,
            stepsize_controller=dfx.PIDController(rtol=args.rtol, atol=1e-3 * args.rtol),
        )  # fmt: skip
    except ValueError as e:
        raise UsageError(str(e)) from None
    progress.compiling("the reference gradient (forward mode, rtol 1e-12)")
    g_ref = reference_gradient(objective, theta)
    records = []
    progress.start_work()
    for k, method in enumerate(methods, 1):
        progress.compiling(f"the {method} gradient")
        solve, record = gradient_report(
            objective, theta, methods=[method], repeats=args.repeats, reference=g_ref
        )
        records.extend([solve, record] if not records else [record])
        ratio, error = record["time_ratio"], record["rel_error"]
        note = f"{method}: {ratio:.2f} forward solves, error {error:.1e}"
        progress.done(k, len(methods), "methods", note)
    for r in records:
        r["names"] = list(objective.selection.names)
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(records, indent=1))
    progress.say(report_table(records))
    progress.say(f"wrote {args.json}")
    if args.plot:
        ax = plot_gradient_components(records, objective.selection.names)
        ax.figure.savefig(args.plot, dpi=120)
        progress.say(f"wrote {args.plot}")
    return 0
