"""`Measurement`: sampled channels of one run with their metadata; NaN marks a missing sample."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..track import TrackReference
from ._layout import sensors_from_layout


SAMPLE_RATE_RTOL = 1e-6  # relative tolerance on the sample spacing


class MeasurementError(ValueError):
    """Invalid measurement data (the message names the field, the value and what is valid)."""


def _as_float(x):
    return x if isinstance(x, jnp.ndarray) or hasattr(x, "aval") else np.asarray(x, dtype=float)


class Measurement(eqx.Module):
    """Measured (or synthetic) channels of one run at constant speed.

    - `times` (n,) [s]: strictly increasing, uniformly spaced (one sample rate);
    - `data` (n, c): channel values in `units`; NaN = missing sample (excluded from the cost);
    - `channels`, `units`: channel names and SI units (c each);
    - `speed` [m/s]; `track`: the `TrackReference` of the track run over, or `None` if
      unknown; `layout`: the sensor layout as JSON (`layout_description`), or "";
      `note`: free text (e.g. the track description of a file from before track references).
    - `start_position` [m]: track position of the bogie's reference point at the first sample
      (finite, >= 0; default 0: the record starts where the run started, at rest). A record cut
      out of a run that was already moving starts at `start_position` > 0, and the objective
      simulates a lead-in over the track before it (`bogie_jax.cost.make_objective`). The
      bogie moves at `speed`, so sample k lies at `start_position + speed * (times[k] -
      times[0])`; `times` may start anywhere (only their spacing is used). Like `speed` an
      array (not static): windows differing only in position share a compilation.

    `channels`, `units`, `track`, `layout` and `note` are static metadata: the cost layer reads
    them when it builds an objective and keeps none of them, so measurements differing only in
    metadata share the objective's compilation.
    """

    times: Float[Array, " n"] = eqx.field(converter=_as_float)
    data: Float[Array, "n c"] = eqx.field(converter=_as_float)
    channels: tuple[str, ...] = eqx.field(static=True, converter=tuple)
    units: tuple[str, ...] = eqx.field(static=True, converter=tuple)
    speed: Float[Array, ""] = eqx.field(converter=_as_float)
    track: TrackReference | None = eqx.field(default=None, static=True)
    layout: str = eqx.field(default="", static=True)
    note: str = eqx.field(default="", static=True)
    start_position: Float[Array, ""] = eqx.field(default=0.0, converter=_as_float)

    def __check_init__(self):
        check_measurement(self)

    @property
    def positions(self):
        """Track positions [m] (n,) of the samples: start_position + speed (times - times[0])."""
        t = jnp.asarray(self.times)
        return self.start_position + self.speed * (t - t[0])

    def window(self, start: float, duration: float) -> "Measurement":
        """The samples with times in [start, start + duration] [s] (times of this measurement,
        kept as they are), as a `Measurement` whose `start_position` [m] is the track position
        of its first sample: `self.start_position + speed * (t_first - times[0])`. Other
        metadata are kept. Use it to cut a record out of a longer run (`make_objective` then
        simulates a lead-in before it).

        **Raises:** `MeasurementError` naming `start` or `duration`, the value and the valid
        range (the window must lie inside the times and hold at least 2 samples).
        """
        times = np.asarray(self.times, dtype=float)
        t_first, t_last = float(times[0]), float(times[-1])
        step = (t_last - t_first) / (times.size - 1)
        tol = SAMPLE_RATE_RTOL * step
        start, duration = float(start), float(duration)
        if not (np.isfinite(start) and t_first - tol <= start <= t_last - step + tol):
            raise MeasurementError(
                f"`start` = {start:g} s is outside the valid range [{t_first:g}, "
                f"{t_last - step:g}] s of this measurement's times"
            )
        if not (np.isfinite(duration) and step - tol <= duration <= t_last - start + tol):
            raise MeasurementError(
                f"`duration` = {duration:g} s is outside the valid range [{step:g}, "
                f"{t_last - start:g}] s (at least 2 samples, inside the times from `start` = "
                f"{start:g} s)"
            )
        keep = (times >= start - tol) & (times <= start + duration + tol)
        first = int(np.argmax(keep))
        position = np.asarray(self.start_position, dtype=float) + np.asarray(
            self.speed, dtype=float
        ) * (times[first] - t_first)
        return Measurement(
            times=times[keep],
            data=np.asarray(self.data)[keep],
            channels=self.channels,
            units=self.units,
            speed=self.speed,
            track=self.track,
            layout=self.layout,
            note=self.note,
            start_position=position,
        )

    @property
    def sample_rate(self) -> float:
        """Samples per second [Hz] (from the concrete `times`)."""
        t = np.asarray(self.times)
        return float((t.size - 1) / (t[-1] - t[0]))

    @property
    def missing(self):
        """Boolean (n, c): True where a sample is missing (NaN)."""
        return jnp.isnan(self.data)

    def sensors(self):
        """The sensors of `layout` (in layout order). **Raises:** `ValueError` if there is none."""
        if not self.layout:
            raise MeasurementError(
                "this measurement has no sensor layout; pass `sensors` explicitly"
            )
        return sensors_from_layout(self.layout)

    def channel(self, name: str):
        """The data column (n,) of channel `name`."""
        if name not in self.channels:
            raise MeasurementError(
                f"unknown channel {name!r}; channels: {', '.join(self.channels)}"
            )
        return self.data[:, self.channels.index(name)]


def _concrete(x) -> bool:
    return not isinstance(x, jax.core.Tracer)


def check_measurement(m: Measurement, *, sample_rate: float | None = None) -> None:
    """Validate a measurement with concrete arrays; traced values are skipped.

    **Raises:** `MeasurementError` for wrong shapes, names or units, non-finite or non-monotone
    times, a non-uniform sample spacing or one that does not match `sample_rate` [Hz], channels
    missing from the layout, infinite data, a non-positive speed or a negative or non-finite
    `start_position`.
    """
    if not all(_concrete(x) for x in (m.times, m.data, m.speed, m.start_position)):
        return
    times, data = np.asarray(m.times), np.asarray(m.data)
    check_times(times, sample_rate)
    c = len(m.channels)
    if data.shape != (times.size, c):
        raise MeasurementError(
            f"`data` must have shape (n_times, n_channels) = ({times.size}, {c}), got {data.shape}"
        )
    if len(m.units) != c:
        raise MeasurementError(f"`units` has {len(m.units)} entries for {c} channels")
    _check_names(m.channels)
    if np.any(np.isinf(data)):
        i, j = np.argwhere(np.isinf(data))[0]
        raise MeasurementError(
            f"`data` must be finite or NaN (missing); got {data[i, j]} in channel "
            f"{m.channels[j]!r} at t = {times[i]:g} s"
        )
    if m.track is not None and not isinstance(m.track, TrackReference):
        raise MeasurementError(
            f"`track` must be a TrackReference or None, got {type(m.track).__name__} "
            f"{m.track!r} (free text belongs in `note`)"
        )
    speed = float(np.asarray(m.speed))
    if not (np.isfinite(speed) and speed > 0):
        raise MeasurementError(f"`speed` must be > 0 m/s, got {speed!r}")
    start = np.asarray(m.start_position)
    if start.shape != () or not (np.isfinite(start) and start >= 0):
        raise MeasurementError(
            f"`start_position` must be a finite scalar >= 0 m (the track position of the first "
            f"sample), got {start!r}"
        )
    if m.layout:
        check_channels_in_layout(m.channels, m.units, sensors_from_layout(m.layout))


def check_times(times: np.ndarray, sample_rate: float | None = None) -> None:
    """1-D, finite, strictly increasing, uniformly spaced; spacing 1/`sample_rate` if given."""
    if times.ndim != 1 or times.size < 2:
        raise MeasurementError(
            f"`times` must be 1-D with at least 2 samples, got shape {times.shape}"
        )
    if not np.all(np.isfinite(times)):
        raise MeasurementError(f"`times` must be finite; got {times[~np.isfinite(times)][0]!r}")
    steps = np.diff(times)
    bad = np.flatnonzero(steps <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise MeasurementError(
            f"`times` must be strictly increasing (non-monotone times): times[{i}] = "
            f"{times[i]!r} s after times[{i - 1}] = {times[i - 1]!r} s"
        )
    bad = np.flatnonzero(np.abs(steps - steps[0]) > SAMPLE_RATE_RTOL * steps[0])
    if bad.size:
        i = int(bad[0]) + 1
        raise MeasurementError(
            f"mismatched sample rates: `times` must be uniformly spaced; the step before sample "
            f"{i} is {steps[i - 1]:.9g} s ({1 / steps[i - 1]:.6g} Hz), the first is "
            f"{steps[0]:.9g} s ({1 / steps[0]:.6g} Hz)"
        )
    if sample_rate is not None:
        rate = (times.size - 1) / (times[-1] - times[0])
        if abs(rate - sample_rate) > SAMPLE_RATE_RTOL * sample_rate:
            raise MeasurementError(
                f"mismatched sample rates: the times are sampled at {rate:.9g} Hz, expected "
                f"`sample_rate` = {sample_rate:.9g} Hz"
            )


def _check_names(channels) -> None:
    for name in channels:
        if not isinstance(name, str) or not name or "," in name or "[" in name:
            raise MeasurementError(
                f"channel names must be non-empty without ',' or '[', got {name!r}"
            )
    dups = sorted({n for n in channels if channels.count(n) > 1})
    if dups:
        raise MeasurementError(f"channel names must be unique; repeated: {', '.join(dups)}")


def check_channels_in_layout(channels, units, sensors) -> None:
    """Every channel must be a sensor of `sensors` with the same unit."""
    by_name = {s.name: s for s in sensors}
    for name, unit in zip(channels, units):
        if name not in by_name:
            raise MeasurementError(
                f"unknown channel {name!r}: no sensor of that name; known: {', '.join(by_name)}"
            )
        if unit != by_name[name].unit:
            raise MeasurementError(
                f"channel {name!r} has unit {unit!r}, its sensor measures {by_name[name].unit!r}"
            )
