"""`fit`: one local fit of a problem, with its Gauss-Newton statistics (`_local.FitResult`)."""

import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._levenberg_marquardt import LevenbergMarquardt
from ._lm_fits import fit_one, lm_outputs
from ._local import FitResult, as_method, fit_statistics, statistics
from ._problem import as_problem, param_names, start_theta


@eqx.filter_jit
def _fit_jit(problem, theta0, method, max_steps, bound_tol):
    """A compiled method's fit and its statistics: from the Jacobian and cost the fit ended
    with where its output holds them, else from one more evaluation (`extra` = 1 in the
    counts)."""
    out = method.solve(problem, theta0, max_steps)
    if out.jacobian is None or out.cost is None:
        return out, statistics(problem, out.theta, bound_tol), 1
    tr = problem.transform
    return out, fit_statistics(tr, out.theta, out.cost, out.jacobian, bound_tol), 0


_FIT_STATISTICS = eqx.filter_jit(fit_statistics)


def _lm_fit(problem, theta0, method: LevenbergMarquardt, max_steps, bound_tol):
    """The Levenberg-Marquardt's fit (`_lm_fits.fit_one`) and its statistics from the Jacobian
    and cost it ended with."""
    out, cost = jax.tree.map(
        lambda x: x[0], lm_outputs([fit_one(problem, theta0, method, max_steps)]).outputs
    )
    theta, cost = jnp.asarray(out.theta), jnp.asarray(cost)
    stats = _FIT_STATISTICS(problem.transform, theta, cost, jnp.asarray(out.jacobian), bound_tol)
    return out, stats, 0


def fit(
    problem,
    start=None,
    *,
    method="lm",
    max_steps: int = 256,
    throw: bool = True,
    bound_tol: float = 1e-6,
) -> FitResult:
    """Fit the parameters of `problem` by a local method.

    **Arguments:**
    - `problem`: a `LeastSquaresProblem` or an `Objective` (see `as_problem`).
    - `start`: start in physical units, strictly inside the bounds (default: nominal).
    - `method`: a name from `LOCAL_METHODS` (default `"lm"`), a `LevenbergMarquardt`, an
      optimistix least-squares solver or minimiser, or an `AbstractLocalMethod`.
    - `max_steps`: solver step limit.
    - `throw`: raise `RuntimeError` if the solver did not succeed (else read `status`).
    - `bound_tol`: an estimate within this fraction of the box width of a bound is flagged.

    **Returns:** a `FitResult`.

    **Raises:** `ValueError` for an empty selection, a bad start or an unknown method name.
    """
    problem = as_problem(problem)
    method = as_method(method)
    theta0 = start_theta(problem.transform, start)
    tic = time.perf_counter()
    # `bound_tol` as an array: a traced input, so another value does not compile again
    tol = jnp.asarray(bound_tol, dtype=float)
    if isinstance(method, LevenbergMarquardt):
        out, stats, extra = _lm_fit(problem, theta0, method, max_steps, tol)
    else:
        out, stats, extra = _fit_jit(problem, theta0, method, max_steps, tol)
    out, stats = jax.block_until_ready((out, stats))
    wall = time.perf_counter() - tic
    result = FitResult(
        names=param_names(problem.transform, theta0.size),
        theta=jnp.asarray(out.theta),
        num_steps=jnp.asarray(out.num_steps),
        num_fn_evals=jnp.asarray(out.num_fn_evals + extra),
        num_jac_evals=jnp.asarray(out.num_jac_evals + extra),
        status=out.result,
        wall_time=np.asarray(wall),
        **stats,
    )
    if throw and not result.success:
        raise RuntimeError(
            f"fit did not succeed: {result.status_name} after {int(out.num_steps)} steps"
        )
    return result
