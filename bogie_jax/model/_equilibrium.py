"""Static equilibrium: the rest state q0 of the bogie on a perfect track (docs/model.md,
"Static equilibrium").

q0 solves a(q0) = 0, with a(q) = M^-1 (Q - h) the accelerations of the equations of motion
(paper eq. 11) at zero velocity on a perfect track, for all 10 coordinates: the frame settles in
heave, roll and pitch (and, through the primary springs' lateral and longitudinal stiffness,
laterally and in yaw) when its springs are uneven; the wheelsets (y, yaw) are held by the
primary springs, the gravitational stiffness of the conical wheels (paper eq. 2: W zeta for y,
-W xi for yaw) and the creep forces of the rolling wheelset at q_dot = 0 (longitudinal creepage
-+lambda y / r0 and lateral creepage -yaw do not depend on the speed, so neither does q0).

Newton's method from q = 0 in a `lax.while_loop` (Nocedal & Wright, Numerical Optimization,
2nd ed., section 11.1): the 10 x 10 Jacobian J = da/dq by `jax.jacfwd`, the step by Householder
QR (`_householder`, plain XLA, which works inside `shard_map` where lineax's `LU` does not).
J = -M^-1 K_eff is non-singular for a bogie whose every coordinate is held (tested). q0 is
differentiable with respect to the parameters p by the implicit function theorem (Nocedal &
Wright, appendix A): differentiating a(q0(p), p) = 0 gives dq0 = -J(q0)^-1 (da/dp . dp). That
is a `jax.custom_jvp` rule, linear in dp (its solve in `jax.lax.custom_linear_solve`, so that
reverse mode transposes it), with J(q0) from the loop's last pass: the Newton iterations are
never differentiated and no second derivative of the vector field is formed. A symmetric
bogie has q0 = 0 (its springs carry their design loads at q = 0).

Why not `optimistix.root_find` (`Newton` in `jax.lax.custom_root`, as before): inside the
fits' objectives (linearised, vmapped and jvp'd) its generic machinery (a `jax.linearize` and a
lineax operator per Newton step, its own implicit adjoint inside `custom_root`) took 197 s of
the 275 s of tracing the default multistart identification program. This loop keeps its
iterates and stopping test (same q0 and step counts, to rounding) and still returns an
`optimistix.Solution`.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from .._householder import back_substitute, triangularise
from ..params import BogieParams, ModelOptions
from ..track import perfect_track
from ._dynamics import accelerations, build_model
from ._layout import N_DOF


# [m/s] speed of the rolling wheelsets in the solve (q0 does not depend on it, see above)
EQUILIBRIUM_SPEED = 1.0
# [m/s^2, rad/s^2] the Newton solve's default acceptance level for |a| (`atol`)
REST_ATOL = 1e-10


def _residual(q, model):
    """Accelerations [m/s^2, rad/s^2] (10,) at q, zero velocity, t = 0, on the model's track."""
    return accelerations(model, 0.0, q, jnp.zeros_like(q))


def _rest_model(params: BogieParams, options: ModelOptions):
    return build_model(params, speed=EQUILIBRIUM_SPEED, track=perfect_track(), options=options)


def equilibrium_residual(params: BogieParams, q, *, options: ModelOptions = ModelOptions()):
    """The accelerations (10,) at rest state candidate `q` on a perfect track (zero at q0)."""
    return _residual(jnp.asarray(q, dtype=float), _rest_model(params, options))


def _newton(model, rtol: float, atol: float, max_steps: int):
    """Newton's method on `_residual` from q = 0: (q0, J, steps, converged, solvable), J the
    Jacobian da/dq at q0 (10, 10) [1/s^2, ...].

    The stopping test is optimistix's `Newton` with Cauchy termination: after the step
    dq = J(q)^-1 a(q) from q, stop when max |dq| / (atol + rtol |q|) < 1 and max |a(q)| < atol,
    and return q0 = q - dq. One more pass of the loop then evaluates J at q0 (for the implicit
    function theorem) without stepping, so that the program holds one site of the Jacobian."""

    def body(carry):
        q, _, steps, converged, solvable, _ = carry
        jac, f = jax.jacfwd(lambda x: (_residual(x, model),) * 2, has_aux=True)(q)
        r, qtf = triangularise(jac, f)
        dq = back_substitute(r, qtf)
        # as `HouseholderQR`: singular when a diagonal of R is at rounding level of the largest
        diag = jnp.abs(jnp.diagonal(r))
        ok = jnp.all(diag > jnp.finfo(r.dtype).eps * N_DOF * jnp.max(diag))
        ok = ok & jnp.all(jnp.isfinite(dq)) & jnp.all(jnp.isfinite(q))
        small_step = jnp.max(jnp.abs(dq) / (atol + rtol * jnp.abs(q))) < 1
        done = small_step & (jnp.max(jnp.abs(f)) < atol)
        # `converged` in the previous pass: q is q0 and this pass only evaluated J there
        return (
            jnp.where(converged, q, q - dq),
            jac,
            jnp.where(converged, steps, steps + 1),
            converged | done,
            jnp.where(converged, solvable, ok),
            converged,
        )

    def cond(carry):
        _, _, steps, converged, solvable, finished = carry
        return ~finished & solvable & (converged | (steps < max_steps))

    q = jnp.zeros(N_DOF, dtype=float)
    false = jnp.array(False)
    init = (q, jnp.zeros((N_DOF, N_DOF)), jnp.zeros((), int), false, jnp.array(True), false)
    return jax.lax.while_loop(cond, body, init)[:5]


@eqx.filter_custom_jvp
def _implicit(q0, jac, params, *, options):
    """q0 (the root of the equilibrium of `params`, computed without derivatives), made
    differentiable with respect to `params` by the implicit function theorem (see the module
    docstring), `jac` da/dq at q0."""
    del jac, params, options
    return q0


@_implicit.def_jvp
def _implicit_jvp(primals, tangents, *, options):
    q0, jac, params = primals
    *_, t_params = tangents  # q0 and jac come without derivatives (`stop_gradient`)
    if t_params is None or not jax.tree.leaves(t_params):
        return q0, None
    residual_of = lambda p: _residual(q0, _rest_model(p, options))
    _, da = eqx.filter_jvp(residual_of, (params,), (t_params,))
    # dq0 = -J^-1 da, transposable for reverse mode
    dq0 = jax.lax.custom_linear_solve(
        lambda x: jac @ x,
        da,
        solve=lambda _, b: _solve(jac, b),
        transpose_solve=lambda _, b: _solve(jac.T, b),
    )
    return q0, -dq0


def _solve(a, b):
    """x with A x = b (10, 10) by Householder QR."""
    return back_substitute(*triangularise(a, b))


@eqx.filter_jit
def static_equilibrium_solve(
    params: BogieParams,
    *,
    options: ModelOptions = ModelOptions(),
    rtol: float = 1e-10,
    atol: float = REST_ATOL,
    max_steps: int = 32,
    throw: bool = True,
) -> optx.Solution:
    """The static equilibrium (see `static_equilibrium`) as an `optimistix.Solution`: `value`
    q0, `result` `successful`, `max_steps_reached` (no convergence in `max_steps` Newton
    steps) or `nonlinear_divergence` (a singular or non-finite Newton step), `stats`
    `num_steps` and `max_steps` (`aux` and `state` are `None`).

    Newton's method in a `lax.while_loop` (not `optimistix.root_find`: see the module
    docstring); derivatives of q0 by the implicit function theorem, dq0/dp =
    -(da/dq)^-1 da/dp, in forward and reverse mode (the linear solves by Householder QR in
    `jax.lax.custom_linear_solve`), without differentiating the iterations. Works inside
    `vmap` and `shard_map` (no LAPACK call) with `throw=False`. A `jit` of its own (traced
    once per program, as `accelerations`)."""
    dynamic, static = eqx.partition(params, eqx.is_inexact_array)
    fixed = eqx.combine(jax.lax.stop_gradient(dynamic), static)
    q, jac, steps, converged, solvable = _newton(_rest_model(fixed, options), rtol, atol, max_steps)
    failure = optx.RESULTS.where(
        solvable, optx.RESULTS.max_steps_reached, optx.RESULTS.nonlinear_divergence
    )
    result = optx.RESULTS.where(converged & solvable, optx.RESULTS.successful, failure)
    if throw:
        q = result.error_if(q, result != optx.RESULTS.successful)
    stats = {"num_steps": steps, "max_steps": max_steps}
    q0 = _implicit(q, jac, params, options=options)
    return optx.Solution(value=q0, result=result, aux=None, stats=stats, state=None)


def static_equilibrium(
    params: BogieParams,
    *,
    options: ModelOptions = ModelOptions(),
    rtol: float = 1e-10,
    atol: float = REST_ATOL,
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


@eqx.filter_jit
def _rest_accelerations(param_sets: BogieParams, options: ModelOptions):
    """a(q = 0) (k, 10) of parameter sets stacked on a leading axis k."""
    at_rest = jnp.zeros(N_DOF)
    return jax.vmap(lambda p: _residual(at_rest, _rest_model(p, options)))(param_sets)


def rests_at_zero(param_sets, *, options: ModelOptions = ModelOptions()) -> bool:
    """True when q = 0 is the rest state of every `BogieParams` in `param_sets` (concrete, a
    sequence): the accelerations at q = 0 and zero velocity pass the Newton solve's own test,
    |a| < `REST_ATOL` [m/s^2, rad/s^2], so `static_equilibrium` would return q0 = 0 to within
    |J^-1| `REST_ATOL` (about 1e-13 m); false where any is not finite. An objective whose
    parameters all pass starts from rest at zero without the solve
    (`bogie_jax.cost.fixed_rest_state`). One program per number of sets."""
    stacked = jax.tree.map(lambda *xs: np.stack([np.asarray(x) for x in xs]), *param_sets)
    largest = np.max(np.abs(np.asarray(_rest_accelerations(stacked, options))))
    return bool(largest < REST_ATOL)  # False for NaN
