"""Local methods, their raw output and the fits' statistics.

Methods are strategy objects: the Levenberg-Marquardt (`LevenbergMarquardt`, run on the host
over a compiled residual-Jacobian program: `_lm_fits.py`), and compiled methods
(`AbstractLocalMethod`: optimistix least squares and minimisers, a compass search); strings are
accepted only through the `LOCAL_METHODS` name table. A fit's statistics are Gauss-Newton's:
covariance `s^2 (J^T J)^+` with `s^2 = 2 J / (m - n)` (`bogie_jax.cost.covariance_from_jacobian`,
rank deficiency reported), mapped to physical units by the derivative of the transform (delta
method). Solver status is `optimistix.RESULTS`.
"""

import abc

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from .._householder import HouseholderQR
from ..cost import Covariance, covariance_from_jacobian, residual_jacobian
from ._levenberg_marquardt import LevenbergMarquardt
from ._problem import (
    is_successful,
    on_bound,
    problem_residuals,
    status_name,
)
from ._student_t import t_quantile


class LocalOutput(eqx.Module):
    """Raw outcome of one local solve (vmappable: no `Solution` objects). `result`: the solver
    status, an `optimistix.RESULTS` (batched along the member axis in a batch; on the host read
    it with `status_names`, store it by name and read it back with `results_from_names`).
    `jacobian`: the residual Jacobian `dr/dtheta` (m, n) at `theta`, and `cost` = 0.5 r^T r
    there, where the fit ends with them (the Levenberg-Marquardt, `_lm_fits.lm_outputs`, and
    the Gauss-Newton family, `LeastSquaresMethod`), else `None`."""

    theta: jax.Array
    result: optx.RESULTS
    num_steps: jax.Array
    num_fn_evals: jax.Array
    num_jac_evals: jax.Array
    jacobian: jax.Array | None = None
    cost: jax.Array | None = None


class AbstractLocalMethod(eqx.Module):
    """A compiled local method: `solve(problem, theta0, max_steps) -> LocalOutput`,
    jit/vmap-safe."""

    @abc.abstractmethod
    def solve(self, problem, theta0, max_steps: int) -> LocalOutput:
        raise NotImplementedError


class LeastSquaresMethod(AbstractLocalMethod):
    """An optimistix least-squares solver (Gauss-Newton, Dogleg) on the residuals.

    Each step linearises the residuals once (`jax.linearize`): one residual evaluation and one
    forward-mode Jacobian per step. The output carries the residual Jacobian and the cost at
    the end from the solver's state (`state.f_info`: the residuals and linearisation at the
    iterate the last step returned), so the statistics evaluate nothing again: one copy of the
    simulation and its tangents fewer in a compiled fit.
    """

    solver: optx.AbstractLeastSquaresSolver

    def solve(self, problem, theta0, max_steps):
        sol = optx.least_squares(
            problem_residuals, self.solver, theta0, problem, max_steps=max_steps, throw=False
        )
        steps = jnp.asarray(sol.stats["num_steps"])
        f_info = sol.state.f_info
        jac = f_info.jac.as_matrix()  # products with unit vectors: exact
        cost = 0.5 * jnp.sum(jnp.ravel(f_info.residual) ** 2)
        return LocalOutput(sol.value, sol.result, steps, steps, steps, jacobian=jac, cost=cost)


class MinimiserMethod(AbstractLocalMethod):
    """An optimistix minimiser (BFGS, Nelder-Mead) on the cost scaled by its starting value.

    The scaling keeps the first quasi-Newton step sane (see docs: BFGS on the unscaled cost).
    `restarts` re-runs the solver from its own end (the standard remedy for a collapsed
    Nelder-Mead simplex); `max_steps` applies to each run. Evaluation counts: BFGS one
    value-and-gradient per step; Nelder-Mead `n + 1` per (re)start and at most 2 per step.
    """

    solver: optx.AbstractMinimiser
    restarts: int = eqx.field(static=True, default=0)

    def _run(self, problem, theta0, max_steps):
        scale = jnp.maximum(
            jax.lax.stop_gradient(problem.cost(theta0)), jnp.finfo(theta0.dtype).tiny
        )
        fn = lambda theta, args: problem.cost(theta) / scale
        sol = optx.minimise(fn, self.solver, theta0, None, max_steps=max_steps, throw=False)
        steps = jnp.asarray(sol.stats["num_steps"])
        if isinstance(self.solver, optx.NelderMead):
            fevs, jevs = theta0.size + 1 + 2 * steps, jnp.zeros_like(steps)
        else:
            fevs, jevs = steps + 1, steps
        return LocalOutput(sol.value, sol.result, steps, fevs, jevs)

    def solve(self, problem, theta0, max_steps):
        out = self._run(problem, theta0, max_steps)

        def restart(_, prev):
            new = self._run(problem, prev.theta, max_steps)
            return LocalOutput(
                new.theta,
                new.result,
                prev.num_steps + new.num_steps,
                prev.num_fn_evals + new.num_fn_evals,
                prev.num_jac_evals + new.num_jac_evals,
            )

        return jax.lax.fori_loop(0, self.restarts, restart, out)


class PatternSearch(AbstractLocalMethod):
    """Compass search: poll `theta +- step * e_i`, move to the best improving point, else shrink.

    Runs in `lax.while_loop` until the step falls below `step_tol` (success) or `max_steps`
    polls. Each poll costs `2 n` cost evaluations (evaluated together with `vmap`).
    """

    initial_step: float = 0.5
    step_tol: float = 1e-10
    contraction: float = 0.5
    expansion: float = 1.0

    def solve(self, problem, theta0, max_steps):
        n = theta0.size
        directions = jnp.concatenate([jnp.eye(n), -jnp.eye(n)]).astype(theta0.dtype)
        safe_cost = lambda th: jnp.nan_to_num(problem.cost(th), nan=jnp.inf)

        def cond(carry):
            _, f, step, k = carry
            return (step > self.step_tol) & (k < max_steps) & jnp.isfinite(f)

        def body(carry):
            theta, f, step, k = carry
            trial = theta + step * directions
            f_trial = jax.vmap(safe_cost)(trial)
            i = jnp.argmin(f_trial)
            better = f_trial[i] < f
            theta = jnp.where(better, trial[i], theta)
            f = jnp.where(better, f_trial[i], f)
            step = step * jnp.where(better, self.expansion, self.contraction)
            return theta, f, step, k + 1

        init = (
            theta0,
            safe_cost(theta0),
            jnp.asarray(self.initial_step, theta0.dtype),
            jnp.asarray(0),
        )
        theta, f, step, k = jax.lax.while_loop(cond, body, init)
        result = optx.RESULTS.where(
            jnp.isfinite(f),
            optx.RESULTS.where(
                step <= self.step_tol,
                optx.RESULTS.successful,
                optx.RESULTS.nonlinear_max_steps_reached,
            ),
            optx.RESULTS.nonlinear_divergence,
        )
        return LocalOutput(theta, result, k, 1 + 2 * n * k, jnp.zeros_like(k))


def local_methods(
    rtol: float = 1e-10, atol: float = 1e-10, offset_tol: float = 1e-2, stall_offset: float = 0.1
) -> dict:
    """The name -> method table used at the CLI/IO boundary. `rtol`, `atol`: optimistix's
    Cauchy test, `atol` also the LM's step rule (`xtol`); the LM's statistical rules
    `offset_tol` and `stall_offset` (`_levenberg_marquardt.py`; 0 turns a rule off). The
    optimistix least-squares steps by `HouseholderQR` (a batched LAPACK QR can deadlock a
    sharded multistart)."""
    qr = HouseholderQR()
    return {
        "lm": LevenbergMarquardt(offset_tol=offset_tol, xtol=atol, stall_offset=stall_offset),
        "gauss-newton": LeastSquaresMethod(optx.GaussNewton(rtol, atol, linear_solver=qr)),
        "dogleg": LeastSquaresMethod(optx.Dogleg(rtol, atol, linear_solver=qr)),
        "bfgs": MinimiserMethod(optx.BFGS(rtol, atol)),
        "nelder-mead": MinimiserMethod(optx.NelderMead(rtol, atol, adelta=0.05), restarts=2),
        "pattern": PatternSearch(),
    }


LOCAL_METHODS = local_methods()


def as_method(method) -> "AbstractLocalMethod | LevenbergMarquardt":
    """A method object from a name, a `LevenbergMarquardt`, an optimistix solver or an
    `AbstractLocalMethod`."""
    if isinstance(method, str):
        try:
            return LOCAL_METHODS[method.lower()]
        except KeyError:
            raise ValueError(
                f"unknown `method` {method!r}; choose one of {sorted(LOCAL_METHODS)} or pass a "
                "method object"
            ) from None
    if isinstance(method, AbstractLocalMethod | LevenbergMarquardt):
        return method
    if isinstance(method, optx.AbstractMinimiser):
        return MinimiserMethod(method)
    if isinstance(method, optx.AbstractLeastSquaresSolver):
        return LeastSquaresMethod(method)
    raise TypeError(
        f"`method` must be a name, a LevenbergMarquardt, an optimistix solver or a method "
        f"object, got {method!r}"
    )


class FitResult(eqx.Module):
    """Outcome of one fit, in physical units unless stated.

    `covariance = D s^2 (J^T J)^+ D^T` with `J` the residual Jacobian in `theta`, `D` the
    (diagonal) Jacobian of `to_physical`, and `s^2 = 2 cost / dof`, `dof = m - n`; `uncertainty`
    is the whole `Covariance` (rank, condition number, null directions in `theta`): a
    rank-deficient fit has infinite standard errors for the parameters of its unidentifiable
    combinations. `ci95` uses the Student-t quantile with `dof` degrees of freedom. Evaluation
    counts include the final residual + Jacobian evaluation for the statistics where one is
    made (a fit whose output holds no Jacobian, e.g. BFGS, and a multistart whose fits do not
    end with their Jacobian: see `_multistart.collect`). `status`:
    `optimistix.RESULTS`; `wall_time` [s]: the fit's time (compile included on a first call).
    """

    names: tuple[str, ...] = eqx.field(static=True)
    estimates: jax.Array
    theta: jax.Array
    cost: jax.Array
    std_errors: jax.Array
    ci95: jax.Array
    correlation: jax.Array
    covariance: jax.Array
    noise_variance: jax.Array
    dof: int = eqx.field(static=True)
    on_bound: jax.Array
    num_steps: jax.Array
    num_fn_evals: jax.Array
    num_jac_evals: jax.Array
    status: optx.RESULTS
    wall_time: jax.Array
    uncertainty: Covariance

    @property
    def success(self) -> bool:
        return bool(is_successful(self.status))

    @property
    def rank(self) -> int:
        """Number of identifiable parameter directions at the estimate."""
        return int(self.uncertainty.rank)

    @property
    def null_directions(self) -> np.ndarray:
        """`(n, n - rank)` unidentifiable directions in `theta` (see `Covariance`)."""
        return self.uncertainty.null_directions

    @property
    def status_name(self) -> str:
        return status_name(self.status)


def fit_statistics(transform, theta, cost, jac, bound_tol):
    """Gauss-Newton covariance and on-bound flags at `theta` from the cost `J = 0.5 r^T r` and
    the residual Jacobian `jac = dr/dtheta` (m, n) there (jit-safe; the one place the fits'
    statistics are formed).

    The covariance is `bogie_jax.cost.covariance_from_jacobian` in `theta` (dimensionless log /
    logit coordinates) with `s^2 = 2 J / (m - n)`, mapped to physical units by the transform's
    derivative (element-wise transforms: a diagonal `D`; the delta method)."""
    m, n = jac.shape
    dof = m - n
    s2 = 2.0 * cost / dof if dof > 0 else jnp.asarray(jnp.nan)
    estimates, d = jax.jvp(transform.to_physical, (theta,), (jnp.ones_like(theta),))
    uncertainty = covariance_from_jacobian(jac, sigma2=s2, scale=d)
    se = uncertainty.std_errors
    half = t_quantile(0.975, max(dof, 1)) * se
    return dict(
        estimates=estimates,
        cost=jnp.asarray(cost),
        std_errors=se,
        ci95=jnp.stack([estimates - half, estimates + half], axis=-1),
        correlation=uncertainty.correlation,
        covariance=uncertainty.covariance,
        uncertainty=uncertainty,
        noise_variance=s2,
        dof=dof,
        on_bound=on_bound(transform, estimates, bound_tol),
    )


def statistics(problem, theta, bound_tol: float):
    """Cost, Gauss-Newton covariance and on-bound flags at `theta` (jit-safe): the residuals
    and their Jacobian by `bogie_jax.cost.residual_jacobian`, then `fit_statistics`."""
    r, jac = residual_jacobian(problem, theta, problem.args)
    return fit_statistics(problem.transform, theta, 0.5 * jnp.sum(r**2), jac, bound_tol)
