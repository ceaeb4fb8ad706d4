"""Synthetic monitoring cases shared by `detection.py` and `goodness_of_fit.py`: a bogie's runs
on random track sections, spoiled as real data are, and the fit's track records, built from a
case's draws (each script draws its own values; these functions only build).

Every run of a case has the same shape: the track long enough for the fastest run
(`track_length`), so one compiled simulation serves every case of a process.
"""

import jax.random as jr
import numpy as np

from bogie_jax.measure import synthetic_measurement
from bogie_jax.monitor import recorded_track, with_channel_noise, with_sensor_bias, with_speed_error
from bogie_jax.params import get_parameter
from bogie_jax.track import TrackIrregularity, TrackReference


WHEELBASE_MARGIN = 50.0  # [m] track beyond the longest run and the wheelbase


def value(params, name: str) -> float:
    """Parameter `name` of `params` as a float."""
    return float(np.asarray(get_parameter(params, name)))


def track_length(nominal, max_speed: float, duration: float) -> float:
    """[m] the track of every run: `duration` [s] at `max_speed` [m/s], plus the wheelbase (the
    rear wheelset runs behind) and `WHEELBASE_MARGIN`."""
    return max_speed * duration + 2.0 * value(nominal, "geometry.semi_wheelbase") + WHEELBASE_MARGIN


def track_references(spectrum: str, seeds, length: float) -> list[TrackReference]:
    """One synthetic track section per seed."""
    return [TrackReference(spectrum=spectrum, seed=int(s), length=length) for s in seeds]


def clean_runs(truth, refs, speeds, *, duration: float, sample_rate: float, model) -> list:
    """The noise-free measurements of `truth` (the default sensor layout) over each track
    `refs[k]` at `speeds[k]` [m/s], from rest at the track start, simulated with `model`
    (`ModelOptions`)."""
    return [
        synthetic_measurement(
            truth,
            ref.build(),
            speed=float(v),
            duration=duration,
            sample_rate=sample_rate,
            track_reference=ref,
            options=model,
        )  # fmt: skip
        for ref, v in zip(refs, speeds)
    ]


def spoiled_runs(
    clean, noise_fraction: float, noise_seed: int, *, declared=True, bias=None, speed_errors=None
) -> tuple:
    """`clean` with Gaussian noise of `noise_fraction` times each channel's RMS (stated in the
    layout where `declared`), then, where given, a constant bias per channel (`bias`: fractions
    of the channel's RMS) and a wrong stated speed per run (`speed_errors`: relative)."""
    runs = with_channel_noise(
        clean, noise_fraction, key=jr.PRNGKey(int(noise_seed)), declared=declared
    )
    if bias is not None:
        runs = with_sensor_bias(runs, bias)
    if speed_errors is not None:
        runs = tuple(with_speed_error(m, e) for m, e in zip(runs, speed_errors))
    return runs


def record_tracks(refs, *, noise: float, offsets, semi_distance: float, errors=None) -> list:
    """The fit's track of each run: `recorded_track` (an error shaped like the track of RMS
    `noise` [m], the record `offsets[k]` [m] along the track), plus, where `errors` is given,
    `errors[k]` `(n, 3)` (alignment [m], vertical [m], cross level [rad]) on the record's
    samples."""
    tracks = [
        recorded_track(ref, noise=noise, offset=float(off), semi_distance=semi_distance)
        for ref, off in zip(refs, offsets)
    ]
    if errors is None:
        return tracks
    out = []
    for track, error in zip(tracks, errors):
        values = np.asarray(track.values, dtype=float)
        if np.shape(error) != values.shape:
            raise ValueError(f"record error of shape {np.shape(error)}, record {values.shape}")
        out.append(
            TrackIrregularity(
                float(np.asarray(track.s0)), float(np.asarray(track.ds)), values + error
            )  # fmt: skip
        )
    return out
