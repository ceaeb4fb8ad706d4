"""Static equilibrium: the rest state q0 of the bogie on a perfect track (docs/model.md,
"Static equilibrium").

q0 solves a(q0) = 0, with a(q) = M^-1 (Q - h) the accelerations of the equations of motion
(paper eq. 11) at zero velocity on a perfect track, for all 10 coordinates: the frame settles in
heave, roll and pitch (and, through the primary springs' lateral and longitudinal stiffness,
laterally and in yaw) when its springs are uneven; the wheelsets (y, yaw) are held by the
primary springs, the gravitational stiffness of the conical wheels (paper eq. 2: W zeta for y,
-W xi for yaw) and the creep forces of the rolling wheelset at q_dot = 0 (longitudinal creepage
-+lambda y / r0 and lateral creepage -yaw do not depend on the speed, so neither does q0).

Newton's method (optimistix, with the plain-XLA `HouseholderQR` linear solver, which works inside
`shard_map` where lineax's `LU` does not) from q = 0; the Jacobian da/dq = -M^-1 K_eff is
non-singular for a bogie whose every coordinate is held (tested). q0 is differentiable with
respect to the parameters by the implicit function theorem (`jax.lax.custom_root`): dq0/dp =
-(da/dq)^-1 da/dp, in forward and reverse mode. A symmetric bogie has q0 = 0 (its springs carry
their design loads at q = 0).
"""

import jax
import jax.numpy as jnp
import optimistix as optx

from .._householder import HouseholderQR, solve_square
from ..params import BogieParams, ModelOptions
from ..track import perfect_track
from ._dynamics import accelerations, build_model
from ._layout import N_DOF


# [m/s] speed of the rolling wheelsets in the solve (q0 does not depend on it, see above)
EQUILIBRIUM_SPEED = 1.0


def _residual(q, model):
    """Accelerations [m/s^2, rad/s^2] (10,) at q, zero velocity, t = 0, on the model's track."""
    return accelerations(model, 0.0, q, jnp.zeros_like(q))


def equilibrium_residual(params: BogieParams, q, *, options: ModelOptions = ModelOptions()):
    """The accelerations (10,) at rest state candidate `q` on a perfect track (zero at q0)."""
    model = build_model(params, speed=EQUILIBRIUM_SPEED, track=perfect_track(), options=options)
    return _residual(jnp.asarray(q, dtype=float), model)


def static_equilibrium_solve(
    params: BogieParams,
    *,
    options: ModelOptions = ModelOptions(),
    rtol: float = 1e-10,
    atol: float = 1e-10,
    max_steps: int = 32,
    throw: bool = True,
) -> optx.Solution:
    """The optimistix `Solution` of the static equilibrium (see `static_equilibrium`); its
    `value` is q0, its `result` says whether Newton converged (`aux` and `state` are `None`).

    The root is found by `optimistix.Newton`; its derivatives come from the implicit function
    theorem through `jax.lax.custom_root` (dq0/dp = -(da/dq)^-1 da/dp, the linear solves by
    `HouseholderQR` in `jax.lax.custom_linear_solve`, transposable for reverse mode) rather than
    optimistix's `ImplicitAdjoint`, whose closure-converted Jacobian operator fails inside
    `shard_map` with jax 0.10 (its shape structs carry the mesh), where the sharded multistart
    batch differentiates the equilibrium."""
    model = build_model(params, speed=EQUILIBRIUM_SPEED, track=perfect_track(), options=options)
    solver = optx.Newton(rtol=rtol, atol=atol, linear_solver=HouseholderQR())

    def newton(f, q_init):
        sol = optx.root_find(lambda q, _: f(q), solver, q_init, max_steps=max_steps, throw=throw)
        # aux as floats: `custom_root` gives integer aux outputs integer tangents, which JAX
        # rejects (jax 0.10)
        ok = jnp.where(sol.result == optx.RESULTS.successful, 1.0, 0.0)
        return sol.value, (ok, jnp.asarray(sol.stats["num_steps"], dtype=float))

    q0, (ok, steps) = jax.lax.custom_root(
        lambda q: _residual(q, model),
        jnp.zeros(N_DOF, dtype=float),
        newton,
        _tangent_solve,
        has_aux=True,
    )
    failure = optx.RESULTS.where(
        steps >= max_steps, optx.RESULTS.max_steps_reached, optx.RESULTS.nonlinear_divergence
    )
    result = optx.RESULTS.where(ok > 0.5, optx.RESULTS.successful, failure)
    stats = {"num_steps": steps.astype(int), "max_steps": max_steps}
    return optx.Solution(value=q0, result=result, aux=None, stats=stats, state=None)


def _tangent_solve(linear_fn, rhs):
    """x with linear_fn(x) = rhs for the (10, 10) linearised equilibrium, by Householder QR of
    its matrix; transposable (reverse mode) through `custom_linear_solve`."""

    def dense(fn, b):
        return solve_square(jax.jacfwd(fn)(b), b)

    return jax.lax.custom_linear_solve(linear_fn, rhs, dense, transpose_solve=dense)


def static_equilibrium(
    params: BogieParams,
    *,
    options: ModelOptions = ModelOptions(),
    rtol: float = 1e-10,
    atol: float = 1e-10,
    max_steps: int = 32,
    throw: bool = True,
):
    """The rest state q0 (10,) of the bogie on a perfect track, in the units of `DOF_UNITS`.

    Solves the accelerations at zero velocity = 0 (all 10 coordinates) by Newton's method from
    q = 0: zeros for a symmetric bogie, heave, roll and pitch of the frame (and small lateral
    and yaw offsets) for uneven suspension elements, whose vertical springs then share the load
    unevenly (`spring_preloads`). The initial state (q0, 0) of `simulate` and of the objective.

    **Arguments:**
    - `params`: `BogieParams` (may be traced: q0 follows them, differentiably by the implicit
      function theorem).
    - `options`: `ModelOptions` (at rest the creep saturation, flange and blow-off options act
      only where their thresholds are reached).
    - `rtol`, `atol`: Newton stops when the step is below atol + rtol |q| [m, rad] and the
      accelerations below atol [m/s^2, rad/s^2] (their rounding floor is about 1e-11, so atol
      should not go below 1e-10); `max_steps`: Newton iterations (3 to 4 are typical: the
      problem is nearly linear).
    - `throw`: raise if Newton does not converge; with `False` use `static_equilibrium_solve`
      to read the result.

    **Returns:** q0 (10,).
    """
    return static_equilibrium_solve(
        params, options=options, rtol=rtol, atol=atol, max_steps=max_steps, throw=throw
    ).value
