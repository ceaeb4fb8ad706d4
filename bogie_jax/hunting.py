"""The nonlinear critical speed: a speed ramp-down from a hunting limit cycle.

A bogie set hunting above its critical speed keeps a limit cycle when the speed is lowered
slowly, down to the speed at which the cycle dies: at the linear critical speed
(`bogie_jax.model.critical_speed`) where the bifurcation is supercritical, below it where it is
subcritical, and the speed that matters in service (Knothe and Boehm, "History of stability of
railway and road vehicles", Vehicle System Dynamics 31, 1999; Polach, "On non-linear methods of
bifurcation analyses in railway vehicle dynamics", Vehicle System Dynamics 44 sup1, 2006: the
ramp method).

The ramp here is quasi-static: one run of `dwell` seconds at each speed of a descending list on
an ideal track, each run starting from the last state of the one before, the first from a
lateral kick grown into its cycle at the first speed. At each speed the cycle's amplitude is
the largest lateral displacement of the leading wheelset over the last second, and its growth
the ratio of that amplitude to the one a second earlier; the cycle is alive where the amplitude
is at least `min_amplitude` and it decays by less than `decay_tolerance` per second.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._validation import check_positive_int, check_range
from .model import dof_index
from .params import BogieParams, ModelOptions
from .simulation import simulate
from .track import perfect_track


LEADING_LATERAL = dof_index("wheelset1.y")


class RampDown(eqx.Module):
    """A speed ramp-down, one entry per speed (descending).

    - `speeds` [m/s];
    - `amplitude` [m]: largest |lateral displacement| of the leading wheelset over the run's
      last second;
    - `growth` [-]: that amplitude over the one of the second before (1 on a limit cycle, < 1
      where the motion dies out, > 1 where it grows);
    - `alive`: the cycle persists (amplitude >= `min_amplitude`, growth >= 1 - `decay_tolerance`);
    - `successful`: the run's solve succeeded (a run that leaves the contact table or fails
      ends the ramp: the later entries are not successful).
    """

    speeds: jax.Array
    amplitude: jax.Array
    growth: jax.Array
    alive: jax.Array
    successful: jax.Array

    def dies_between(self) -> tuple[float, float]:
        """(lower, upper) [m/s]: the first speed of the ramp at which the cycle is dead after it
        has lived, and the speed before it (the lowest at which it lived). NaN, NaN where the
        cycle never lived, never died, or a run failed before it died."""
        alive = [bool(a) for a in self.alive]
        ok = [bool(s) for s in self.successful]
        speeds = [float(v) for v in self.speeds]
        for k in range(1, len(speeds)):
            if not ok[k]:
                break
            if alive[k - 1] and not alive[k]:
                return speeds[k], speeds[k - 1]
        return float("nan"), float("nan")


def hunting_options(params: BogieParams) -> ModelOptions:
    """The nonlinear model a hunting cycle needs: saturated creep forces (Shen-Hedrick-Elkins),
    blow-off anti-yaw dampers, and flange springs on the cone (a profile table holds the flange
    in its geometry)."""
    return ModelOptions(
        creep_saturation=True,
        nonlinear_dampers=True,
        flange_contact=params.contact_geometry == "cone",
    )


def ramp_from_linear(
    params: BogieParams,
    linear_speed: float | None,
    *,
    above: float = 6.0,
    count: int = 81,
    step: float = 0.5,
    top: float = 150.0,
    **ramp_options,
) -> RampDown:
    """`ramp_down` over `count` speeds in `step` [m/s] steps from `above` [m/s] over the linear
    critical speed `linear_speed` [m/s] (`bogie_jax.model.critical_speed`), or from `top` [m/s]
    where it is None (stable up to `top`); speeds below 1 m/s are dropped. `ramp_options`: the
    other arguments of `ramp_down`."""
    check_positive_int("count", count, 10_000, lo=2)
    check_range("step", step, 0.0, 50.0, "m/s", open_lo=True)
    check_range("top", top, 0.0, 150.0, "m/s", open_lo=True)
    start = top if linear_speed is None else min(float(linear_speed) + above, top)
    speeds = start - step * np.arange(count)
    return ramp_down(params, speeds[speeds >= 1.0], **ramp_options)


def ramp_down(
    params: BogieParams,
    speeds,
    *,
    dwell: float = 8.0,
    settle: float = 30.0,
    sample_rate: float = 50.0,
    kick: float = 5e-3,
    min_amplitude: float = 0.1e-3,
    decay_tolerance: float = 0.02,
    options: ModelOptions | None = None,
) -> RampDown:
    """Lower the speed through `speeds` from a hunting motion and record the limit cycle.

    **Arguments:**
    - `params`: `BogieParams` (SI units); a profile contact (`contact="s1002-uic60"`) or the cone.
    - `speeds` [m/s]: strictly descending, each in (0, 150].
    - `dwell` [s]: duration of the run at each speed, >= 2 (static; the cycle's transient after
      a speed step must decay within it: 6-12 s near the bifurcation).
    - `settle` [s]: a first run at `speeds[0]` from the kick, before the ramp, in which the
      hunting motion grows into its cycle, in [0, 600] (static; 0: none; at least 2 s if any).
    - `sample_rate` [Hz]: output rate of each run (static), in [20, 1000].
    - `kick` [m]: lateral displacement of both wheelsets at the start (with a lateral velocity
      of 10 `kick` per second on the leading one), in (0, 0.02].
    - `min_amplitude` [m]: the smallest amplitude counted as a cycle, > 0.
    - `decay_tolerance` [-]: the largest decay per second of a cycle still counted alive, in
      [0, 0.5).
    - `options`: `ModelOptions` (default `hunting_options(params)`).

    **Returns:** a `RampDown`; `.dies_between()` brackets the nonlinear critical speed.

    **Raises:** `ValueError` naming the argument and its valid range before anything compiles.
    """
    speeds = jnp.asarray(speeds, dtype=float)
    if speeds.ndim != 1 or speeds.size < 2 or not bool(jnp.all(jnp.diff(speeds) < 0)):
        raise ValueError(f"`speeds` = {speeds} must be at least two strictly descending values")
    check_range("speeds", float(speeds.min()), 0.0, 150.0, "m/s", open_lo=True)
    check_range("speeds", float(speeds.max()), 0.0, 150.0, "m/s", open_lo=True)
    check_range("dwell", dwell, 2.0, 600.0, "s")
    check_range("settle", settle, 0.0, 600.0, "s")
    check_range("sample_rate", sample_rate, 20.0, 1000.0, "Hz")
    check_range("kick", kick, 0.0, 0.02, "m", open_lo=True)
    check_range("min_amplitude", min_amplitude, 0.0, 0.05, "m", open_lo=True)
    check_range("decay_tolerance", decay_tolerance, 0.0, 0.5, open_hi=True)
    options = hunting_options(params) if options is None else options
    y0 = jnp.zeros(20).at[6:8].set(kick).at[10 + LEADING_LATERAL].set(10.0 * kick)
    amplitude, growth, successful = _ramp(
        params, speeds, y0, dwell=dwell, settle=settle, sample_rate=sample_rate, options=options
    )
    alive = (amplitude >= min_amplitude) & (growth >= 1.0 - decay_tolerance) & successful
    return RampDown(speeds, amplitude, growth, alive, successful)


@eqx.filter_jit
def _ramp(params, speeds, y0, *, dwell, settle, sample_rate, options):
    per_second = int(round(sample_rate))
    track = perfect_track()

    def run(y, speed, duration=dwell):
        trajectory = simulate(
            params,
            track,
            speed=speed,
            duration=duration,
            sample_rate=sample_rate,
            y0=y,
            options=options,
            throw=False,
        )
        lateral = jnp.abs(trajectory.q[:, LEADING_LATERAL])
        last = jnp.max(lateral[-per_second:])
        before = jnp.max(lateral[-2 * per_second : -per_second])
        y_end = jnp.concatenate([trajectory.q[-1], trajectory.qd[-1]])
        ok = trajectory.successful & jnp.all(jnp.isfinite(y_end))
        return y_end, last, last / jnp.maximum(before, 1e-300), ok

    def skip(y, speed):  # after a failed run: nothing more is solved
        nan = jnp.asarray(jnp.nan, dtype=y.dtype)
        return y, nan, nan, jnp.asarray(False)

    def step(carry, speed):
        y, going = carry
        y_end, last, growth, ok = jax.lax.cond(going, run, skip, y, speed)
        return (y_end, ok), (last, growth, ok)

    start = (y0, jnp.asarray(True))
    if settle > 0:
        y_settled, _, _, settled = run(y0, speeds[0], max(settle, 2.0))
        start = (y_settled, settled)
    _, (amplitude, growth, successful) = jax.lax.scan(step, start, speeds)
    return amplitude, growth, successful
