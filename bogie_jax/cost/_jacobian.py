"""`residual_jacobian`: the residual Jacobian dr/dtheta, the one way the library takes it.

Forward mode through the solve: one solve carries the `n` tangents of the basis vectors (`vmap`
of `jax.jvp`), which for a measurement (many residuals, few parameters) is far cheaper than
reverse mode (one backward pass per residual). An
`Objective` is switched to `diffrax.ForwardMode()` here, so callers never switch adjoints by
hand; `bogie_jax.identify.JacobianResiduals` (the residuals the least-squares solvers
linearise) materialises the same Jacobian.
"""

import jax
import jax.numpy as jnp


def forward_mode(objective):
    """`objective` differentiated in forward mode: `objective.forward_mode()` where it has one
    (an `Objective`), else unchanged (plain residual functions need no switch)."""
    switch = getattr(objective, "forward_mode", None)
    return switch() if callable(switch) else objective


def residual_jacobian(objective, theta, args=None, directions=None):
    """`(r, J)`: residuals `r` (m,) and their Jacobian `J = dr/dtheta` (m, n) at `theta` (n,);
    with `directions` (n, k), `J @ directions` (m, k) instead: k tangents carried, so that one
    compiled program takes a Jacobian's columns block by block, each block on a core of its own
    (the step sizes follow the primal solve alone, so the blocks' columns are the whole
    Jacobian's, up to rounding).

    `objective`: anything with `residuals(theta, args)` (an `Objective` or a
    `CorrectedObjective` over [theta, run corrections], switched to forward mode; a
    `bogie_jax.identify.LeastSquaresProblem`, with its `args`). Pure JAX: jit and vmap
    it with the objective as an argument (`eqx.filter_jit`).
    """
    objective = forward_mode(objective)
    fn = lambda th: jnp.ravel(objective.residuals(th, args))
    theta = jnp.asarray(theta)
    if directions is None:
        directions = jnp.eye(theta.size, dtype=theta.dtype)
    tangents = jnp.asarray(directions, dtype=theta.dtype).T
    r, jac_t = jax.vmap(lambda v: jax.jvp(fn, (theta,), (v,)), out_axes=(None, 0))(tangents)
    return r, jac_t.T
