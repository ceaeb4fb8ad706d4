"""`--track` and `--seed` -> a typed `TrackReference`, and the track it names."""

from ..io import load_track
from ..track import TrackReference
from ._common import UsageError
from ._names import names


TRACK_HELP = f"{' | '.join(names('track'))} | PATH.csv"


def track_reference(name: str, params, *, seed: int, speed: float, duration: float):
    """The reference of a track long enough for a run of `duration` [s] at `speed` [m/s] of
    the bogie `params`: a spectrum name, `perfect`, or a CSV file (`bogie_jax.io`)."""
    try:
        return TrackReference.for_run(
            name,
            seed=seed,
            speed=speed,
            duration=duration,
            wheelbase=2 * float(params.geometry.semi_wheelbase),
        )
    except ValueError as e:
        raise UsageError(str(e)) from None


def build_track(reference):
    """The `TrackIrregularity` of `reference` (a file is read by `bogie_jax.io.load_track`)."""
    try:
        return load_track(reference)
    except ValueError as e:
        raise UsageError(str(e)) from None
