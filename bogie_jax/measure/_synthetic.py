"""Sensor readings from a trajectory, and synthetic measurements from known parameters."""

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from ..model import BogieModel, accelerations, build_model
from ..params import BogieParams, ModelOptions
from ..runtime.solve_settings import resolve_settings
from ..simulation import (
    SolveSettings,
    Trajectory,
    check_simulation_inputs,
    check_window,
    simulate,
)
from ..track import TrackIrregularity, TrackReference
from ._layout import check_sensor_names, default_sensor_layout, layout_description
from ._locations import sample_state
from ._measurement import Measurement


def sensor_readings(sensors, model: BogieModel, ts, q, qd, qdd):
    """Noise-free readings (n_times, n_sensors) of `sensors` (bias included) at times `ts` [s]
    for coordinates `q`, rates `qd` and accelerations `qdd` (n_times, 10) of the run `model`."""

    return jax.vmap(_readings_at, in_axes=(None, None, 0, 0, 0, 0))(sensors, model, ts, q, qd, qdd)


@eqx.filter_jit
def _readings_at(sensors, model, t, q, qd, qdd):
    """The readings (n_sensors,) at one time; a `jit` of its own (traced once, as
    `bogie_jax.model.accelerations`)."""
    state = sample_state(model, t, q, qd, qdd)
    return jnp.stack([s.read(model, state) + s.bias for s in sensors])


def readings_from_states(sensors, model: BogieModel, ts, q, qd):
    """`sensor_readings` with q_ddot from the equations of motion (`model.accelerations`).

    Non-finite states (the unreached samples of a failed solve) are replaced by zeros first, so
    that neither the readings nor their derivatives become NaN (double-where).
    """
    q = jnp.where(jnp.isfinite(q), q, 0.0)
    qd = jnp.where(jnp.isfinite(qd), qd, 0.0)
    qdd = jax.vmap(lambda t, a, b: accelerations(model, t, a, b))(ts, q, qd)
    return sensor_readings(sensors, model, ts, q, qd, qdd)


def measure(
    trajectory: Trajectory,
    sensors,
    params: BogieParams,
    track: TrackIrregularity,
    *,
    options: ModelOptions = ModelOptions(),
):
    """Noise-free channels (n_times, n_sensors) of `sensors` for a simulated `trajectory` of the
    bogie `params` on `track` (the run's speed is `trajectory.speed`)."""
    sensors = tuple(sensors)
    check_sensor_names(sensors)
    model = build_model(params, speed=trajectory.speed, track=track, options=options)
    t = trajectory
    return sensor_readings(sensors, model, t.ts, t.q, t.qd, t.qdd)


@eqx.filter_jit
def _clean_channels(params, track, speed, sensors, duration, sample_rate, window, options,
                    settings, y0):  # fmt: skip
    start_position, lead_in = window  # arrays: traced, one compilation for every window
    run = simulate(
        params, track, speed=speed, duration=duration, sample_rate=sample_rate,
        start_position=start_position, lead_in=lead_in, y0=y0, options=options,
        settings=settings,
    )  # fmt: skip
    return run.ts, measure(run, sensors, params, track, options=options), run.successful


def synthetic_measurement(
    params: BogieParams,
    track: TrackIrregularity,
    *,
    speed: float,
    duration: float,
    sample_rate: float = 200.0,
    start_position: float = 0.0,
    lead_in: float = 0.0,
    sensors=None,
    key=None,
    noise_scale: float = 1.0,
    track_reference: TrackReference | None = None,
    options: ModelOptions = ModelOptions(),
    settings: SolveSettings | None = None,
    y0=None,
    **solve_options,
) -> Measurement:
    """Simulate `params` on `track` and read `sensors` (default `default_sensor_layout(params)`).

    **Arguments:**
    - `speed` [m/s], `duration` [s], `sample_rate` [Hz]: as in `simulate`.
    - `start_position` [m], `lead_in` [m]: a window whose first sample is at track position
      `start_position`, simulated from rest (`y0`) `lead_in` metres earlier (0 <= `lead_in`
      <= `start_position`; see `simulate`). The defaults (0, 0) give the run from the start of
      the track. The measurement records `start_position`; its `times` are the model times
      `start_position / speed + k / sample_rate` (`Trajectory.ts`). A window of a run that
      started at rest at track position 0 is `lead_in = start_position`, or equally
      `synthetic_measurement(...).window(t_start, duration)` of a longer run.
    - `key`: PRNG key for additive Gaussian noise of standard deviation
      `noise_scale * sensor.noise_std` per channel; `None` gives noise-free data. Sensor biases
      are always added.
    - `track_reference`: the `TrackReference` of `track`, stored in the measurement (`None`:
      unknown).
    - `options`, `y0`, `settings` (`SolveSettings`, default `SolveSettings()`; the solve runs
      with `throw=False` and a failure raises here), `solve_options` (shorthand for single
      fields of `settings`): passed to `simulate`.

    **Returns:** a `Measurement` whose `layout` describes `sensors`.

    **Raises:** `RuntimeError` if the solve fails; `ValueError` for a bad window
    (`bogie_jax.simulation.check_window`), before anything is compiled.
    """
    if track_reference is not None and not isinstance(track_reference, TrackReference):
        raise TypeError(
            f"`track_reference` must be a TrackReference or None, got {track_reference!r}"
        )
    settings = resolve_settings(settings, SolveSettings(), **solve_options).replace(throw=False)
    sensors = default_sensor_layout(params) if sensors is None else tuple(sensors)
    layout = layout_description(sensors)
    y0 = None if y0 is None else np.asarray(y0, dtype=float)
    check_simulation_inputs(speed, duration, sample_rate, settings.max_steps)
    check_window(start_position, lead_in, speed=speed, duration=duration, track=track)
    window = (np.asarray(start_position, dtype=float), np.asarray(lead_in, dtype=float))
    ts, clean, ok = _clean_channels(
        params, track, np.asarray(speed, dtype=float), sensors, duration, sample_rate, window,
        options, settings, y0,
    )  # fmt: skip
    if not bool(ok):
        raise RuntimeError("the simulation for the synthetic measurement failed (see `simulate`)")
    data = np.asarray(clean)
    if key is not None:
        std = np.array([float(s.noise_std) for s in sensors])
        data = data + noise_scale * std * np.asarray(jr.normal(key, data.shape, dtype=clean.dtype))
    return Measurement(
        times=np.asarray(ts),
        data=data,
        channels=tuple(s.name for s in sensors),
        units=tuple(s.unit for s in sensors),
        speed=float(speed),
        track=track_reference,
        layout=layout,
        start_position=float(start_position),
    )
