"""`JacobianResiduals`: its custom JVP (through `bogie_jax.cost.residual_jacobian`) gives the
analytic Jacobian in forward mode, under `jax.linearize` (as optimistix's least-squares solvers
use it) and transposed in reverse mode (BFGS), and traces the residuals once.

Oracle: the hand-written Jacobian of an exponential decay, r_i = a exp(-b t_i) - y_i, in the
unconstrained coordinates of the box transform (chain rule d r / d theta = d r / d p * d p /
d theta, with d p / d theta of the element-wise transform, which is not under test).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from bogie_jax.identify import (
    BoxTransform,
    JacobianResiduals,
    LeastSquaresProblem,
    as_problem,
    fit_multistart,
    relative_offset,
)


T = jnp.linspace(0.0, 2.0, 9)
Y = 2.0 * jnp.exp(-0.7 * T)
TR = BoxTransform([0.5, 0.1], [4.0, 2.0], names=("a", "b"))
TRACES = []  # one entry per trace of `_Decay.residuals`


class _Decay(eqx.Module):
    """Objective-like: `residuals(theta, args)` and a `selection` (as `cost.Objective`) of the
    decay `a exp(-b t)` against data `y`, plus `rough` times a term that changes with the
    parameters but is not differentiated (as an ODE solver's error)."""

    selection: BoxTransform
    t: jax.Array
    y: jax.Array
    rough: float = eqx.field(static=True, default=0.0)

    @property
    def n_residuals(self) -> int:
        return self.t.size

    def residuals(self, theta, args=None):
        TRACES.append(1)
        a, b = self.selection.to_physical(theta)
        jitter = jax.lax.stop_gradient(jnp.sin(1e7 * (a + 2.0 * b) + 17.0 * self.t))
        return a * jnp.exp(-b * self.t) - self.y + self.rough * jitter


def _analytic_jacobian(theta):
    a, b = np.asarray(TR.to_physical(theta))
    dp = np.asarray(jax.jvp(TR.to_physical, (theta,), (jnp.ones(2),))[1])  # diagonal transform
    t = np.asarray(T)
    dr_dp = np.stack([np.exp(-b * t), -a * t * np.exp(-b * t)], axis=1)
    return dr_dp * dp


def test_custom_jvp_gives_the_analytic_jacobian_in_every_mode():
    objective = _Decay(TR, T, Y)
    residuals = JacobianResiduals(objective)
    theta = jnp.asarray([0.3, -0.2])
    expected = _analytic_jacobian(theta)
    np.testing.assert_allclose(jax.jacfwd(residuals)(theta), expected, rtol=1e-12, atol=1e-14)
    TRACES.clear()
    jax.jit(jax.jacfwd(residuals)).lower(theta)
    assert len(TRACES) == 1  # primal and tangents in one trace of the residuals
    r, jvp = jax.linearize(residuals, theta)
    np.testing.assert_allclose(r, objective.residuals(theta), rtol=1e-14)
    v = jnp.asarray([0.4, -1.3])
    np.testing.assert_allclose(jvp(v), expected @ np.asarray(v), rtol=1e-12, atol=1e-14)
    cost = lambda th: 0.5 * jnp.sum(residuals(th) ** 2)
    r0 = np.asarray(objective.residuals(theta))
    np.testing.assert_allclose(jax.grad(cost)(theta), expected.T @ r0, rtol=1e-12, atol=1e-14)
    # as_problem wraps a `selection` objective in JacobianResiduals
    problem = as_problem(objective)
    assert isinstance(problem.residuals, JacobianResiduals)


T_FIT = jnp.linspace(0.0, 2.0, 200)
Y_NOISY = 2.0 * jnp.exp(-0.7 * T_FIT) + 0.01 * jr.normal(jr.PRNGKey(5), T_FIT.shape)


def test_multistart_traces_the_residuals_once():
    """The Levenberg-Marquardt's multistart compiles one evaluation program, the residual
    Jacobian of the fits in flight (`JacobianResiduals`' tangent rule: the residuals traced once,
    primal and tangents together), takes the same steps whether its fits queue or all run at
    once, and ends where the default LM's relative offset has fallen below its 1e-2."""
    # 200 noisy samples and a rough term of 1e-4 of the noise: the LM stops on its offset
    objective = _Decay(TR, T_FIT, Y_NOISY, rough=1e-6)
    problem = LeastSquaresProblem(JacobianResiduals(objective), TR)
    kw = dict(key=jr.PRNGKey(0), n_starts=6, max_steps=50)
    TRACES.clear()
    queued = fit_multistart(problem, lanes=2, **kw)
    assert len(TRACES) == 1
    lock_step = fit_multistart(problem, lanes=None, **kw)
    assert np.all(queued.status == "successful")
    np.testing.assert_array_equal(queued.num_steps, lock_step.num_steps)
    np.testing.assert_allclose(queued.ends, lock_step.ends, rtol=1e-12)
    for end in queued.ends:
        theta = TR.to_theta(jnp.asarray(end))
        jac = jax.jacfwd(objective.residuals)(theta)
        assert relative_offset(jac, objective.residuals(theta)) < 1e-2
