"""Batched local fits that take the objective as a batch input, compiled once per structure.

`fit_multistart` closes over its problem, so every new data set (a new trial, a new chunk's
caller, a new command run) compiles the batch again: minutes for a simulation objective. Here
the objective's arrays are an input of the compiled programs (broadcast to every member, or
stacked: one data set per member), and `batched_fits` keeps the runners it built in a small LRU
cache (`RUNNER_CACHE_SIZE` entries) keyed by equality (not `repr`) of the objective's static
structure, the method, `max_steps`, the devices, the lanes and an optional annealing schedule;
a key that cannot be hashed is not cached. Members and failure flags are as in
`fit_multistart`; Levenberg-Marquardt fits run as a queue (`lanes` in flight per device, see
`_lm_fits.LMFits`), other methods every member at once in lock-step; with a schedule, every
member anneals from its start first (one lock-step batch), then fits.
"""

import collections

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..runtime.batch import batch_runner
from ._annealing import anneal_theta
from ._lm_fits import LMFits, queue_lanes, supports_queue
from ._local import as_method
from ._problem import as_problem, is_successful


RUNNER_CACHE_SIZE = 8  # runners kept by `batched_fits` (each holds its compiled programs)
_RUNNERS: collections.OrderedDict = collections.OrderedDict()


class BatchedFits:
    """`fits(objective, thetas, keys=None, stacked=False) -> BatchResult` of `(LocalOutput, cost)`.

    - `objective`: an `Objective` (broadcast to every member) or, with `stacked=True`, objectives
      of one structure stacked along a leading member axis (`stack_objectives`).
    - `thetas` (N, n): starts in unconstrained coordinates; `keys` (N, 2): annealing keys
      (only with a `schedule`: a hybrid member anneals from its start, then fits).
    - `lanes`: Levenberg-Marquardt fits in flight per device, `"auto"` (default, see
      `queue_lanes`) or an int; `None`: every member at once.
    """

    def __init__(
        self, objective, method="lm", max_steps=100, *, schedule=None, devices=None, lanes="auto"
    ):
        self.static = eqx.partition(objective, eqx.is_array)[1]
        self.method, self.schedule = as_method(method), schedule
        method_, static = self.method, self.static
        lanes = queue_lanes(lanes, len(as_problem(objective).transform.lower), devices)
        problem_of = lambda dynamic: as_problem(eqx.combine(dynamic, static))
        # what the compiled programs close over, for the program store (`bogie_jax.runtime.batch`)
        identity = ("bogie_jax.identify.BatchedFits", static, method_, max_steps, lanes, schedule)
        self.anneal = None
        if schedule is not None:

            def chain(inputs):
                theta0, key, dynamic = inputs
                return anneal_theta(problem_of(dynamic), theta0, key, schedule)[0]

            runner = batch_runner(chain, devices=devices)
            self.anneal = runner.with_identity(identity + ("anneal",))
        if supports_queue(method_):
            fits = LMFits(method_, problem_of, max_steps, lanes=lanes, devices=devices)
            self.runner = fits.with_identity(identity)
            return

        def member(inputs):
            theta0, dynamic = inputs
            problem = problem_of(dynamic)
            out = method_.solve(problem, theta0, max_steps)
            cost = problem.cost(out.theta) if out.cost is None else out.cost
            return out, cost

        self.runner = batch_runner(
            member, devices=devices, failure_fn=lambda out: ~is_successful(out[0].result)
        ).with_identity(identity)

    def _inputs(self, objective, thetas, keys, stacked):
        """`(thetas, dynamic)` for the fits, and the annealing's `(thetas, keys, dynamic)`."""
        n = thetas.shape[0]
        dynamic = eqx.partition(objective, eqx.is_array)[0]
        if not stacked:
            # on the host: a device broadcast would compile a program per leaf
            dynamic = jax.tree.map(lambda x: np.broadcast_to(x, (n, *np.shape(x))), dynamic)
        if keys is None:
            keys = jnp.zeros((n, 2), jnp.uint32)
        return (thetas, dynamic), (thetas, keys, dynamic)

    def __call__(self, objective, thetas, keys=None, *, stacked=False):
        (thetas, dynamic), chains = self._inputs(objective, thetas, keys, stacked)
        if self.anneal is not None:
            thetas = np.asarray(self.anneal(chains).outputs)
        return jax.block_until_ready(self.runner((thetas, dynamic)))

    def compile(self, objective, thetas, keys=None, *, stacked=False) -> None:
        """Compile for these input shapes ahead of time, without running the fits."""
        fits, chains = self._inputs(objective, thetas, keys, stacked)
        if self.anneal is not None:
            self.anneal.compile(chains)
        self.runner.compile(fits)


def batched_fits(
    objective, method="lm", max_steps=100, *, schedule=None, devices=None, lanes="auto"
):
    """A `BatchedFits` for `objective`'s structure, reused from the bounded cache when an equal
    structure, method and settings were seen (see module docstring; `clear_runner_cache`)."""
    static = eqx.partition(objective, eqx.is_array)[1]
    leaves, treedef = jax.tree.flatten(static)
    devs = tuple(jax.devices() if devices is None else devices)
    key = (treedef, tuple(leaves), as_method(method), max_steps, schedule, devs, lanes)
    build = lambda: BatchedFits(
        objective, method, max_steps, schedule=schedule, devices=devices, lanes=lanes
    )
    try:
        hash(key)
    except TypeError:  # e.g. a method holding arrays: build, do not cache
        return build()
    if key in _RUNNERS:
        _RUNNERS.move_to_end(key)
    else:
        _RUNNERS[key] = build()
        while len(_RUNNERS) > RUNNER_CACHE_SIZE:
            _RUNNERS.popitem(last=False)
    return _RUNNERS[key]


def clear_runner_cache() -> None:
    """Drop the runners kept by `batched_fits` (and their compiled programs)."""
    _RUNNERS.clear()


def stack_objectives(objectives):
    """Objectives of one structure (e.g. one scenario with different noise) stacked along a
    leading axis, for `BatchedFits(..., stacked=True)`."""
    dyn = [eqx.partition(o, eqx.is_array)[0] for o in objectives]
    return jax.tree.map(lambda *xs: jnp.stack([jnp.asarray(x) for x in xs]), *dyn)
