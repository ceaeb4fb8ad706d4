"""Linear stability: eigenvalues of the Jacobian of the vector field at the static equilibrium
on a perfect track, swept over speed; the linear critical (hunting) speed and frequency.

The linearisation point is the rest state (q0, 0) of the parameters (`static_equilibrium`):
q0 = 0 for a symmetric bogie, but an asymmetric one (a soft spring, a failed damper) rests with
the frame heaved, rolled and pitched, and its small-motion dynamics are those about q0.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import optimistix as optx

from ..params import BogieParams, ModelOptions
from ..track import perfect_track
from ._dynamics import build_model, vector_field
from ._equilibrium import static_equilibrium_solve
from ._layout import N_DOF


class StabilitySweep(eqx.Module):
    """Eigenvalues [1/s] (n_speeds, 20) and the largest real part per speed."""

    speeds: jax.Array
    eigenvalues: jax.Array
    max_real_part: jax.Array


class CriticalSpeed(eqx.Module):
    """Linear critical speed [m/s] and the frequency [Hz] of the mode that becomes unstable.

    `found` is False when no crossing lies inside the swept range (`speed` is then NaN).
    """

    speed: jax.Array
    frequency: jax.Array
    found: jax.Array


def rest_state(params: BogieParams, options: ModelOptions = ModelOptions()):
    """The linearisation point y = (q0, 0) (20,) of `system_matrix`: q0 the static equilibrium
    of `params`, or q = 0 where its Newton solve fails (no raise: works inside `vmap`)."""
    rest = static_equilibrium_solve(params, options=options, throw=False)
    ok = (rest.result == optx.RESULTS.successful) & jnp.all(jnp.isfinite(rest.value))
    q0 = jnp.where(ok, rest.value, 0.0)
    return jnp.concatenate([q0, jnp.zeros(N_DOF, dtype=q0.dtype)])


def _jacobian(params, speed, y0, options):
    model = build_model(params, speed=speed, track=perfect_track(), options=options)
    return jax.jacfwd(vector_field, argnums=1)(0.0, y0, model)


def system_matrix(params: BogieParams, speed, options: ModelOptions = ModelOptions()):
    """Jacobian A = d(dy/dt)/dy (20, 20) [1/s, ...] at the rest state y = (q0, 0) on a perfect
    track at `speed` [m/s] (by `jax.jacfwd`), q0 the static equilibrium of `params`
    (`static_equilibrium`; zeros for a symmetric bogie). Small motions about the rest state
    obey d(dy)/dt = A dy. Where the equilibrium's Newton solve fails (no raise: works inside
    `vmap`), e.g. for a test bogie with a coordinate held by nothing (a singular stiffness, a
    zero eigenvalue), A is taken at q = 0, the rest state of a symmetric bogie (`rest_state`)."""
    return _jacobian(params, speed, rest_state(params, options), options)


def _eigenvalues_at(params, speed, y0, options):
    return jnp.linalg.eigvals(_jacobian(params, speed, y0, options))


@eqx.filter_jit
def eigenvalues(params: BogieParams, speed, options: ModelOptions = ModelOptions()):
    """Eigenvalues [1/s] of the bogie linearised at its rest state at `speed` [m/s]."""
    return _eigenvalues_at(params, speed, rest_state(params, options), options)


def _sweep(params, speeds, y0, options):
    eig = jax.vmap(lambda v: _eigenvalues_at(params, v, y0, options))(speeds)
    return StabilitySweep(speeds=speeds, eigenvalues=eig, max_real_part=jnp.max(eig.real, axis=1))


@eqx.filter_jit
def stability_sweep(params: BogieParams, speeds, options: ModelOptions = ModelOptions()):
    """Eigenvalues at each speed of `speeds` [m/s] (vmapped; one rest state for all)."""
    speeds = jnp.asarray(speeds, dtype=float)
    return _sweep(params, speeds, rest_state(params, options), options)


@eqx.filter_jit
def critical_speed(
    params: BogieParams,
    *,
    v_min: float = 5.0,
    v_max: float = 150.0,
    n_grid: int = 30,
    bisections: int = 40,
    options: ModelOptions = ModelOptions(),
) -> CriticalSpeed:
    """Lowest speed in [v_min, v_max] [m/s] where the largest eigenvalue real part crosses zero.

    A grid of `n_grid` speeds brackets the first crossing, then bisection refines it.
    """
    y0 = rest_state(params, options)  # one equilibrium solve for every speed
    sweep = _sweep(params, jnp.linspace(v_min, v_max, n_grid), y0, options)
    unstable = sweep.max_real_part > 0
    found = jnp.any(unstable)
    first = jnp.argmax(unstable)
    hi = sweep.speeds[first]
    lo = jnp.where(first > 0, sweep.speeds[jnp.maximum(first - 1, 0)], v_min)

    def bisect(_, bracket):
        a, b = bracket
        mid = 0.5 * (a + b)
        above = jnp.max(_eigenvalues_at(params, mid, y0, options).real) > 0
        return jnp.where(above, a, mid), jnp.where(above, mid, b)

    lo, hi = jax.lax.fori_loop(0, bisections, bisect, (lo, hi))
    eig = _eigenvalues_at(params, hi, y0, options)
    frequency = jnp.abs(eig[jnp.argmax(eig.real)].imag) / (2 * jnp.pi)
    nan = jnp.nan
    return CriticalSpeed(
        speed=jnp.where(found, 0.5 * (lo + hi), nan),
        frequency=jnp.where(found, frequency, nan),
        found=found,
    )
