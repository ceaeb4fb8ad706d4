"""`bogie-jax critical-speed`: the linear critical speed and hunting frequency of a bogie, and
where a hunting limit cycle dies on a speed ramp-down (the nonlinear critical speed)."""

import math

import jax.numpy as jnp

from ..hunting import ramp_from_linear
from ..model import critical_speed, stability_sweep
from ..plot import plot_stability
from ._common import UsageError, require_suffix
from ._model_choice import add_contact, params_with_contact
from .simulate import add_vehicle


def add_parser(sub):
    p = sub.add_parser("critical-speed", help="linear critical speed and hunting frequency")
    add_vehicle(p)
    p.add_argument("--v-min", type=float, default=5.0, help="lowest speed swept [m/s]")
    p.add_argument("--v-max", type=float, default=150.0, help="highest speed swept [m/s]")
    p.add_argument("--plot", default=None, help="write max Re(eigenvalue) vs speed to this PNG")
    add_contact(p)
    p.add_argument(
        "--ramp-down",
        action="store_true",
        help="also lower the speed from a hunting limit cycle (saturated creep) in 0.5 m/s steps "
        "and say where it dies: the nonlinear critical speed (a few minutes)",
    )
    return p


def run(args, progress) -> int:
    if not (0 < args.v_min < args.v_max <= 300):
        raise UsageError(
            f"need 0 < `--v-min` < `--v-max` <= 300 m/s, got {args.v_min:g} and {args.v_max:g}"
        )
    require_suffix("--plot", args.plot, ".png")
    params = params_with_contact(args.params, args, vehicle_option="--params")
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
    if args.ramp_down:
        progress.compiling("the speed ramp-down")
        _say_ramp(progress, params, float(result.speed) if bool(result.found) else None)
    if args.plot:
        sweep = stability_sweep(params, jnp.linspace(args.v_min, args.v_max, 60))
        plot_stability(sweep, result).figure.savefig(args.plot, dpi=120)
        progress.say(f"wrote {args.plot}")
    return 0


def _say_ramp(progress, params, linear_speed) -> None:
    ramp = ramp_from_linear(params, linear_speed)
    lower, upper = ramp.dies_between()
    if math.isnan(lower):
        progress.say(
            f"speed ramp-down from {float(ramp.speeds[0]):.1f} m/s: no hunting cycle died on the"
            f" ramp (down to {float(ramp.speeds[-1]):.1f} m/s)"
        )
    else:
        progress.say(
            f"a hunting limit cycle (saturated creep) dies between {lower:.1f} and {upper:.1f} "
            f"m/s: the nonlinear critical speed"
        )
