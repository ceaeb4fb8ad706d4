"""Least-squares fits step by step, for queued multistart batches.

`optx.least_squares` runs a whole fit inside one `while_loop`. A queued batch
(`runtime.queued_batch`) needs the same fit as `init`/`step`/`done`/`output`, so that a lane can
start the next start when its fit ends. This follows optimistix's own iteration (`solver.init`,
`solver.step`, `solver.terminate` on the previous iterate, a non-finite iterate ends the fit, the
step limit gives `nonlinear_max_steps_reached`; the status is carried as an `optimistix.RESULTS`
through the loop), so a fit stepped here takes the same steps and
ends with the same status as `LeastSquaresMethod.solve`. Only the Gauss-Newton family (LM,
Gauss-Newton, Dogleg) is stepped this way: their `postprocess` returns the iterate unchanged.
"""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import optimistix as optx

from .._householder import HouseholderQR
from ..runtime.queued_batch import IterativeMember, queued_runner
from ._jacobian import JacobianResiduals
from ._local import LeastSquaresMethod, LocalOutput
from ._problem import is_successful, problem_residuals


def least_squares_member(method: LeastSquaresMethod, problem_of, max_steps: int):
    """An `IterativeMember` of a least-squares fit with input `(theta0, data)`, output
    `(LocalOutput, cost)`: the fit, with `jacobian`, and its cost `0.5 r^T r` at `theta`.

    - `problem_of(data)`: the member's `LeastSquaresProblem` (its arrays travel in `data`, so
      the members of one batch may fit different data sets).

    The cost and Jacobian come from the solver's state, not from a new evaluation: after every
    `solver.step` of the Gauss-Newton family, `state.f_info` holds the residuals and the
    linearisation at the iterate the step returns (the new point if the step was accepted, else
    the previous iterate and its `f_info`, in one `filter_cond`; the first step is always
    accepted, as optimistix's searches must). Its `jac` is the product `J @ t` of the
    linearisation (`_jacobian.JacobianResiduals`: a stored matrix), materialised here by
    `as_matrix` (products with unit vectors: exact). A member is stepped at least once, so the
    output never holds the placeholders of `init`.
    """
    solver = method.solver
    options, tags = {}, frozenset()

    def fn(theta, problem):
        return problem_residuals(theta, problem), None

    def solver_init(theta0, problem):
        # `f_struct` is None: the Gauss-Newton family's `init` does not read it (optimistix
        # 0.1.0: it traces `f_info` itself, for its structure only). With `JacobianResiduals`
        # it traces the zero twin's linearisation, the same operator structure (`_jacobian`):
        # the real one traced the whole simulation (3 calls per batch trace, ~10 s each)
        if isinstance(problem.residuals, JacobianResiduals):
            problem = eqx.tree_at(lambda p: p.residuals, problem, problem.residuals.shape_twin())
        return solver.init(fn, theta0, problem, options, None, None, tags)

    def status(theta, problem, state):
        terminate, result = solver.terminate(fn, theta, problem, options, state, tags)
        return terminate, optx.RESULTS.where(
            jnp.all(jnp.isfinite(theta)), result, optx.RESULTS.nonfinite
        )

    def fit_info(state):
        """`(cost, J)` at the iterate of `state` (see above)."""
        r = jnp.ravel(state.f_info.residual)
        return 0.5 * jnp.sum(r**2), state.f_info.jac.as_matrix()

    # carry: (theta, steps, the state's arrays, terminate, result, data, cost, Jacobian)
    def init(x):
        theta0, data = x
        problem = problem_of(data)
        state = solver_init(theta0, problem)
        terminate, result = status(theta0, problem, state)
        dynamic = eqx.partition(state, eqx.is_array)[0]
        shapes = eqx.filter_eval_shape(fit_info, state)
        cost, jac = (jnp.zeros(s.shape, s.dtype) for s in shapes)
        return theta0, jnp.asarray(0), dynamic, terminate, result, data, cost, jac

    def step(carry):
        theta, steps, dynamic, _, _, data, _, _ = carry
        problem = problem_of(data)
        # the state's static part (operator structures) rebuilt in the caller's trace: inside
        # `shard_map` its shape structs carry the mesh, so one built outside would not match
        static = eqx.partition(solver_init(theta, problem), eqx.is_array)[1]
        state = eqx.combine(dynamic, static)
        new_theta, state, _ = solver.step(fn, theta, problem, options, state, tags)
        terminate, result = status(theta, problem, state)  # optimistix tests the old iterate
        cost, jac = fit_info(state)  # at `new_theta`
        dynamic = eqx.partition(state, eqx.is_array)[0]
        return new_theta, steps + 1, dynamic, terminate, result, data, cost, jac

    def done(carry):
        _, steps, _, terminate, result, _, _, _ = carry
        return terminate | (result != optx.RESULTS.successful) | (steps >= max_steps)

    def output(carry):
        theta, steps, _, terminate, result, _, cost, jac = carry
        # as optimistix: still running at the step limit -> nonlinear_max_steps_reached
        running = (result == optx.RESULTS.successful) & ~terminate
        result = optx.RESULTS.where(running, optx.RESULTS.nonlinear_max_steps_reached, result)
        return LocalOutput(theta, result, steps, steps, steps, jacobian=jac), cost

    return IterativeMember(init=init, step=step, done=done, output=output)


def queue_lanes(lanes, n_params: int, devices=None) -> int | None:
    """Lanes per device for a queued batch: an int or `None` (lock-step) as given, or `"auto"`:
    one fit per CPU device (vmapped fits buy a core no parallelism), `ceil(32 / (n + 1))` fits
    (about 32 residual tangents per step) per accelerator; `devices`: default all."""
    if lanes is None:
        return None
    if lanes == "auto":
        devices = jax.devices() if devices is None else devices
        if all(d.platform == "cpu" for d in devices):
            return 1
        return max(1, math.ceil(32 / (n_params + 1)))
    if isinstance(lanes, str) or int(lanes) < 1:
        raise ValueError(f'`lanes` must be "auto", None or an int >= 1, got {lanes!r}')
    return int(lanes)


def default_chunk(lanes, n_params: int, devices=None) -> int:
    """Starts per chunk of a chunked multistart when the caller gives none: every device's
    lanes once (`queue_lanes`), at least two per device."""
    devices = jax.devices() if devices is None else devices
    per_device = queue_lanes("auto" if lanes is None else lanes, n_params, devices)
    return len(devices) * max(2, per_device)


def supports_queue(method) -> bool:
    """Whether `method` can run as a queued batch: optimistix's Gauss-Newton family with the
    library's `HouseholderQR` steps (the queue runs each device on its own with `shard_map`,
    where lineax's own solvers fail; other methods run lock-step)."""
    if not (
        isinstance(method, LeastSquaresMethod)
        and isinstance(method.solver, optx.AbstractGaussNewton)
    ):
        return False
    return isinstance(getattr(method.solver.descent, "linear_solver", None), HouseholderQR)


def queued_fits(method, problem_of, max_steps: int, *, lanes: int, devices=None):
    """`run((thetas, data)) -> BatchResult` of `(LocalOutput, cost)`: least-squares fits as a
    queue with `lanes` fits in flight per device (`runtime.queued_batch`), each with its cost
    and residual Jacobian (`LocalOutput.jacobian`) at its end taken from the solver's state
    (`least_squares_member`: no evaluation after the fits), unsuccessful statuses flagged as
    failed (and, as every batch output, non-finite ones: a start whose cost or Jacobian is not
    finite has no statistics)."""
    return queued_runner(
        least_squares_member(method, problem_of, max_steps),
        lanes=lanes,
        devices=devices,
        failure_fn=lambda out: ~is_successful(out[0].result),
    )
