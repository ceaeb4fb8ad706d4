"""`--contact` (the wheel-rail contact the model uses) and `--fit-model` (the equations the
monitor fits), shared by the commands that take them.

`--contact` replaces the manchester set's 1:20 cone by a profile pair's contact table
(`bogie_jax.params.manchester_benchmark(contact=...)`): fit the profile model where the wheels
are real, since a cone cannot follow an S1002 wheel's contact (docs/benchmarks.md,
`real-profile`). `--fit-model nonlinear` fits creep saturation and blow-off anti-yaw dampers
(`bogie_jax.monitor.nonlinear_options`) where the linear model leaves the data not explained.
"""

from ..contact import PROFILE_PAIRS
from ..monitor import nonlinear_options
from ..params import ModelOptions
from ._common import UsageError
from ._names import lookup


CONTACTS = ("cone", *PROFILE_PAIRS)
PROFILE_SET = "manchester"  # the parameter set that carries the profile pairs
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


def add_fit_model(p) -> None:
    """Add `--fit-model` to the parser `p`."""
    p.add_argument(
        "--fit-model",
        default="linear",
        choices=tuple(FIT_MODELS),
        help="--data: the equations fitted (default linear; nonlinear: creep saturation and "
        "blow-off anti-yaw dampers, several times slower)",
    )


def params_with_contact(vehicle: str, contact: str, wear=None, *, vehicle_option: str):
    """The parameter set `vehicle` with the wheel-rail `contact` and the wheels' `wear` level
    (`None`: none).

    **Raises:** `UsageError` for an unknown set, a profile contact on a set other than
    manchester (the one whose wheels the profile pairs fit), or a wear level outside (0, 1] or
    without `--contact s1002-uic60`."""
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
