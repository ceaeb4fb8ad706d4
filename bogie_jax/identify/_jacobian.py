"""Residuals whose derivative is the materialised forward-mode Jacobian.

`jax.linearize` (used by the optimistix least-squares solvers) cannot split an ODE solve's
`while_loop` into a stored linear map, so every Jacobian-vector product would re-run the whole
tangent solve and the compiled program would hold several copies of it. `JacobianResiduals`
gives the residuals a custom JVP: the tangent rule computes the full Jacobian with one solve
carrying all `n` tangents (`vmap` of `jvp`) and returns `J @ t`. Linearising then stores `J`,
every further product is a matrix product, and reverse mode (BFGS) transposes that product: one
forward-mode solve per linearisation, for every method.
"""

import equinox as eqx
import jax
import jax.numpy as jnp


@eqx.filter_custom_jvp
def _residuals(theta, objective):
    return jnp.ravel(objective.residuals(theta, None))


@_residuals.def_jvp
def _residuals_jvp(primals, tangents):
    theta, objective = primals
    t_theta, t_objective = tangents
    if any(t is not None for t in jax.tree.leaves(t_objective, is_leaf=lambda x: x is None)):
        raise NotImplementedError(
            "JacobianResiduals differentiates with respect to `theta` only, not the objective"
        )
    fn = lambda th: jnp.ravel(objective.residuals(th, None))
    if t_theta is None:
        return fn(theta), None
    basis = jnp.eye(theta.size, dtype=theta.dtype)
    r, jac_t = jax.vmap(lambda v: jax.jvp(fn, (theta,), (v,)), out_axes=(None, 0))(basis)
    return r, jac_t.T @ t_theta


class JacobianResiduals(eqx.Module):
    """`residuals(theta, args)` of `objective` with the materialised-Jacobian JVP (see module)."""

    objective: eqx.Module

    def __call__(self, theta, args=None):
        del args
        return _residuals(theta, self.objective)
