"""Named tracks for the command line and demos: spectrum names -> synthesised tracks."""

from pathlib import Path

import jax.random as jr

from .track import ERRIB176Spectrum, FRASpectrum, perfect_track, synthesise_track


def spectrum_from_name(name: str):
    """`erri-low`, `erri-high` or `fra-1` ... `fra-6` -> a track PSD."""
    if name == "erri-low":
        return ERRIB176Spectrum.low()
    if name == "erri-high":
        return ERRIB176Spectrum.high()
    if name.startswith("fra-") and name[4:].isdigit():
        return FRASpectrum.track_class(int(name[4:]))
    raise ValueError(
        f"`track` = {name!r} is not a known spectrum; valid: erri-low, erri-high, fra-1 .. fra-6, "
        "perfect, or a path to a .csv file"
    )


def track_from_name(name: str, *, seed: int, length: float):
    """A track from a spectrum name (synthesised with `seed` over `length` [m]), `perfect`, or a
    CSV path (format in `bogie_jax.io.load_track_csv`)."""
    if name == "perfect":
        return perfect_track()
    if name.lower().endswith(".csv"):
        from .io import load_track_csv

        if not Path(name).is_file():
            raise ValueError(f"`track` file {name!r} does not exist")
        return load_track_csv(name)
    psd = spectrum_from_name(name)
    return synthesise_track(psd, key=jr.PRNGKey(seed), length=length)


def run_track(name: str, params, *, seed: int, speed: float, duration: float):
    """`track_from_name` long enough for a run of `duration` [s] at `speed` [m/s]: the distance
    travelled plus the wheelbase (the rear wheelset runs `2 a` behind) and a 50 m margin."""
    margin = 2 * float(params.geometry.semi_wheelbase) + 50.0
    return track_from_name(name, seed=seed, length=speed * duration + margin)
