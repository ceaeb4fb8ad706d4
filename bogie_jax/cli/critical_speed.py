"""`bogie-jax critical-speed`: the linear critical speed and hunting frequency of a bogie."""

import jax.numpy as jnp

from ..model import critical_speed, stability_sweep
from ..params import PARAMETER_SETS
from ..plot import plot_stability
from ._common import UsageError, require_suffix
from .simulate import add_vehicle


def add_parser(sub):
    p = sub.add_parser("critical-speed", help="linear critical speed and hunting frequency")
    add_vehicle(p)
    p.add_argument("--v-min", type=float, default=5.0, help="lowest speed swept [m/s]")
    p.add_argument("--v-max", type=float, default=150.0, help="highest speed swept [m/s]")
    p.add_argument("--plot", default=None, help="write max Re(eigenvalue) vs speed to this PNG")
    return p


def run(args, progress) -> int:
    if not (0 < args.v_min < args.v_max <= 300):
        raise UsageError(
            f"need 0 < `--v-min` < `--v-max` <= 300 m/s, got {args.v_min:g} and {args.v_max:g}"
        )
    require_suffix("--plot", args.plot, ".png")
    params = PARAMETER_SETS[args.params]()
    progress.compiling("the stability sweep")
    result = critical_speed(params, v_min=args.v_min, v_max=args.v_max)
    if bool(result.found):
        v, f = float(result.speed), float(result.frequency)
        progress.say(
            f"linear critical speed: {v:.2f} m/s ({3.6 * v:.1f} km/h), hunting frequency {f:.2f} Hz"
        )
    else:
        progress.say(
            f"stable over the whole range {args.v_min:g}-{args.v_max:g} m/s: no critical speed"
        )
    if args.plot:
        sweep = stability_sweep(params, jnp.linspace(args.v_min, args.v_max, 60))
        plot_stability(sweep, result).figure.savefig(args.plot, dpi=120)
        progress.say(f"wrote {args.plot}")
    return 0
