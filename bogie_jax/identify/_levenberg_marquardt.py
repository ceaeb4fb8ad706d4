"""Levenberg-Marquardt that stops when the fit is converged in the statistical sense.

optimistix's Gauss-Newton family stops on a Cauchy test: the accepted step and *every*
residual's change below `atol + rtol |value|`. The residuals of an ODE fit jitter at the
solver's error level (adaptive steps move with the parameters), so that test does not pass
before the trust region has shrunk to nothing, and a collapsed region (damping `1 / step_size`
infinite) makes the step's linear solve fail: a fit that has reached the best minimum ends
`singular`.

Here the fit also stops when the Bates-Watts **relative offset** is small: with `J = Q R` at the
current point, residuals `r` (m of them) and `n` parameters,

    RO = sqrt(|Q1^T r|^2 / n) / sqrt(|Q2^T r|^2 / (m - n))

(Bates & Watts 1981, "A relative offset orthogonality convergence criterion for nonlinear least
squares", Technometrics 23(2) 179-183; Bates & Watts 1988, *Nonlinear Regression Analysis and
Its Applications*, 2.2.3). `|Q1^T r| = |J d|` for the Gauss-Newton step `d` still to take, and
`|Q2^T r|^2 / (m - n)` is the noise variance `s^2` the covariance uses, so `RO sqrt(n)` is the
length of the remaining step in the metric of the parameters' confidence region: `RO < tol`
means the estimate would move by less than `tol sqrt(n)` joint standard errors. It is
scale-free (no parameter or residual units enter). Without noise (`|Q2^T r|` at the ODE
error level) it only passes at the ODE error's own optimum, so the Cauchy test stays as the
other way to stop.

`offset_tol` is 1e-2, not Bates and Watts' 1e-3: the ODE error puts a floor under the offset,
and a tighter tolerance leaves fits that have reached the optimum stepping at that floor until
the trust region collapses (`singular`). Parameters held on a bound are left out of the offset
(`LevenbergMarquardt`).

**Stalled at the ODE error.** The floor can lie above `offset_tol`: near the optimum the cost
then changes by more between nearby points (the ODE error) than the Gauss-Newton step promises,
no step is accepted, and the trust region shrinks until the step's linear solve fails. So the
fit also stops, successfully, when `stall_steps` (5) steps in a row were rejected at an offset
below `stall_offset` (0.1): near the optimum of a smooth problem the Gauss-Newton model predicts
the decrease well and its steps are accepted, so repeated rejections there mean that the
objective's own error, not the model, stops progress. Such a fit ends within 0.1 sqrt(n)
standard errors of the optimum, one that passes `offset_tol` within 0.01 sqrt(n).
"""

from collections.abc import Callable

import jax.numpy as jnp
import lineax as lx
import optimistix as optx

from .._householder import triangularise
from ._problem import on_bound


def relative_offset(jac, residual, free=None):
    """The Bates-Watts relative offset (module docstring) of residuals `residual` (m,) with
    Jacobian `jac` (m, n), over the columns marked `free` (n,) (default: all); `inf` where no
    residual is left outside the tangent plane (also for m <= n: no degrees of freedom estimate
    the noise), 0 where no column is free."""
    r = jnp.ravel(residual)
    m, n = jac.shape
    if m <= n:
        return jnp.asarray(jnp.inf, r.dtype)
    if free is None:
        free = jnp.ones(n, bool)
    # the free columns first (stable), the others zeroed: the first k reflections span them
    order = jnp.argsort(~free, stable=True)
    free = free[order]
    _, qtr = triangularise(jnp.where(free, jac[:, order], 0.0), r)
    k = jnp.sum(free)
    offset2 = jnp.sum(jnp.where(jnp.arange(n) < k, qtr, 0.0) ** 2)
    orth2 = jnp.sum(r**2) - offset2
    ratio = (offset2 / jnp.maximum(k, 1)) / jnp.where(orth2 > 0, orth2 / (m - k), 1.0)
    offset = jnp.where(orth2 > 0, jnp.sqrt(ratio), jnp.inf)
    return jnp.where(k > 0, offset, 0.0)


def free_parameters(y, args, bound_tol):
    """Which parameters are not held on a bound (`_problem.on_bound` at `y`), with `args` a
    problem with a `transform` (this package's `LeastSquaresProblem`); without one, all."""
    transform = getattr(args, "transform", None)
    if transform is None or not hasattr(transform, "lower"):
        return jnp.ones(jnp.shape(y), bool)
    return ~on_bound(transform, transform.to_physical(y), bound_tol)


def _quiet(**kwargs):
    """No output (module-level: equal methods stay equal, and their batch is found again)."""


class LevenbergMarquardt(optx.AbstractGaussNewton):
    """`optimistix.LevenbergMarquardt` that also stops when the relative offset at the current
    iterate is below `offset_tol`, or below `stall_offset` after `stall_steps` rejected steps in
    a row (module docstring); otherwise the same solver (damped Newton descent, classical trust
    region, `rtol`/`atol` Cauchy test). `stall_offset=0` turns the stall rule off.

    Parameters held on a bound (within `bound_tol` box widths, `free_parameters`; the default
    is `fit`'s on-bound flag) are left out of the offset, as a constrained optimum's first-order
    conditions leave them out: the transform's logistic flattens there, the residual keeps a
    component along their (vanishing) columns, and the offset over all columns would never
    fall while the fit crawls towards the bound."""

    rtol: float
    atol: float
    offset_tol: float
    bound_tol: float
    stall_offset: float
    stall_steps: int
    norm: Callable
    descent: optx.DampedNewtonDescent
    search: optx.ClassicalTrustRegion
    verbose: Callable

    def __init__(
        self,
        rtol: float,
        atol: float,
        offset_tol: float = 1e-2,
        linear_solver: lx.AbstractLinearSolver = lx.QR(),
        bound_tol: float = 1e-6,
        stall_offset: float = 0.1,
        stall_steps: int = 5,
    ):
        self.rtol = rtol
        self.atol = atol
        self.offset_tol = offset_tol
        self.bound_tol = bound_tol
        self.stall_offset = stall_offset
        self.stall_steps = stall_steps
        self.norm = optx.max_norm
        self.descent = optx.DampedNewtonDescent(linear_solver=linear_solver)
        self.search = optx.ClassicalTrustRegion()
        self.verbose = _quiet

    def terminate(self, fn, y, args, options, state, tags):
        cauchy, result = super().terminate(fn, y, args, options, state, tags)
        # `state.f_info` holds the residuals and linearisation at `y` once a step was taken
        free = free_parameters(y, args, self.bound_tol)
        offset = relative_offset(state.f_info.jac.as_matrix(), state.f_info.residual, free)
        stalled = (state.num_steps_since_acceptance >= self.stall_steps) & (
            offset < self.stall_offset
        )
        converged = ~state.first_step & ((offset < self.offset_tol) | stalled)
        return cauchy | converged, result
