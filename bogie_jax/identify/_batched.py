"""Batched local fits that take the objective as a batch input, compiled once per structure.

`fit_multistart` closes over its problem, so every new data set (a new trial, a new chunk's
caller, a new command run) compiles the vmapped batch again: minutes for a simulation
objective. Here the objective's arrays are an input of the compiled batch (broadcast to every
member, or stacked: one data set per member), and the compiled runner is cached by the
objective's static structure, the method, `max_steps`, the devices and an optional annealing
schedule. Members and failure flags are as in `fit_multistart`; LM, Gauss-Newton and Dogleg fits
run as a queue (`lanes` in flight per device, see `bogie_jax.queued_batch`) unless `lanes=None`.
"""

import equinox as eqx
import jax
import jax.numpy as jnp

from ..batch import batch_runner
from ._annealing import anneal_theta
from ._iteration import queue_lanes, queued_fits, supports_queue
from ._local import as_method
from ._problem import SUCCESS, as_problem


_RUNNERS: dict = {}


class BatchedFits:
    """`fits(objective, thetas, keys=None, stacked=False) -> BatchResult` of `(LocalOutput, cost)`.

    - `objective`: an `Objective` (broadcast to every member) or, with `stacked=True`, objectives
      of one structure stacked along a leading member axis (`stack_objectives`).
    - `thetas` (N, n): starts in unconstrained coordinates; `keys` (N, 2): annealing keys
      (only with a `schedule`: a hybrid member anneals from its start, then fits).
    - `lanes`: fits in flight per device of a queued batch, `"auto"` (default, see
      `queue_lanes`) or an int; `None`, or with a `schedule`: every member at once in lock-step
      (`batch_runner`).
    """

    def __init__(
        self, objective, method="lm", max_steps=100, *, schedule=None, devices=None, lanes="auto"
    ):
        self.static = eqx.partition(objective, eqx.is_array)[1]
        self.method = as_method(method)
        method_ = self.method
        static = self.static
        lanes = queue_lanes(lanes, len(as_problem(objective).transform.lower))
        self.queued = lanes is not None and schedule is None and supports_queue(method_)
        if self.queued:
            problem_of = lambda dynamic: as_problem(eqx.combine(dynamic, static))
            self.runner = queued_fits(method_, problem_of, max_steps, lanes=lanes, devices=devices)
            return

        def member(inputs):
            theta0, key, dynamic = inputs
            problem = as_problem(eqx.combine(dynamic, static))
            if schedule is not None:
                theta0, _, _, _ = anneal_theta(problem, theta0, key, schedule)
            out = method_.solve(problem, theta0, max_steps)
            return out, problem.cost(out.theta)

        self.runner = batch_runner(
            member, devices=devices, failure_fn=lambda out: out[0].result != SUCCESS
        )

    def _inputs(self, objective, thetas, keys, stacked):
        n = thetas.shape[0]
        dynamic = eqx.partition(objective, eqx.is_array)[0]
        if not stacked:
            dynamic = jax.tree.map(lambda x: jnp.broadcast_to(x, (n, *jnp.shape(x))), dynamic)
        if self.queued:
            return thetas, dynamic
        if keys is None:
            keys = jnp.zeros((n, 2), jnp.uint32)
        return thetas, keys, dynamic

    def __call__(self, objective, thetas, keys=None, *, stacked=False):
        inputs = self._inputs(objective, thetas, keys, stacked)
        return jax.block_until_ready(self.runner(inputs))

    def compile(self, objective, thetas, keys=None, *, stacked=False) -> None:
        """Compile for these input shapes ahead of time, without running the fits."""
        self.runner.compile(self._inputs(objective, thetas, keys, stacked))


def batched_fits(
    objective, method="lm", max_steps=100, *, schedule=None, devices=None, lanes="auto"
):
    """A cached `BatchedFits` for `objective`'s structure (compiled once per process)."""
    static = eqx.partition(objective, eqx.is_array)[1]
    leaves, treedef = jax.tree.flatten(static)
    devs = tuple(jax.devices() if devices is None else devices)
    key = (
        treedef,
        tuple(map(repr, leaves)),
        repr(as_method(method)),
        max_steps,
        repr(schedule),
        devs,
        lanes,
    )
    if key not in _RUNNERS:
        _RUNNERS[key] = BatchedFits(
            objective, method, max_steps, schedule=schedule, devices=devices, lanes=lanes
        )
    return _RUNNERS[key]


def stack_objectives(objectives):
    """Objectives of one structure (e.g. one scenario with different noise) stacked along a
    leading axis, for `BatchedFits(..., stacked=True)`."""
    dyn = [eqx.partition(o, eqx.is_array)[0] for o in objectives]
    return jax.tree.map(lambda *xs: jnp.stack([jnp.asarray(x) for x in xs]), *dyn)
