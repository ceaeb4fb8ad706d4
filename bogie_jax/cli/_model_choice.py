"""`--contact` (the wheel-rail contact the model uses) and `--fit-model` (the equations the
monitor fits), shared by the commands that take them.

`--contact` replaces the manchester set's 1:20 cone by a profile pair's contact table
(`bogie_jax.params.manchester_benchmark(contact=...)`): fit the profile model where the wheels
are real, since a cone cannot follow an S1002 wheel's contact (docs/benchmarks.md,
`real-profile`); `--wheel-profile` by a measured wheel's on the same rail, for a wheel that no
blend of the new and worn tables follows (`half-worn-profile`). `--fit-model nonlinear` fits
creep saturation and blow-off anti-yaw dampers (`bogie_jax.monitor.nonlinear_options`) where
the linear model leaves the data not explained.
"""

from ..contact import PROFILE_PAIRS, measured_wheel
from ..monitor import nonlinear_options
from ..params import PROFILE_SET, ModelOptions
from ._common import UsageError
from ._names import lookup


CONTACTS = ("cone", *PROFILE_PAIRS)
WEAR_CONTACT = "s1002-uic60"  # the pair whose table `--wear` blends towards the worn wheel
FIT_MODELS = {"linear": ModelOptions, "nonlinear": nonlinear_options}


def add_contact(p) -> None:
    """Add `--contact` to the parser `p`."""
    p.add_argument(
        "--contact",
        default="cone",
        choices=CONTACTS,
        help="wheel-rail contact of the manchester set (default cone 1:20; s1002-uic60: S1002 "
        "on UIC60 1:40; worn-uic60: a measured worn wheel on it; half-worn-uic60: a wheel "
        "halfway between the two)",
    )
    p.add_argument(
        "--wear",
        type=float,
        default=None,
        metavar="LEVEL",
        help="with --contact s1002-uic60: the wheels' wear level in (0, 1] (0 new, 1 the "
        "measured worn wheel; the contact tables blended); monitor fits it from this guess",
    )
    p.add_argument(
        "--wheel-profile",
        default=None,
        metavar="FILE",
        help="a measured wheel profile (.prw, or .csv of y, z in mm) on UIC60 1:40, in place of "
        "--contact (manchester set)",
    )
    p.add_argument(
        "--flange-back",
        type=float,
        default=-70.0,
        metavar="MM",
        help="--wheel-profile: y of the flange back in the file's frame [mm] (default -70, as "
        "the S1002 file; 0 where the file's origin is the flange back)",
    )


def add_fit_model(p) -> None:
    """Add `--fit-model` to the parser `p`."""
    p.add_argument(
        "--fit-model",
        default="linear",
        choices=tuple(FIT_MODELS),
        help="--data: the equations fitted (default linear, fitted again with the nonlinear "
        "model where it does not explain the data; nonlinear: creep saturation and blow-off "
        "anti-yaw dampers, several times slower)",
    )
    p.add_argument(
        "--no-model-refit",
        action="store_true",
        help="--data: keep the first fit where it does not explain the data (no fit of the "
        "nonlinear model there)",
    )


def params_with_contact(vehicle: str, args, *, vehicle_option: str):
    """The parameter set `vehicle` with the wheel-rail contact of `args` (`--contact`, or a
    measured wheel `--wheel-profile` at `--flange-back`) and the wheels' `--wear` level.

    **Raises:** `UsageError` for an unknown set, a profile contact on a set other than
    manchester (the one whose wheels the profile pairs fit), a wear level outside (0, 1] or
    without `--contact s1002-uic60`, or a wheel profile file that is not one (before any table
    is built)."""
    contact, wear = args.contact, args.wear
    if args.wheel_profile is not None:
        if contact != "cone" or wear is not None:
            raise UsageError("`--wheel-profile` takes the place of `--contact` and `--wear`")
        if not -500 <= args.flange_back <= 500:
            raise UsageError(f"`--flange-back` = {args.flange_back:g} mm must lie in [-500, 500]")
        try:
            contact = measured_wheel(args.wheel_profile, 1e-3 * args.flange_back)
        except ValueError as e:  # ProfileError: not a wheel profile, the flange back's range
            raise UsageError(f"`--wheel-profile`: {e}") from None
    make = lookup("vehicle", vehicle, vehicle_option)
    if wear is not None and contact != WEAR_CONTACT:
        raise UsageError(f"`--wear` needs `--contact {WEAR_CONTACT}`, got `--contact {contact}`")
    if wear is not None and not 0 < wear <= 1:
        raise UsageError(f"`--wear` = {wear!r} must lie in (0, 1]")
    if contact == "cone":
        return make()
    if vehicle != PROFILE_SET:
        raise UsageError(f"`--contact {contact}` needs `{vehicle_option} {PROFILE_SET}`")
    return make(contact=contact, wear=wear)


def fit_model(name: str) -> ModelOptions:
    """The `ModelOptions` that `--fit-model name` fits."""
    return FIT_MODELS[name]()
