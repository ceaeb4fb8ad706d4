"""`identify`'s Levenberg-Marquardt fits: one compiled residual-Jacobian program for the fits in
flight, evaluated once per iteration of the host's `levenberg_marquardt_batch`.

The program (`evaluation`) gives each fit's residuals r, their forward-mode Jacobian J
(`bogie_jax.cost.residual_jacobian`, the library's one Jacobian path) and which parameters are
free at the points the LM asks for: a parameter within the method's `bound_tol` of a bound
(`_problem.on_bound`) is held there, left out of the LM's step and offset. Its column vanishes
there (a logistic map is flat), so the scale-invariant Marquardt step along it would be huge
and, cut to `max_step`, would shrink the others' steps to nothing.
It holds no optimiser loop, so its compile is that of one residual Jacobian.
Its members are split over the devices in contiguous blocks, each device's block run on its
own and vmapped (`bogie_jax.runtime.batch.per_device_runner`): `lanes` fits per device, and a
fit that ends hands its lane to the next start (the host's queue), so no lane waits for a
slower fit to end, only each evaluation for its slowest member.
"""

import copy
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import PartitionSpec

from ..cost import residual_jacobian
from ..runtime.batch import BatchResult, per_device_runner
from ._levenberg_marquardt import HostFit, LevenbergMarquardt, levenberg_marquardt_batch
from ._local import LocalOutput
from ._problem import on_bound, results_from_names


STATUS = {  # the LM's status -> the name of its `optimistix.RESULTS` member
    "converged": "successful",
    "max_steps": "nonlinear_max_steps_reached",
    "failed": "nonfinite",
}


def free_parameters(theta, problem, bound_tol):
    """Which parameters at `theta` are free, not held within `bound_tol` box widths of a bound
    (`_problem.on_bound`), `problem` one with a `transform` (a `LeastSquaresProblem`); without
    one, all (jit/vmap-safe)."""
    transform = getattr(problem, "transform", None)
    if transform is None or not hasattr(transform, "lower"):
        return jnp.ones(jnp.shape(theta), bool)
    return ~on_bound(transform, transform.to_physical(theta), bound_tol)


def evaluation(problem, theta, bound_tol):
    """`(r, J, free)` of `problem` at `theta` (module docstring; jit/vmap-safe)."""
    r, jac = residual_jacobian(problem, theta, problem.args)
    return r, jac, free_parameters(theta, problem, bound_tol)


_EVALUATE = eqx.filter_jit(evaluation)


def lm_outputs(fits: list[HostFit]) -> BatchResult:
    """The batch outputs `(LocalOutput, cost)` of `fits` (on the host; each fit's Jacobian at
    its end in the output, its cost there beside it), failed where not converged or not
    finite."""
    stack = lambda name: np.stack([np.asarray(getattr(f, name)) for f in fits])
    steps, evaluations = stack("steps"), stack("evaluations")
    status = [STATUS[f.status] for f in fits]
    out = LocalOutput(
        theta=stack("phi"), result=results_from_names(status), num_steps=steps,
        num_fn_evals=evaluations, num_jac_evals=evaluations, jacobian=stack("jac"),
    )  # fmt: skip
    finite = np.array([np.isfinite(f.cost) and np.all(np.isfinite(f.jac)) for f in fits])
    failed = np.array([s != "successful" for s in status]) | ~finite
    return BatchResult(outputs=(out, stack("cost")), failed=failed)


def fit_one(problem, theta0, method: LevenbergMarquardt, max_steps: int) -> HostFit:
    """One fit of `problem` from `theta0` (a batch of one; the evaluation compiled once per
    problem structure)."""

    def evaluate(points, members):
        del members
        r, jac, free = _EVALUATE(problem, points[0], method.bound_tol)
        return np.asarray(r)[None], np.asarray(jac)[None], np.asarray(free)[None]

    return levenberg_marquardt_batch(evaluate, [theta0], method, max_steps=max_steps)[0]


class LMFits:
    """`fits((thetas, data)) -> BatchResult` of `(LocalOutput, cost)` (`lm_outputs`): the LM
    from each of `thetas` (N, n), `lanes` fits in flight per device (module docstring).

    - `problem_of(data)`: a member's `LeastSquaresProblem`, `data` its row of the input's
      `data` (a pytree with a leading member axis, or `None`): the members may fit different
      data sets, and the problem's arrays are inputs of the compiled program.
    - `lanes`: fits in flight per device (`None`: every start at once).
    - `fits.compile((thetas, data))`: compile for that many starts ahead of time.
    """

    def __init__(self, method, problem_of, max_steps, *, lanes: int | None, devices=None):
        self.method, self.max_steps = method, max_steps
        self.devices = list(devices) if devices is not None else jax.devices()
        self.lanes = None if lanes is None else int(lanes)
        bound_tol = method.bound_tol

        def member(inputs):
            theta, data = inputs
            return evaluation(problem_of(data), theta, bound_tol)

        self.runner = per_device_runner(member, devices=self.devices)

    def with_identity(self, identity) -> "LMFits":
        """These fits, their program stored under `identity` where the store is on."""
        fits = copy.copy(self)
        fits.runner = self.runner.with_identity(identity)
        return fits

    def width(self, n_starts: int) -> int:
        """Fits in flight for `n_starts` starts."""
        if self.lanes is None:
            return n_starts
        return min(self.lanes * len(self.devices), n_starts)

    def compile(self, inputs) -> None:
        """Compile the evaluation for `inputs`' number of starts, without fitting."""
        thetas, data = inputs
        k = self.width(len(thetas))
        rows = jax.tree.map(lambda x: np.asarray(x)[:k], data)
        self.runner.compile((np.asarray(thetas)[:k], rows))

    def __call__(self, inputs) -> BatchResult:
        thetas, data = inputs
        thetas = np.asarray(thetas, dtype=float)
        fits = levenberg_marquardt_batch(
            _Evaluation(self.runner, data, self.devices), thetas, self.method,
            max_steps=self.max_steps,
            width=self.width(len(thetas)),
        )  # fmt: skip
        return lm_outputs(fits)


class _Evaluation:
    """`evaluate(points, members) -> (r, J, free)` of `LMFits` on `data`: the members' rows of
    `data` are placed on the devices once per set of members in flight (it changes only when a
    fit ends), not at every iteration, where they split evenly over the devices (else the
    runner pads and places them)."""

    def __init__(self, runner, data, devices):
        self.runner, self.data, self.n_devices = runner, data, len(devices)
        mesh = jax.sharding.Mesh(np.array(devices), ("batch",))
        self.sharding = jax.sharding.NamedSharding(mesh, PartitionSpec("batch"))
        self.members, self.rows = None, None

    def __call__(self, points, members):
        if self.members is None or not np.array_equal(members, self.members):
            rows = jax.tree.map(lambda x: np.asarray(x)[members], self.data)
            if len(members) % self.n_devices == 0:
                rows = jax.device_put(rows, self.sharding)
            self.members, self.rows = members, rows
        r, jac, free = self.runner((points, self.rows)).outputs
        return np.asarray(r), np.asarray(jac), np.asarray(free)


def queue_lanes(lanes, n_params: int, devices=None) -> int | None:
    """Fits in flight per device: an int or `None` (every start at once) as given, or
    `"auto"`: one fit per CPU device (vmapped fits buy a core no parallelism),
    `ceil(32 / (n + 1))` fits (about 32 residual tangents per evaluation) per accelerator;
    `devices`: default all."""
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
    """Whether `method` runs as a queue (the LM: `LMFits`); the other methods run every start
    at once in lock-step."""
    return isinstance(method, LevenbergMarquardt)
