"""`simulate`: integrate the bogie model with diffrax (the only place that calls diffeqsolve)."""

import math

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from ._precision import warn_if_float32
from ._validation import check_positive_int, check_range
from .contact import ProfileGeometry
from .model import (
    N_DOF,
    accelerations,
    beyond_contact_table,
    build_model,
    static_equilibrium_solve,
    vector_field,
)
from .params import BogieParams, ModelOptions
from .runtime.solve_settings import (
    SolveSettings as SolveSettings,
    default_controller as default_controller,
    resolve_settings,
)
from .track import TrackIrregularity


MAX_SPEED = 150.0  # [m/s] upper end of the valid speed range
_DEFAULT_SETTINGS = SolveSettings()


class Trajectory(eqx.Module):
    """A simulated run.

    - `ts` [s] (n,): the model times of the samples, `start_position / speed + k / sample_rate`:
      the bogie's reference point is at track position `speed * t` (`positions`), so a run from
      the start of the track has `ts[0] = 0` and a window starting mid-run has
      `ts[0] = start_position / speed` (not 0);
    - `q` (n, 10), `qd` (n, 10), `qdd` (n, 10): coordinates, velocities and
      accelerations (from the equations of motion, not finite differences) in the units of
      `bogie_jax.model.DOF_UNITS` (per s, per s^2);
    - `speed` [m/s];
    - `result`: diffrax `RESULTS` of the solve (check `successful`);
    - `num_steps`, `num_accepted_steps`, `num_rejected_steps`: solver statistics.
    """

    ts: jax.Array
    q: jax.Array
    qd: jax.Array
    qdd: jax.Array
    speed: jax.Array
    result: dfx.RESULTS
    num_steps: jax.Array
    num_accepted_steps: jax.Array
    num_rejected_steps: jax.Array

    @property
    def successful(self):
        """True where the solve succeeded (array under vmap)."""
        return self.result == dfx.RESULTS.successful

    @property
    def positions(self):
        """Track positions [m] (n,) of the bogie's reference point at the samples: speed * ts."""
        return self.speed * self.ts


def check_simulation_inputs(speed, duration, sample_rate, max_steps: int = 100_000) -> None:
    """Raise ValueError naming the argument, its value and the valid range (before any work)."""
    check_range("speed", speed, 0.0, MAX_SPEED, "m/s", open_lo=True)
    check_range("duration", duration, 0.0, 1e5, "s", open_lo=True)
    check_range("sample_rate", sample_rate, 0.0, 1e6, "Hz", open_lo=True)
    check_positive_int("max_steps", max_steps)


def sample_times(duration: float, sample_rate: float):
    """Sample times 0, 1/fs, ..., up to `duration` [s] (static length)."""
    n = int(math.floor(duration * sample_rate + 1e-9)) + 1
    return np.arange(n) / sample_rate


def track_end(track: TrackIrregularity):
    """The track position [m] of the last irregularity sample, or `None` where the track has no
    end: a perfect track (all samples zero: perfect everywhere) or traced samples."""
    values = track.values
    if any(isinstance(x, jax.core.Tracer) for x in (values, track.s0, track.ds)):
        return None
    if not np.any(np.asarray(values)):
        return None
    return float(track.s0) + float(track.ds) * (track.num_samples - 1)


def check_window(start_position, lead_in, *, speed=None, duration=None, track=None) -> None:
    """Check a measurement window on the track (before anything is compiled).

    - `start_position` [m]: track position of the first sample, finite and >= 0 (track
      position 0 is where a run from the start begins: the bogie's reference point is at
      `speed * t`);
    - `lead_in` [m]: distance simulated before the first sample, in [0, start_position] (the
      simulation cannot begin before track position 0);
    - with `speed` [m/s], `duration` [s] and `track` given, a window starting mid-run
      (`start_position > 0`) must end on the sampled track:
      `start_position + speed * duration <= track end` (`track_end`; a perfect track has no
      end). A run from the start of the track may run past its end (perfect beyond), as
      before.

    Traced values are not checked. **Raises:** `ValueError` naming the argument, its value and
    the valid range.
    """
    check_range("start_position", start_position, 0.0, math.inf, "m")
    start = _concrete(start_position)
    check_range("lead_in", lead_in, 0.0, math.inf if start is None else start, "m")
    if start is None or start <= 0 or track is None or speed is None or duration is None:
        return
    end, v, d = track_end(track), _concrete(speed), _concrete(duration)
    if end is None or v is None or d is None:
        return
    window_end = start + v * d
    if window_end > end * (1 + 1e-12) + 1e-9:
        raise ValueError(
            f"the window beyond the track: `start_position` + speed * duration = {start:g} m + "
            f"{v:g} m/s * {d:g} s = {window_end:g} m lies past the end of the track at {end:g} m;"
            f" valid: `start_position` in [0, {max(end - v * d, 0.0):g}] m for this track"
        )


def _concrete(x):
    if isinstance(x, jax.core.Tracer):
        return None
    return float(np.asarray(x))


def _vector_field_in_window_time(tau, y, args):
    """`vector_field` at model time t = first + tau; `args` = (model, first [s])."""
    model, first = args
    return vector_field(first + tau, y, model)


def _beyond_table_in_window_time(tau, y, args, **kwargs):
    """`beyond_contact_table` at model time t = first + tau: a `diffrax.Event` condition."""
    model, first = args
    return beyond_contact_table(first + tau, y, model)


def _event(table: bool, stop_after):
    """The solve's `diffrax.Event`: at the contact table's edge (`table`) and, where
    `stop_after` [s] is given, past that window time (key `"stop"`); `None` for neither."""
    if stop_after is None:
        return dfx.Event(_beyond_table_in_window_time) if table else None
    conds = {"stop": lambda tau, y, args, **kwargs: tau > stop_after}
    if table:
        conds["table"] = _beyond_table_in_window_time
    return dfx.Event(conds)


def sample_accelerations(model, ts, q, qd):
    """q_ddot (n, 10) at the samples `ts` [s] from the equations of motion (paper eq. 11).

    Non-finite entries of q, q_dot (the samples a failed solve did not reach) are evaluated at 0
    and the rows holding them set to NaN: values and derivatives stay finite elsewhere
    (double-where), and a caller that zeroes the non-finite samples gets finite derivatives.
    """
    finite = jnp.all(jnp.isfinite(q) & jnp.isfinite(qd), axis=-1, keepdims=True)
    q_safe = jnp.where(jnp.isfinite(q), q, 0.0)
    qd_safe = jnp.where(jnp.isfinite(qd), qd, 0.0)
    qdd = jax.vmap(lambda t, a, b: accelerations(model, t, a, b))(ts, q_safe, qd_safe)
    return jnp.where(finite, qdd, jnp.nan)


def simulate(
    params: BogieParams,
    track: TrackIrregularity,
    *,
    speed,
    duration: float,
    sample_rate: float = 200.0,
    start_position=0.0,
    lead_in=0.0,
    y0=None,
    options: ModelOptions = ModelOptions(),
    settings: SolveSettings | None = None,
    stop_after=None,
    **solve_options,
) -> Trajectory:
    """Simulate the bogie running at constant `speed` over `track`.

    **Arguments:**
    - `params`: `BogieParams` (SI units).
    - `track`: `TrackIrregularity` (e.g. `synthesise_track(...)` or `perfect_track()`).
    - `speed`: forward speed [m/s], in (0, 150]; may be traced (vmap over speeds).
    - `duration`: time [s] from the first to the last sample (static), `sample_rate`: output
      rate [Hz] (static): `floor(duration * sample_rate) + 1` samples.
    - `start_position` [m]: track position of the bogie's reference point at the first sample,
      >= 0 (default 0: the old run from the start of the track); may be traced (one
      compilation for every window of the same length). The bogie is at track position
      `speed * t`, so the samples are at t_k = start_position / speed + k / sample_rate
      (`Trajectory.ts`).
    - `lead_in` [m]: distance run before the first sample, in [0, start_position] (default 0):
      the integration starts at t0 = (start_position - lead_in) / speed from `y0` and only
      the samples inside the window are saved. A window cut out of a run that was already
      moving needs a lead-in long enough for the start transient to decay
      (`bogie_jax.cost.default_lead_in`). May be traced.
    - `y0`: initial state (q, q_dot) (20,) at the start of the lead-in; default `None`: at rest
      in the static equilibrium of `params`, (q0, 0) with q0 =
      `bogie_jax.model.static_equilibrium(params)` (zeros for a symmetric bogie), computed
      inside this function so that it follows traced parameters (differentiably). If its
      Newton solve fails, `Trajectory.result` says so (with `throw=False`; with `throw=True`
      it raises).
    - `options`: `ModelOptions` (nonlinear model options).
    - `stop_after` [s]: time after the first sample at which the solve stops (may be traced;
      `None`: it runs to the last sample). The samples after the step that passes it hold inf
      states and NaN accelerations and the result stays successful: a fit of the first seconds
      of a run pays for those seconds only, with one compiled program for every span.
    - `settings`: `SolveSettings` (solver, step-size controller, adjoint, `max_steps`, `dt0`,
      `throw`; default `SolveSettings()`). Use `settings.forward_mode()` for `jax.jacfwd`,
      `throw=False` inside `vmap` (failures are then in `Trajectory.result`).
    - `solve_options`: shorthand for single fields of `settings` (`max_steps=...`, ...).

    **Returns:** a `Trajectory`.

    **Raises:** `ValueError` naming the argument, its value and the valid range for a speed,
    duration, sample rate, start position or lead-in out of range, or a window starting
    mid-run that ends past the track (`check_window`), before anything is compiled.
    """
    settings = resolve_settings(settings, _DEFAULT_SETTINGS, **solve_options)
    check_simulation_inputs(speed, duration, sample_rate, settings.max_steps)
    check_window(start_position, lead_in, speed=speed, duration=duration, track=track)
    warn_if_float32()
    as_array = lambda x: jnp.asarray(x, dtype=float)  # a Python float would be static
    return _simulate_compiled(
        params,
        track,
        as_array(speed),
        as_array(start_position),
        as_array(lead_in),
        None if y0 is None else as_array(y0),
        None if stop_after is None else as_array(stop_after),
        duration=duration,
        sample_rate=sample_rate,
        options=options,
        settings=settings,
    )


@eqx.filter_jit
def _simulate_compiled(
    params, track, speed, start_position, lead_in, y0, stop_after, *, duration, sample_rate,
    options, settings,
) -> Trajectory:  # fmt: skip
    """`simulate` after its checks, as one compiled program: called from Python, the solve, the
    static equilibrium and the accelerations would otherwise each be dispatched (and the
    operations between them compiled) one by one. Under an outer `jit` or `vmap` it is
    inlined."""
    first = start_position / speed  # [s] model time of sample 0
    # Integrated in the window's own time tau = t - first: the save times are then exact
    # constants (a window starting mid-track has the same step grid as a run from the track
    # start; diffrax's check that every save time lies in [t0, t1] cannot fail on rounding).
    window_ts = sample_times(duration, sample_rate)
    ts = first + window_ts
    tau0 = -lead_in / speed
    model = build_model(params, speed=speed, track=track, options=options)
    table = isinstance(model.constants.geometry, ProfileGeometry)  # a stop where the table ends
    rest = None
    if y0 is None:
        rest = static_equilibrium_solve(params, options=options, throw=settings.throw)
        y0 = jnp.concatenate([rest.value, jnp.zeros(N_DOF, dtype=rest.value.dtype)])
    solution = dfx.diffeqsolve(
        dfx.ODETerm(_vector_field_in_window_time),
        settings.solver,
        t0=tau0,
        t1=float(window_ts[-1]),
        dt0=settings.dt0,
        y0=y0,
        args=(model, first),
        saveat=dfx.SaveAt(ts=window_ts),
        stepsize_controller=settings.stepsize_controller,
        adjoint=settings.adjoint,
        max_steps=settings.max_steps,
        throw=settings.throw,
        event=_event(table, stop_after),
    )
    q, qd = solution.ys[:, :N_DOF], solution.ys[:, N_DOF:]
    qdd = sample_accelerations(model, ts, q, qd)
    if table:  # samples after a stop at the table's edge hold inf (diffrax), never NaN
        qdd = jnp.where(jnp.isfinite(q).all(axis=1, keepdims=True), qdd, jnp.inf)
    result = solution.result
    if stop_after is not None:  # stopping there is what was asked for
        stopped = solution.event_mask["stop"]
        result = dfx.RESULTS.where(stopped, dfx.RESULTS.successful, result)
    if rest is not None:
        at_rest = rest.result == optx.RESULTS.successful
        result = dfx.RESULTS.where(at_rest, result, dfx.RESULTS.promote(rest.result))
    return Trajectory(
        ts=ts,
        q=q,
        qd=qd,
        qdd=qdd,
        speed=model.speed,
        result=result,
        num_steps=solution.stats["num_steps"],
        num_accepted_steps=solution.stats["num_accepted_steps"],
        num_rejected_steps=solution.stats["num_rejected_steps"],
    )
