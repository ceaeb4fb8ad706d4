"""`make_objective`: build and check an `Objective` from a measurement and a parameter selection."""

from collections.abc import Mapping

import numpy as np

from ..measure import Measurement, MeasurementError
from ..measure._layout import check_sensor_names
from ..measure._measurement import check_channels_in_layout
from ..params import BogieParams, ModelOptions
from ..runtime.solve_settings import resolve_settings
from ..simulation import SolveSettings, check_window, sample_times
from ..track import TrackIrregularity
from ._lead_in import window_lead_in
from ._objective import Objective, ResidualModel
from ._rest_state import fixed_rest_state
from ._selection import select_parameters


def make_objective(
    measurement: Measurement,
    params: BogieParams,
    track: TrackIrregularity,
    names,
    *,
    sensors=None,
    weights=None,
    bounds=None,
    options: ModelOptions = ModelOptions(),
    settings: SolveSettings | None = None,
    y0=None,
    lead_in=None,
    **solve_options,
) -> Objective:
    """The objective J(theta) of paper eq. 12 for `measurement`, over the parameters `names`.

    **Arguments:**
    - `measurement`: a `Measurement` sampled uniformly (its `times` may start anywhere: only
      the spacing 1/f_s counts, the model samples at k / f_s after the first sample); its
      `speed` is the run's speed and its `start_position` [m] the track position of its first
      sample (0: the run starts there, at rest unless `y0` is given).
    - `lead_in` [m]: distance over the known track simulated before the first sample, in
      [0, start_position]; the residuals compare only the samples inside the window. Default
      `None`: 0 for a window at the start of the track (`start_position` = 0, the old
      behaviour), otherwise `min(default_lead_in(params, speed), start_position)`: long
      enough for the start transient to decay by 1e-3 (`bogie_jax.cost.default_lead_in`,
      from the slowest decay rate of the linearised base `params` at the run's speed),
      clipped to the track before the window. `lead_in=0` with `start_position` > 0 starts at
      rest at the first sample (biased: the real bogie was moving there).
    - `y0`: the initial state (20,) at the start of the lead-in; default `None`: at rest in the
      static equilibrium of the parameters being evaluated, (q0(p(theta)), 0), computed inside
      the objective so that it follows theta (differentiably,
      `bogie_jax.model.static_equilibrium`); zeros for a symmetric bogie. Where the selected
      parameters cannot move it (dampers, tied stiffnesses of a symmetric bogie: tested at
      probe points by `bogie_jax.cost.fixed_rest_state`), the objective holds `y0` = 0 and its
      program has no equilibrium solve (a fifth to a third of a fit's compile time).
    - `params`: base parameters: nominal values of the selected parameters (theta = 0) and
      fixed values of the others. `track`: the track of the run.
    - `names`, `bounds`: the selection (see `select_parameters`).
    - `sensors`: the sensors of the channels (default: the measurement's layout); each channel
      must have a sensor of that name and unit; extra sensors are ignored.
    - `weights`: W per channel [1/unit^2]: `None` = 1 / noise_std^2 of each sensor, an array
      (n_channels,), or `{channel: weight}` (others keep the default). Must be finite, > 0.
    - `options`, `y0`: the run (see `simulate`; `y0=None` starts at the static equilibrium of
      the parameters being evaluated); `settings`: the solve, default
      `SolveSettings.for_objective()` (PID rtol 1e-6, atol 1e-9, `max_steps=16_384`,
      `throw=False`: a failed solve gives infinite residuals instead of an error; reverse mode
      with one checkpoint per step, what `jax.grad` needs; the Jacobian path switches to forward
      mode by itself). `solve_options`: shorthand for single fields of `settings`
      (`stepsize_controller=...`, `max_steps=...`).

    **Raises:** `ValueError` (`MeasurementError` for the data) naming the problem: among
    others a `lead_in` < 0, longer than the track before the window (> `start_position`) or
    not finite, and a window starting mid-run that ends past the track (`check_window`), all
    before anything is compiled.
    """
    settings = resolve_settings(settings, SolveSettings.for_objective(), **solve_options)
    sensors = _matching_sensors(measurement, sensors)
    duration, rate = _check_sampling(measurement)
    speed = np.asarray(measurement.speed, dtype=float)
    start = np.asarray(measurement.start_position, dtype=float)
    given = 0.0 if lead_in is None else lead_in
    check_window(start, given, speed=speed, duration=duration, track=track)
    lead = window_lead_in(lead_in, params, speed, start, options=options)
    sqrt_w = np.sqrt(_weights(weights, sensors, measurement.channels))
    selection = select_parameters(params, names, bounds=bounds)
    data = np.asarray(measurement.data, dtype=float)
    mask = np.isfinite(data)
    if not mask.any():
        raise MeasurementError("every sample of the measurement is missing (NaN)")
    if y0 is None:
        y0 = fixed_rest_state(params, selection, options)
    model = ResidualModel(
        params=params,
        track=track,
        speed=speed,
        sensors=sensors,
        data=np.where(mask, data, 0.0),
        mask=mask,
        sqrt_weights=sqrt_w,
        duration=duration,
        sample_rate=rate,
        options=options,
        settings=settings,
        y0=None if y0 is None else np.asarray(y0, dtype=float),
        start_position=start,
        lead_in=np.asarray(lead, dtype=float),
    )
    return Objective(selection, model)


def _matching_sensors(measurement, sensors) -> tuple:
    sensors = measurement.sensors() if sensors is None else tuple(sensors)
    check_sensor_names(sensors)
    check_channels_in_layout(measurement.channels, measurement.units, sensors)
    by_name = {s.name: s for s in sensors}
    return tuple(by_name[c] for c in measurement.channels)


def _check_sampling(measurement) -> tuple[float, float]:
    """(duration, rate): the model samples at k / f_s after the first sample, k = 0..n-1; the
    measurement's times relative to their first must be those (uniform spacing). Both are
    static fields of the residual model, so they are canonical: the rate to 12 significant
    digits and the duration (n - 1) / rate. The times of a window that starts at
    start_position / speed carry a few ulps of rounding (0.49999999999999994 s and
    100.00000000000001 Hz for 0.5 s at 100 Hz from 10 m at 30 m/s), which would otherwise
    compile another program for every such window."""
    times = np.asarray(measurement.times, dtype=float)
    rate = float(f"{measurement.sample_rate:.12g}")
    relative = times - times[0]
    expected = np.asarray(sample_times(float(relative[-1]), rate))
    if expected.shape != times.shape or not np.allclose(
        expected, relative, rtol=0, atol=1e-6 / rate
    ):
        raise MeasurementError(
            f"the objective samples at k / f_s after the first sample; the measurement has "
            f"{times.size} samples from t = {times[0]:g} s to {times[-1]:g} s that are not "
            f"uniformly spaced at {rate:g} Hz"
        )
    return (times.size - 1) / rate, rate


def _weights(weights, sensors, channels) -> np.ndarray:
    default = np.array([1.0 / float(s.noise_std) ** 2 for s in sensors])
    if weights is None:
        w = default
    elif isinstance(weights, Mapping):
        unknown = [k for k in weights if k not in channels]
        if unknown:
            raise ValueError(f"`weights` for unknown channels: {', '.join(map(str, unknown))}")
        w = np.array([float(weights.get(c, d)) for c, d in zip(channels, default)])
    else:
        w = np.asarray(weights, dtype=float)
        if w.shape != (len(channels),):
            raise ValueError(
                f"`weights` must have shape ({len(channels)},) (one per channel), got {w.shape}"
            )
    bad = ~(np.isfinite(w) & (w > 0))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"`weights` must be finite and > 0; channel {channels[i]!r} has {w[i]!r}")
    return w
