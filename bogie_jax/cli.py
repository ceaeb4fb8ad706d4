"""`bogie-jax` command line: simulate, critical-speed, demo, gradcheck.

Every option has a default; `--help` gives units. Bad values get a one-line error and exit code 2.
"""

import argparse
import sys
from pathlib import Path

from . import _cli_identify, _cli_sensitivity


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message}\n")


class UsageError(Exception):
    """A bad command-line value (reported in one line, exit code 2)."""


def _build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="bogie-jax", description="Railway bogie dynamics and identification.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    sim = sub.add_parser("simulate", help="simulate the bogie on a track")
    _add_vehicle(sim)
    sim.add_argument("--speed", type=float, default=50.0, help="forward speed [m/s] (default 50)")
    sim.add_argument("--duration", type=float, default=5.0, help="simulated time [s] (default 5)")
    sim.add_argument(
        "--track",
        default="erri-low",
        help="erri-low | erri-high | fra-1..fra-6 | perfect | PATH.csv (default erri-low)",
    )
    sim.add_argument("--seed", type=int, default=0, help="PRNG seed of the synthesised track")
    sim.add_argument("--sample-rate", type=float, default=200.0, help="output rate [Hz] (default 200)")
    sim.add_argument("--out", default="bogie_simulation.npz", help="output FILE.npz or FILE.csv")
    sim.add_argument("--plot", default=None, help="write a PNG of the run to this file")

    crit = sub.add_parser("critical-speed", help="linear critical speed and hunting frequency")
    _add_vehicle(crit)
    crit.add_argument("--v-min", type=float, default=5.0, help="lowest speed swept [m/s]")
    crit.add_argument("--v-max", type=float, default=150.0, help="highest speed swept [m/s]")
    crit.add_argument("--plot", default=None, help="write max Re(eigenvalue) vs speed to this PNG")

    demo = sub.add_parser("demo", help="simulate the default bogie and write data and plots")
    demo.add_argument("--out", default="demo_out", help="output directory (default demo_out)")
    _add_gradcheck(sub)
    _cli_identify.add_parser(sub)
    _cli_sensitivity.add_parser(sub)
    return parser


def _add_gradcheck(sub):
    g = sub.add_parser(
        "gradcheck",
        help="compare gradient methods (AD modes, continuous adjoint, finite differences)",
        description="Synthetic data from the vehicle, the least-squares cost (paper eq. 12) over "
        "the selected parameters, and every gradient method timed against one forward solve, "
        "with its error against a forward-mode reference at rtol 1e-12.",
    )
    add = g.add_argument
    add("--params", required=True,
        help="comma-separated parameter names (e.g. primary.kz,yaw_dampers.c) or 'all'")
    add("--json", required=True, help="write the records (a JSON list) to this file")
    add("--vehicle", default="manchester", help="named parameter set (default manchester)")
    add("--methods", default="all", help="comma-separated methods or 'all' "
        "(reverse, backsolve, forward, direct, fd-forward, fd-central)")
    add("--speed", type=float, default=50.0, help="forward speed [m/s] (default 50)")
    add("--duration", type=float, default=1.0, help="simulated time [s] (default 1)")
    add("--sample-rate", type=float, default=200.0, help="sample rate [Hz] (default 200)")
    add("--track", default="erri-low",
        help="erri-low | erri-high | fra-1..fra-6 | perfect | PATH.csv (default erri-low)")
    add("--seed", type=int, default=0, help="PRNG seed of track and measurement noise")
    add("--offset", type=float, default=0.1, help="relative offset from the true parameters "
        "at which the gradients are taken (default 0.1)")
    add("--rtol", type=float, default=1e-6, help="solver relative tolerance (default 1e-6)")
    add("--repeats", type=int, default=5, help="timed calls per method (median; default 5)")
    add("--plot", default=None, help="write the gradient components by method to this PNG")


def _add_vehicle(p):
    from .params import PARAMETER_SETS

    p.add_argument(
        "--params",
        default="manchester",
        choices=sorted(PARAMETER_SETS),
        help="named parameter set (default manchester: Manchester benchmark vehicle 1 bogie)",
    )


def _simulate(args) -> int:
    import matplotlib

    matplotlib.use("Agg")
    from ._tracks import run_track
    from .io import save_trajectory
    from .params import PARAMETER_SETS
    from .plot import plot_simulation
    from .simulate import check_simulation_inputs, simulate

    if not args.out.lower().endswith((".npz", ".csv")):
        raise UsageError(f"`--out` must end in .npz or .csv, got {args.out!r}")
    if args.plot is not None and not args.plot.lower().endswith(".png"):
        raise UsageError(f"`--plot` must end in .png, got {args.plot!r}")
    params = PARAMETER_SETS[args.params]()
    try:
        check_simulation_inputs(args.speed, args.duration, args.sample_rate)
        track = run_track(
            args.track, params, seed=args.seed, speed=args.speed, duration=args.duration
        )
        trajectory = simulate(
            params, track, speed=args.speed, duration=args.duration, sample_rate=args.sample_rate
        )
    except ValueError as e:
        raise UsageError(str(e)) from None
    path = save_trajectory(args.out, trajectory)
    print(f"simulated {args.duration:g} s at {args.speed:g} m/s on {args.track}: "
          f"{int(trajectory.num_steps)} steps, wrote {path}")
    if args.plot:
        fig = plot_simulation(trajectory)
        fig.savefig(args.plot, dpi=120)
        print(f"wrote {args.plot}")
    return 0


def _critical_speed(args) -> int:
    import jax.numpy as jnp
    import matplotlib

    matplotlib.use("Agg")
    from .model import critical_speed, stability_sweep
    from .params import PARAMETER_SETS
    from .plot import plot_stability

    if not (0 < args.v_min < args.v_max <= 300):
        raise UsageError(
            f"need 0 < `--v-min` < `--v-max` <= 300 m/s, got {args.v_min:g} and {args.v_max:g}"
        )
    params = PARAMETER_SETS[args.params]()
    result = critical_speed(params, v_min=args.v_min, v_max=args.v_max)
    if bool(result.found):
        print(f"linear critical speed: {float(result.speed):.2f} m/s "
              f"({3.6 * float(result.speed):.1f} km/h), hunting frequency {float(result.frequency):.2f} Hz")
    else:
        print(f"stable over the whole range {args.v_min:g}-{args.v_max:g} m/s: no critical speed")
    if args.plot:
        sweep = stability_sweep(params, jnp.linspace(args.v_min, args.v_max, 60))
        ax = plot_stability(sweep, result)
        ax.figure.savefig(args.plot, dpi=120)
        print(f"wrote {args.plot}")
    return 0


def _demo(args) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    sim_args = argparse.Namespace(
        params="manchester", speed=50.0, duration=5.0, track="erri-low", seed=0,
        sample_rate=200.0, out=str(out / "simulation.npz"), plot=str(out / "simulation.png"),
    )
    _simulate(sim_args)
    crit_args = argparse.Namespace(
        params="manchester", v_min=5.0, v_max=150.0, plot=str(out / "stability.png")
    )
    return _critical_speed(crit_args)


def _gradcheck(args) -> int:
    import json

    import diffrax as dfx
    import jax.random as jr
    import matplotlib

    matplotlib.use("Agg")
    from ._tracks import run_track
    from .cost import select_parameters, synthetic_objective
    from .gradients import METHODS, gradient_report, report_table
    from .params import PARAMETER_SETS, parameter_names
    from .plot import plot_gradient_components

    if args.vehicle not in PARAMETER_SETS:
        valid = ", ".join(sorted(PARAMETER_SETS))
        raise UsageError(f"`--vehicle` must be one of {valid}, got {args.vehicle!r}")
    if args.plot is not None and not args.plot.lower().endswith(".png"):
        raise UsageError(f"`--plot` must end in .png, got {args.plot!r}")
    if not (1 <= args.repeats <= 1000):
        raise UsageError(f"`--repeats` must be in [1, 1000], got {args.repeats}")
    if not (0 < args.rtol < 1):
        raise UsageError(f"`--rtol` must be in (0, 1), got {args.rtol:g}")
    params = PARAMETER_SETS[args.vehicle]()
    names = parameter_names(params) if args.params == "all" else _split(args.params)
    methods = METHODS if args.methods == "all" else _split(args.methods)
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise UsageError(f"unknown `--methods` {', '.join(unknown)}; valid: {', '.join(METHODS)}")
    try:
        select_parameters(params, names)  # names checked before anything is compiled
        track = run_track(
            args.track, params, seed=args.seed, speed=args.speed, duration=args.duration
        )
        objective, theta = synthetic_objective(
            params, track, names, speed=args.speed, duration=args.duration,
            sample_rate=args.sample_rate, key=jr.PRNGKey(args.seed + 1), offset=args.offset,
            track_name=f"{args.track} seed={args.seed}",
            stepsize_controller=dfx.PIDController(rtol=args.rtol, atol=1e-3 * args.rtol),
        )
    except ValueError as e:
        raise UsageError(str(e)) from None
    records = gradient_report(objective, theta, methods=methods, repeats=args.repeats)
    for r in records:
        r["names"] = list(objective.selection.names)
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(records, indent=1))
    print(report_table(records))
    print(f"wrote {args.json}")
    if args.plot:
        ax = plot_gradient_components(records, objective.selection.names)
        ax.figure.savefig(args.plot, dpi=120)
        print(f"wrote {args.plot}")
    return 0


def _split(text: str) -> list[str]:
    return [t.strip() for t in text.split(",") if t.strip()]


COMMANDS = {
    "simulate": _simulate,
    "critical-speed": _critical_speed,
    "demo": _demo,
    "gradcheck": _gradcheck,
    "identify": _cli_identify.run,
    "sensitivity": _cli_sensitivity.run,
}


def main(argv=None) -> int:
    """Entry point of the `bogie-jax` console script; returns the exit code."""
    import jax

    jax.config.update("jax_enable_x64", True)
    args = _build_parser().parse_args(argv)
    try:
        return COMMANDS[args.command](args)
    except UsageError as e:
        print(f"bogie-jax {args.command}: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
