"""`simulate`: integrate the bogie model with diffrax (the only place that calls diffeqsolve)."""

import math

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import optimistix as optx

from ._precision import warn_if_float32
from ._solve_settings import (
    SolveSettings as SolveSettings,
    default_controller as default_controller,
    resolve_settings,
)
from ._validation import check_positive_int, check_range
from .model import N_DOF, accelerations, build_model, static_equilibrium_solve, vector_field
from .params import BogieParams, ModelOptions
from .track import TrackIrregularity


MAX_SPEED = 150.0  # [m/s] upper end of the valid speed range
_DEFAULT_SETTINGS = SolveSettings()


class Trajectory(eqx.Module):
    """A simulated run.

    - `ts` [s] (n,), `q` (n, 10), `qd` (n, 10), `qdd` (n, 10): coordinates, velocities and
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


def check_simulation_inputs(speed, duration, sample_rate, max_steps: int = 100_000) -> None:
    """Raise ValueError naming the argument, its value and the valid range (before any work)."""
    check_range("speed", speed, 0.0, MAX_SPEED, "m/s", open_lo=True)
    check_range("duration", duration, 0.0, 1e5, "s", open_lo=True)
    check_range("sample_rate", sample_rate, 0.0, 1e6, "Hz", open_lo=True)
    check_positive_int("max_steps", max_steps)


def sample_times(duration: float, sample_rate: float):
    """Sample times 0, 1/fs, ..., up to `duration` [s] (static length)."""
    n = int(math.floor(duration * sample_rate + 1e-9)) + 1
    return jnp.arange(n) / sample_rate


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
    y0=None,
    options: ModelOptions = ModelOptions(),
    settings: SolveSettings | None = None,
    **solve_options,
) -> Trajectory:
    """Simulate the bogie running at constant `speed` over `track`.

    **Arguments:**
    - `params`: `BogieParams` (SI units).
    - `track`: `TrackIrregularity` (e.g. `synthesise_track(...)` or `perfect_track()`).
    - `speed`: forward speed [m/s], in (0, 150]; may be traced (vmap over speeds).
    - `duration`: simulated time [s] (static), `sample_rate`: output rate [Hz] (static).
    - `y0`: initial state (q, q_dot) (20,); default `None`: at rest in the static equilibrium
      of `params`, (q0, 0) with q0 = `bogie_jax.model.static_equilibrium(params)` (zeros for a
      symmetric bogie), computed inside this function so that it follows traced parameters
      (differentiably). If its Newton solve fails, `Trajectory.result` says so (with
      `throw=False`; with `throw=True` it raises).
    - `options`: `ModelOptions` (nonlinear model options).
    - `settings`: `SolveSettings` (solver, step-size controller, adjoint, `max_steps`, `dt0`,
      `throw`; default `SolveSettings()`). Use `settings.forward_mode()` for `jax.jacfwd`,
      `throw=False` inside `vmap` (failures are then in `Trajectory.result`).
    - `solve_options`: shorthand for single fields of `settings` (`max_steps=...`, ...).

    **Returns:** a `Trajectory`.
    """
    settings = resolve_settings(settings, _DEFAULT_SETTINGS, **solve_options)
    check_simulation_inputs(speed, duration, sample_rate, settings.max_steps)
    warn_if_float32()
    ts = sample_times(duration, sample_rate)
    model = build_model(params, speed=speed, track=track, options=options)
    rest = None
    if y0 is None:
        rest = static_equilibrium_solve(params, options=options, throw=settings.throw)
        y0 = jnp.concatenate([rest.value, jnp.zeros(N_DOF, dtype=rest.value.dtype)])
    solution = dfx.diffeqsolve(
        dfx.ODETerm(vector_field),
        settings.solver,
        t0=0.0,
        t1=ts[-1],
        dt0=settings.dt0,
        y0=jnp.asarray(y0, dtype=float),
        args=model,
        saveat=dfx.SaveAt(ts=ts),
        stepsize_controller=settings.stepsize_controller,
        adjoint=settings.adjoint,
        max_steps=settings.max_steps,
        throw=settings.throw,
    )
    q, qd = solution.ys[:, :N_DOF], solution.ys[:, N_DOF:]
    qdd = sample_accelerations(model, ts, q, qd)
    result = solution.result
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
