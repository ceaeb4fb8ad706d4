"""Residuals whose derivative is the materialised forward-mode Jacobian.

`jax.linearize` (used by the optimistix least-squares solvers) cannot split an ODE solve's
`while_loop` into a stored linear map, so every Jacobian-vector product would re-run the whole
tangent solve and the compiled program would hold several copies of it. `JacobianResiduals`
gives the residuals a custom JVP: the tangent rule computes the full Jacobian by the library's one
Jacobian path, `bogie_jax.cost.residual_jacobian` (one forward-mode solve carrying all `n`
tangents, `vmap` of `jvp`; the residuals are traced once, primal and tangents together), and
returns `J @ t`. Linearising then stores `J`, every further product is a matrix product, and
reverse mode (BFGS) transposes that product: one forward-mode solve per linearisation, for
every method.
"""

import equinox as eqx
import jax
import jax.numpy as jnp

from ..cost import residual_jacobian


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
    if t_theta is None:
        return jnp.ravel(objective.residuals(theta, None)), None
    r, jac = residual_jacobian(objective, theta)
    return r, jac @ t_theta


class JacobianResiduals(eqx.Module):
    """`residuals(theta, args)` of `objective` with the materialised-Jacobian JVP (see module)."""

    objective: eqx.Module

    def __call__(self, theta, args=None):
        del args
        return _residuals(theta, self.objective)
