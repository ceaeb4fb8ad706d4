"""What real data get wrong, as functions that spoil synthetic data or the
information a fit is given, one imperfection each, for benchmarks and demos:

- (a) `recorded_track`: the fit's track is a recording car's measurement of the true one
  (per-channel recording error and a distance offset);
- (b) `with_speed_error`: the fit is told a speed `speed * (1 + error)`;
- (c) `with_sensor_bias`: every channel carries a constant bias the fit is not told;
- (d) `nonlinear_options`: the data come from the model with its nonlinear options on (creep
  saturation, blow-off anti-yaw dampers) while the fit uses the default linear model;
- (e) `with_channel_noise(..., declared=False)`: the noise of each channel is a fraction of that
  channel's RMS, while the sensor layout (whence the fit's weights 1 / noise_std^2) keeps the
  sensors' nominal noise levels; with `declared=True` the layout states the true levels;
- (f) `worn_wheels`: the true cone slope differs from the nominal one.

A channel's RMS is taken over every run given together (`channel_rms`): noise and bias are
properties of a sensor, the same on every run of one bogie, so runs judged together keep one
sensor layout (as `monitor` requires).
"""

import dataclasses
import math
from collections.abc import Sequence

import equinox as eqx
import jax.random as jr
import numpy as np
from jaxtyping import ArrayLike

from ..measure import Measurement, layout_description
from ..params import BogieParams, ModelOptions, get_parameter, set_parameters
from ..track import TrackIrregularity, TrackReference
from ._checks import as_measurements
from ._track_error import synthesis_error


ERROR_SEED_OFFSET = 1000
"""Seed of a track record's error realisation: the true track's seed + this."""
BIAS_REFERENCES = ("rms", "noise_std")


def recorded_track(
    reference: TrackReference, *, noise: float, offset: float, semi_distance: float
) -> TrackIrregularity:
    """The synthetic track of `reference` as a recording car measures it.

    The record is the true irregularity plus a recording error, positioned `offset` [m] wrong
    along the track: the record's irregularity at distance s is the true one at s + offset
    (its first sample lies at `s0 - offset`). The error is a second, independent realisation of
    the same spectrum (`TrackReference` with seed + `ERROR_SEED_OFFSET`, same length and band),
    scaled per channel to RMS `noise` [m] for alignment and level and `noise / (2
    semi_distance)` [rad] for the cross level (a level error of `noise` on each rail over the
    contact distance 2 b_0, `semi_distance` [m]): an error whose spectrum is shaped like the
    track's. `noise` = 0 and `offset` = 0 give the true track.

    **Raises:** `ValueError` for a `noise` that is not finite and >= 0, a non-finite `offset`,
    a `semi_distance` that is not > 0, or `noise` > 0 with a reference that is not synthetic.
    """
    if not (math.isfinite(noise) and noise >= 0):
        raise ValueError(f"`noise` = {noise!r} m must be finite and >= 0")
    if not math.isfinite(offset):
        raise ValueError(f"`offset` = {offset!r} m must be finite")
    if not semi_distance > 0:
        raise ValueError(f"`semi_distance` = {semi_distance!r} m must be > 0")
    if noise > 0 and reference.spectrum in (None, "perfect"):
        raise ValueError(
            f"`noise` = {noise!r} m > 0 needs a `reference` with a synthetic spectrum, got "
            f"{reference.describe()!r} (a measured or perfect track has no error realisation)"
        )
    true = reference.build()
    values = np.asarray(true.values, dtype=float)
    if noise > 0:
        values = values + synthesis_error(
            reference, reference.seed + ERROR_SEED_OFFSET, noise, semi_distance
        )
    return TrackIrregularity(
        float(np.asarray(true.s0)) - offset, float(np.asarray(true.ds)), values
    )


def with_speed_error(measurement: Measurement, error: float) -> Measurement:
    """`measurement` stating the speed `speed * (1 + error)` [m/s] (error finite, > -1) while
    its data ran at `speed`; everything else unchanged."""
    if not (math.isfinite(error) and error > -1):
        raise ValueError(f"`error` = {error!r} must be finite and > -1 (a relative speed error)")
    speed = float(np.asarray(measurement.speed)) * (1.0 + error)
    return eqx.tree_at(lambda m: m.speed, measurement, np.asarray(speed))


def channel_rms(measurements: Sequence[Measurement]) -> np.ndarray:
    """(c,) RMS about zero of each channel over all `measurements` (one channel list), NaN
    samples left out."""
    measurements = _runs(measurements)
    data = np.concatenate([np.asarray(m.data, dtype=float) for m in measurements])
    return np.sqrt(np.nanmean(data**2, axis=0))


def with_sensor_bias(
    measurements: Sequence[Measurement], fraction: ArrayLike, *, relative_to: str = "rms"
) -> tuple[Measurement, ...]:
    """`measurements` with a constant bias added to each channel, the same on every run;
    the sensor layout is unchanged, so a fit is not told of the bias.

    Bias of channel c = `fraction[c]` times, with `relative_to="rms"`, the channel's RMS over all
    runs (`channel_rms`), or, with `"noise_std"`, the `noise_std` of its sensor in the layout.
    `fraction`: a number (every channel) or one signed number per channel.

    **Raises:** `ValueError` for a non-finite `fraction` or one of the wrong length, an unknown
    `relative_to`, or measurements of different channels.
    """
    measurements = _runs(measurements)
    if relative_to not in BIAS_REFERENCES:
        raise ValueError(
            f"`relative_to` = {relative_to!r} must be one of {', '.join(BIAS_REFERENCES)}"
        )
    frac = _per_channel(fraction, measurements[0], "fraction", minimum=-math.inf)
    if relative_to == "rms":
        scale = channel_rms(measurements)
    else:
        scale = np.array([float(s.noise_std) for s in measurements[0].sensors()])
    bias = frac * scale
    return tuple(
        eqx.tree_at(lambda m: m.data, m, np.asarray(m.data, dtype=float) + bias)
        for m in measurements
    )


def with_channel_noise(
    measurements: Sequence[Measurement],
    fraction: ArrayLike,
    *,
    key,
    declared: bool = True,
) -> tuple[Measurement, ...]:
    """`measurements` (best noise-free) plus Gaussian noise of standard deviation `fraction[c]`
    times channel c's RMS over all runs (`channel_rms`): the same noise level on every run,
    independent samples (run k draws from `jax.random.fold_in(key, k)`).

    - `declared=True`: the sensor layout states these noise levels (each sensor's `noise_std`
      set to its channel's level), so a fit weights every channel right;
    - `declared=False`: the layout keeps the sensors' nominal `noise_std`, so weights
      1 / noise_std^2 that assume it are wrong by the ratio of the levels.

    `fraction`: a number (every channel) or one number per channel, each >= 0; 0.02 is noise
    of 2 % of each channel's RMS.

    **Raises:** `ValueError` for a negative or non-finite `fraction`, one of the wrong length,
    measurements of different channels or without a sensor layout, or, with `declared=True`, a
    channel whose noise level would be 0 (a sensor's `noise_std` must be > 0).
    """
    measurements = _runs(measurements)
    frac = _per_channel(fraction, measurements[0], "fraction", minimum=0.0)
    std = frac * channel_rms(measurements)
    layout = measurements[0].layout
    if declared:
        bad = [name for name, s in zip(measurements[0].channels, std) if not s > 0]
        if bad:
            raise ValueError(
                f"`declared=True` needs a noise level > 0 on every channel; zero (a zero "
                f"`fraction` or RMS) on {', '.join(bad)}"
            )
        sensors = {s.name: s for s in measurements[0].sensors()}
        for name, s in zip(measurements[0].channels, std):
            sensors[name] = eqx.tree_at(lambda x: x.noise_std, sensors[name], np.asarray(s))
        layout = layout_description(tuple(sensors.values()))
    out = []
    for k, m in enumerate(measurements):
        data = np.asarray(m.data, dtype=float)
        noise = np.asarray(jr.normal(jr.fold_in(key, k), data.shape, dtype=float))
        out.append(dataclasses.replace(m, data=data + std * noise, layout=layout))
    return tuple(out)


def worn_wheels(params: BogieParams, factor: float) -> BogieParams:
    """`params` with the cone slope `contact.cone_slope` times `factor` (finite, > 0: worn
    wheels), every other parameter kept."""
    if not (math.isfinite(factor) and factor > 0):
        raise ValueError(f"`factor` = {factor!r} must be finite and > 0")
    slope = float(np.asarray(get_parameter(params, "contact.cone_slope")))
    return set_parameters(params, {"contact.cone_slope": slope * factor})


def nonlinear_options(
    *, creep_saturation: bool = True, nonlinear_dampers: bool = True, flange_contact: bool = False
) -> ModelOptions:
    """The `ModelOptions` of nonlinear data: creep saturation (Shen-Hedrick-Elkins)
    and blow-off anti-yaw dampers on by default, flange contact off (`ModelOptions`). Simulate
    the data with them and fit with the default `ModelOptions()`."""
    return ModelOptions(
        creep_saturation=creep_saturation,
        flange_contact=flange_contact,
        nonlinear_dampers=nonlinear_dampers,
    )


def _runs(measurements) -> tuple[Measurement, ...]:
    measurements = as_measurements(measurements)
    for k, m in enumerate(measurements):
        if m.channels != measurements[0].channels:
            raise ValueError(
                f"`measurements[{k}]` has channels {', '.join(m.channels)}, run 0 has "
                f"{', '.join(measurements[0].channels)}: give runs of one sensor layout"
            )
    return measurements


def _per_channel(value, measurement: Measurement, name: str, *, minimum: float) -> np.ndarray:
    n = len(measurement.channels)
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise ValueError(
            f"`{name}` has shape {arr.shape}: give a number or one per channel ({n} channels)"
        )
    if not (np.all(np.isfinite(arr)) and np.all(arr >= minimum)):
        valid = "finite" if minimum == -math.inf else f"finite and >= {minimum:g}"
        raise ValueError(f"`{name}` = {arr.tolist()!r} must be {valid}")
    return arr
