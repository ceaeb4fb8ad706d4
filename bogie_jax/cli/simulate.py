"""`bogie-jax simulate`: one run of a named bogie over a track, saved as .npz or .csv."""

import sys

from ..io import save_trajectory
from ..params import PARAMETER_SETS
from ..plot import plot_simulation
from ..simulation import check_simulation_inputs, simulate
from ._common import UsageError, require_suffix
from ._names import names
from ._track import TRACK_HELP, build_track, track_reference


def add_vehicle(p) -> None:
    """`--params NAME`: a named parameter set (argparse checks the choice)."""
    p.add_argument(
        "--params",
        default="manchester",
        choices=names("vehicle"),
        help="named parameter set (default manchester: Manchester benchmark vehicle 1 bogie)",
    )


def add_parser(sub):
    p = sub.add_parser("simulate", help="simulate the bogie on a track")
    add_vehicle(p)
    add = p.add_argument
    add("--speed", type=float, default=50.0, help="forward speed [m/s] (default 50)")
    add("--duration", type=float, default=5.0, help="simulated time [s] (default 5)")
    add("--track", default="erri-low", help=f"{TRACK_HELP} (default erri-low)")
    add("--seed", type=int, default=0, help="PRNG seed of the synthesised track")
    add("--sample-rate", type=float, default=200.0, help="output rate [Hz] (default 200)")
    add("--out", default="bogie_simulation.npz", help="output FILE.npz or FILE.csv")
    add("--plot", default=None, help="write a PNG of the run to this file")
    return p


def run(args, progress) -> int:
    require_suffix("--out", args.out, ".npz", ".csv")
    require_suffix("--plot", args.plot, ".png")
    params = PARAMETER_SETS[args.params]()
    try:
        check_simulation_inputs(args.speed, args.duration, args.sample_rate)
    except ValueError as e:
        raise UsageError(str(e)) from None
    reference = track_reference(
        args.track, params, seed=args.seed, speed=args.speed, duration=args.duration
    )
    track = build_track(reference)
    progress.compiling(f"the {args.duration:g} s simulation")
    try:
        trajectory = simulate(
            params,
            track,
            speed=args.speed,
            duration=args.duration,
            sample_rate=args.sample_rate,
            throw=False,  # a failed solve is reported below, in one line
        )
    except ValueError as e:
        raise UsageError(str(e)) from None
    if not bool(trajectory.successful):
        print(
            f"bogie-jax simulate: error: the solve failed ({trajectory.result}); "
            "try a shorter `--duration` or a lower `--speed`",
            file=sys.stderr,
        )
        return 1
    path = save_trajectory(args.out, trajectory)
    progress.say(
        f"simulated {args.duration:g} s at {args.speed:g} m/s on {reference.describe()}: "
        f"{int(trajectory.num_steps)} steps, {progress.elapsed():.1f} s, wrote {path}"
    )
    if args.plot:
        plot_simulation(trajectory).savefig(args.plot, dpi=120)
        progress.say(f"wrote {args.plot}")
    return 0
