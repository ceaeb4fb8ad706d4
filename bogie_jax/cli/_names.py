"""The one table from command-line names to the library's objects.

Commands resolve every name here, at the boundary, and pass objects (not strings) to the
library: `lookup("--method", "lm")` is identify's Levenberg-Marquardt method object,
`lookup("--design", "sobol")` a `Sobol` design, `lookup("--track", "erri-low")` a spectrum.
"""

from ..identify import DESIGNS, LOCAL_METHODS, SCENARIOS
from ..monitor import COVARIANCES, DEFECT_SCENARIOS, NOISE_MODELS
from ..params import PARAMETER_SETS
from ..sensitivity import (
    LAYOUTS,
    fisher_information,
    profile_likelihood,
    sensitivity_sobol,
    sensitivity_sweeps,
)
from ..track import SPECTRA, spectrum_from_name
from ._common import UsageError


PERFECT = "perfect"

TABLE: dict[str, dict[str, object]] = {
    # named parameter sets: name -> a function returning `BogieParams`
    "vehicle": dict(PARAMETER_SETS),
    # identify: local method objects and start designs
    "method": dict(LOCAL_METHODS),
    "design": dict(DESIGNS),
    "scenario": dict(SCENARIOS),
    # demo: the defect scenarios of bogie_jax.monitor
    "defect": dict(DEFECT_SCENARIOS),
    # monitor: the noise model and the covariance rule (strategy objects)
    "noise": dict(NOISE_MODELS),
    "covariance": dict(COVARIANCES),
    # sensitivity: the analysis each `--method` runs
    "analysis": {
        "screening": sensitivity_sweeps,
        "sobol": sensitivity_sobol,
        "fim": fisher_information,
        "profile": profile_likelihood,
    },
    "sensors": {name: name for name in LAYOUTS},  # resolved per vehicle by `sensor_layouts`
    # track spectra (`perfect`: no irregularity)
    "track": {**{name: spectrum_from_name(name) for name in SPECTRA}, PERFECT: None},
}


def names(kind: str) -> tuple[str, ...]:
    """The command-line names of one kind of the table."""
    return tuple(TABLE[kind])


def lookup(kind: str, name: str, option: str | None = None):
    """The object named `name` of `kind`. **Raises:** `UsageError` listing the valid names."""
    try:
        return TABLE[kind][name]
    except KeyError:
        option = option or f"--{kind}"
        valid = ", ".join(TABLE[kind])
        message = f"unknown `{option}` {name!r}: `{option}` must be one of {valid}"
        raise UsageError(message) from None


def default_parameters() -> tuple[str, ...]:
    """The parameters of the default identification scenario (what `--params` defaults to)."""
    return tuple(TABLE["scenario"]["default"].offsets)
