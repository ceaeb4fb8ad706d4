"""Multistart: space-filling starts inside the bounds, all local fits as one sharded batch.

Levenberg-Marquardt fits run as a queue by default (`_lm_fits.LMFits`: a few fits in flight
per device, vmapped where a device holds several, see `queue_lanes`; a fit that has ended hands
its lane to the next start), so no lane waits for the slowest fit; `lanes=None` runs every
start at once. The other methods run every start at once in lock-step through
`runtime.batch.batch_runner` (in chunks). A fit takes the same steps whatever the lanes (up to
rounding: vmaps of different widths can round differently). A failed start (non-finite output
or unsuccessful solver status) is reported, never raised.
Distinct minima are clustered on the host in box-normalised coordinates.
"""

import abc
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from ..qmc import sobol_sequence
from ..runtime.batch import batch_runner
from ._lm_fits import LMFits, queue_lanes, supports_queue
from ._local import FitResult, as_method, fit_statistics, statistics
from ._problem import (
    as_problem,
    bounds,
    is_successful,
    param_names,
    start_theta,
    status_names,
)


class AbstractDesign(eqx.Module):
    """A space-filling design: `sample(key, n, dim) -> (n, dim)` points in the open unit cube."""

    @abc.abstractmethod
    def sample(self, key, n: int, dim: int) -> np.ndarray:
        raise NotImplementedError


class LatinHypercube(AbstractDesign):
    """Latin hypercube with a random point in each stratum (pure JAX)."""

    margin: float = 1e-6

    def sample(self, key, n, dim):
        return np.asarray(_latin_hypercube(key, n, dim, self.margin))


@eqx.filter_jit
def _latin_hypercube(key, n: int, dim: int, margin: float):
    """(n, dim) points in [margin, 1 - margin], one program (not one per operation)."""
    perm_key, jitter_key = jr.split(key)
    perms = jax.vmap(lambda k: jr.permutation(k, n))(jr.split(perm_key, dim)).T
    u = (perms + jr.uniform(jitter_key, (n, dim))) / n
    return margin + (1.0 - 2.0 * margin) * u


class Sobol(AbstractDesign):
    """Scrambled Sobol' points (`bogie_jax.qmc.sobol_sequence`): the first `n` of the next
    power-of-two design, so any start count works (balance holds exactly for powers of two)."""

    margin: float = 1e-6

    def sample(self, key, n, dim):
        u = np.asarray(sobol_sequence(max(2, 1 << (int(n) - 1).bit_length()), dim, key=key))[:n]
        return self.margin + (1.0 - 2.0 * self.margin) * u


DESIGNS = {"lhs": LatinHypercube(), "sobol": Sobol()}


def as_design(design) -> AbstractDesign:
    if isinstance(design, AbstractDesign):
        return design
    if isinstance(design, str) and design.lower() in DESIGNS:
        return DESIGNS[design.lower()]
    raise ValueError(
        f"unknown `design` {design!r}; choose one of {sorted(DESIGNS)} or an AbstractDesign"
    )


class Cluster(eqx.Module):
    """One distinct minimum: the best member's estimates and cost, and who reached it."""

    estimates: np.ndarray
    cost: float
    count: int
    members: tuple[int, ...]


class MultistartResult(eqx.Module):
    """Every start's record, the clustered minima (best first) and the answer `best`."""

    names: tuple[str, ...] = eqx.field(static=True)
    starts: np.ndarray  # (N, n) physical
    ends: np.ndarray  # (N, n) physical
    costs: np.ndarray  # (N,)
    status: np.ndarray  # (N,) str: optx.RESULTS member names (`RESULT_NAMES`)
    failed: np.ndarray  # (N,) bool
    num_steps: np.ndarray
    num_fn_evals: np.ndarray
    num_jac_evals: np.ndarray
    clusters: tuple[Cluster, ...]
    best: FitResult | None
    wall_time: np.ndarray  # [s], 0-d

    def records(self) -> list[dict]:
        """Per-start records (JSON-ready)."""
        return [
            dict(
                start=self.starts[i].tolist(),
                end=self.ends[i].tolist(),
                cost=float(self.costs[i]),
                status=str(self.status[i]),
                failed=bool(self.failed[i]),
                num_steps=int(self.num_steps[i]),
                num_fn_evals=int(self.num_fn_evals[i]),
            )
            for i in range(len(self.costs))
        ]


def cluster_minima(ends_unit, costs, ok, tol: float) -> tuple[list[list[int]], list[int]]:
    """Greedy clustering of successful ends, lowest cost first (max-norm distance `tol`)."""
    groups, heads = [], []
    for i in sorted(np.flatnonzero(ok), key=lambda j: costs[j]):
        for group, head in zip(groups, heads):
            if np.max(np.abs(ends_unit[i] - ends_unit[head])) <= tol:
                group.append(int(i))
                break
        else:
            groups.append([int(i)])
            heads.append(int(i))
    return groups, heads


def run_batch(member, batch, *, chunk_size, devices):
    """Run `member` over `batch` through the batch runner; flag unsuccessful statuses."""
    runner = batch_runner(
        member,
        chunk_size=chunk_size,
        devices=devices,
        failure_fn=lambda out: ~is_successful(out[0].result),
    )
    return jax.block_until_ready(runner(batch))


def local_member(problem, method, max_steps):
    def member(theta0):
        out = method.solve(problem, theta0, max_steps)
        return out, problem.cost(out.theta)

    return member


def local_fits(problem, method, thetas, max_steps, *, lanes, chunk_size=None, devices=None):
    """`BatchResult` of `(LocalOutput, cost)`: the fits of `problem` from each of `thetas`,
    the Levenberg-Marquardt's as a queue with `lanes` fits in flight per device (`None`: every
    start at once, or `chunk_size` per device), any other method's every start at once in
    lock-step (`run_batch`, in chunks of `chunk_size`)."""
    if supports_queue(method):
        lanes = chunk_size if lanes is None else lanes
        run = LMFits(method, lambda _: problem, max_steps, lanes=lanes, devices=devices)
        return run((thetas, None))
    member = local_member(problem, method, max_steps)
    return run_batch(member, thetas, chunk_size=chunk_size, devices=devices)


# the best fit's statistics: from the Jacobian its fit ended with (a small program), or, for
# methods whose state holds none, from a new residual-Jacobian evaluation
_FIT_STATISTICS = eqx.filter_jit(fit_statistics)
_STATISTICS = eqx.filter_jit(statistics)


def collect(
    problem,
    starts_theta,
    batch,
    wall,
    *,
    cluster_tol,
    bound_tol,
    throw,
    extra_fevs=0,
    jacobian_of=None,
):
    """Turn a batch of `(LocalOutput, cost)` into a `MultistartResult`.

    The best fit's statistics use the residual Jacobian its fit ended with (`out.jacobian`, or
    `jacobian_of(h)` for member `h` where the outputs carry none; `None` if unknown), with the
    batch's cost at that point; without one they evaluate the residual Jacobian again
    (`statistics`, one more residual and Jacobian evaluation in the counts).
    """
    out, costs = batch.outputs
    tr = problem.transform
    lower, upper = bounds(tr)
    ends = np.asarray(jax.vmap(tr.to_physical)(out.theta))
    costs, failed = np.asarray(costs), np.asarray(batch.failed)
    groups, heads = cluster_minima((ends - lower) / (upper - lower), costs, ~failed, cluster_tol)
    clusters = tuple(
        Cluster(ends[h], float(costs[h]), len(g), tuple(g)) for g, h in zip(groups, heads)
    )
    n_fev = np.asarray(out.num_fn_evals) + extra_fevs
    best = None
    if heads:
        h = heads[0]
        tol = jnp.asarray(bound_tol, dtype=float)  # traced: another value does not recompile
        if out.jacobian is not None:
            jac = out.jacobian[h]
        else:
            jac = None if jacobian_of is None else jacobian_of(h)
        if jac is None:
            stats, extra = _STATISTICS(problem, out.theta[h], tol), 1
        else:
            cost = jnp.asarray(costs[h], dtype=float)
            stats, extra = _FIT_STATISTICS(tr, out.theta[h], cost, jnp.asarray(jac), tol), 0
        best = FitResult(
            names=param_names(tr, lower.size),
            theta=out.theta[h],
            num_steps=out.num_steps[h],
            num_fn_evals=jnp.asarray(n_fev.sum() + extra),
            num_jac_evals=jnp.asarray(np.asarray(out.num_jac_evals).sum() + extra),
            status=jax.tree.map(lambda x: x[h], out.result),
            wall_time=np.asarray(wall),
            **stats,
        )
    elif throw:
        raise RuntimeError(f"all {len(costs)} starts failed")
    return MultistartResult(
        names=param_names(tr, lower.size),
        starts=np.asarray(jax.vmap(tr.to_physical)(starts_theta)),
        ends=ends,
        costs=costs,
        status=status_names(out.result),
        failed=failed,
        num_steps=np.asarray(out.num_steps),
        num_fn_evals=n_fev,
        num_jac_evals=np.asarray(out.num_jac_evals),
        clusters=clusters,
        best=best,
        wall_time=np.asarray(wall),
    )


def design_starts(problem, key, n_starts, design):
    """`n_starts` thetas from `design`, mapped into the bounds."""
    lower, upper = bounds(problem.transform)
    if n_starts < 1:
        raise ValueError(f"`n_starts` must be >= 1, got {n_starts}")
    u = as_design(design).sample(key, n_starts, lower.size)
    return jax.vmap(problem.transform.to_theta)(jnp.asarray(lower + (upper - lower) * u))


def fit_multistart(
    problem,
    *,
    key,
    n_starts: int = 32,
    method="lm",
    design="lhs",
    starts=None,
    max_steps: int = 256,
    lanes: int | str | None = "auto",
    chunk_size: int | None = None,
    devices=None,
    cluster_tol: float = 1e-4,
    bound_tol: float = 1e-6,
    throw: bool = True,
) -> MultistartResult:
    """Local fits from `n_starts` space-filling starts, run as one sharded batch.

    **Arguments:**
    - `problem`: a `LeastSquaresProblem` or an `Objective`.
    - `key`: PRNG key for the design (keyword-only, no default).
    - `n_starts`, `design` (`"lhs"`, `"sobol"` or an `AbstractDesign`), or explicit physical
      `starts` of shape `(N, n)` (then `n_starts`/`design` are ignored).
    - `method`, `max_steps`: as in `fit`; solves use `throw=False`.
    - `lanes`: Levenberg-Marquardt fits in flight per device: `"auto"` (default, see
      `queue_lanes`) or an int; `None`: every start at once (`chunk_size` per device if given).
    - `chunk_size`: members vmapped together in a lock-step batch of another method, or the
      LM's fits in flight per device with `lanes=None`; `devices`: devices to spread the
      starts over (default all).
    - `cluster_tol`: max-norm distance, as a fraction of each box width, within one minimum.
    - `throw`: raise if every start failed.

    **Returns:** a `MultistartResult`; `best` is the fit from the lowest-cost cluster.
    """
    problem = as_problem(problem)
    method = as_method(method)
    if starts is None:
        thetas = design_starts(problem, key, n_starts, design)
    else:
        thetas = jnp.stack([start_theta(problem.transform, s) for s in np.atleast_2d(starts)])
    lanes = queue_lanes(lanes, thetas.shape[1], devices)
    tic = time.perf_counter()
    batch = local_fits(
        problem, method, thetas, max_steps, lanes=lanes, chunk_size=chunk_size, devices=devices
    )
    wall = time.perf_counter() - tic
    return collect(
        problem, thetas, batch, wall, cluster_tol=cluster_tol, bound_tol=bound_tol, throw=throw
    )
