"""Simulated annealing (paper section 5.4) and the hybrid: annealing chains, then local fits.

Annealing keeps its points in the unconstrained coordinates `theta` but proposes its moves in
the physical box: a Gaussian step in the fraction of the bounds `u = (p - lower) / (upper -
lower)`, reflected at the bounds, for a bounded parameter, and a Gaussian step in `log p` for a
log-scale one (no upper bound). The step's scale shrinks with the temperature; Metropolis
acceptance, geometric cooling, all in one `lax.scan` (a fixed evaluation budget, counted exactly:
`n_iter + 1` cost evaluations per chain).

Why not a random walk in `theta` itself: the logistic map is flat far from the box centre, so a
hot chain drifts to large `|theta|` (the bounds) and, once cold, its small steps no longer change
the parameters; it cannot come back. A chain of 52 000 proposals did exactly that.
"""

import time

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from ..runtime.batch import batch_runner
from ._lm_fits import queue_lanes
from ._local import as_method
from ._multistart import collect, design_starts, local_fits
from ._problem import as_problem, bounds, param_names, start_theta


class SimulatedAnnealing(eqx.Module):
    """Annealing schedule.

    - `n_iter`: proposals (cost evaluations) per chain.
    - `initial_temperature`: in cost units; `None` = the cost at the start.
    - `final_ratio`: final / initial temperature (geometric cooling).
    - `step_size`, `min_step`: proposal scale at `T0`, shrinking as `sqrt(T / T0)`; in fractions
      of the box width for a bounded parameter, in `log p` for a log-scale one.
    """

    n_iter: int = eqx.field(static=True, default=2000)
    initial_temperature: float | None = None
    final_ratio: float = 1e-8
    step_size: float = 1.0
    min_step: float = 1e-6


class AnnealingResult(eqx.Module):
    """One chain's best point (`estimates` physical, `theta`), its `cost`, the
    `acceptance_rate`, the cost evaluations `num_fn_evals` and `wall_time` [s] (0-d array)."""

    names: tuple[str, ...] = eqx.field(static=True)
    estimates: jax.Array
    theta: jax.Array
    cost: jax.Array
    acceptance_rate: jax.Array
    num_fn_evals: jax.Array
    wall_time: jax.Array


class AnnealingState(eqx.Module):
    """Where a chain stands: the next iteration `k`, the current point and cost, the best point
    and cost so far, the accepted proposals, and the initial temperature `t0` [cost units]."""

    k: jax.Array
    theta: jax.Array
    cost: jax.Array
    best: jax.Array
    best_cost: jax.Array
    accepted: jax.Array
    t0: jax.Array


def _chain_cost(problem, theta):
    return jnp.nan_to_num(problem.cost(theta), nan=jnp.inf)


def _propose(transform, theta, scale, key):
    """A move from `theta`: reflected Gaussian step of `scale` box widths for a bounded
    parameter, Gaussian step of `scale` in `log p` for one without upper bound (both symmetric,
    as Metropolis acceptance assumes)."""
    lower, upper = jnp.asarray(transform.lower), jnp.asarray(transform.upper)
    boxed = jnp.isfinite(lower) & jnp.isfinite(upper)
    span = jnp.where(boxed, upper - lower, 1.0)
    base = jnp.where(boxed, lower, 0.0)
    p = transform.to_physical(theta)
    step = scale * jr.normal(key, theta.shape, theta.dtype)
    u = jnp.mod((p - base) / span + step, 2.0)
    u = jnp.where(u > 1.0, 2.0 - u, u)  # reflection at 0 and 1
    eps = jnp.finfo(theta.dtype).eps
    u = jnp.clip(u, eps, 1.0 - eps)  # strictly inside: finite theta
    moved = jnp.where(boxed, base + span * u, p * jnp.exp(jnp.where(boxed, 0.0, step)))
    return transform.to_theta(moved)


def anneal_start(problem, theta0, schedule: SimulatedAnnealing) -> AnnealingState:
    """A chain at `theta0` before its first proposal (one cost evaluation)."""
    f0 = _chain_cost(problem, theta0)
    t0 = (
        jnp.maximum(f0, 1e-300)
        if schedule.initial_temperature is None
        else jnp.asarray(schedule.initial_temperature, f0.dtype)
    )
    return AnnealingState(jnp.asarray(0), theta0, f0, theta0, f0, jnp.asarray(0), t0)


def anneal_steps(
    problem, state: AnnealingState, key, schedule: SimulatedAnnealing, length: int, keep_path=True
):
    """`length` (static) further proposals of the chain of `key`: `(state, path)`, `path` the
    best point after every proposal, shape `(length, n)` (`None` without `keep_path`).

    Steps run in pieces give the chain run in one piece, up to rounding (proposal `k` always
    uses the `k`-th of `jr.split(key, schedule.n_iter)`), so a long chain can be run and saved
    piece by piece; `state.k + length` must not exceed `schedule.n_iter`.
    """
    n = schedule.n_iter
    if not 1 <= length <= n:
        raise ValueError(f"`length` must be in [1, n_iter = {n}], got {length}")

    def step(st: AnnealingState, key):
        frac = st.k / n
        temp = st.t0 * schedule.final_ratio**frac
        scale = jnp.maximum(
            schedule.step_size * jnp.sqrt(schedule.final_ratio**frac), schedule.min_step
        )
        k_prop, k_acc = jr.split(key)
        trial = _propose(problem.transform, st.theta, scale, k_prop)
        f_trial = _chain_cost(problem, trial)
        accept = (f_trial < st.cost) | (jr.uniform(k_acc) < jnp.exp(-(f_trial - st.cost) / temp))
        accept = accept & jnp.isfinite(f_trial)
        theta = jnp.where(accept, trial, st.theta)
        f = jnp.where(accept, f_trial, st.cost)
        improved = f < st.best_cost
        best = jnp.where(improved, theta, st.best)
        f_best = jnp.where(improved, f, st.best_cost)
        st = AnnealingState(st.k + 1, theta, f, best, f_best, st.accepted + accept, st.t0)
        return st, (best if keep_path else None)

    keys = jax.lax.dynamic_slice_in_dim(jr.split(key, n), state.k, length)
    return jax.lax.scan(step, state, keys)


def anneal_theta(problem, theta0, key, schedule: SimulatedAnnealing):
    """Best `(theta, cost)`, acceptance rate and evaluation count of one chain (jit/vmap-safe)."""
    n = schedule.n_iter
    st, _ = anneal_steps(problem, anneal_start(problem, theta0, schedule), key, schedule, n, False)
    return st.best, st.best_cost, st.accepted / n, jnp.asarray(n + 1)


def anneal_path(problem, theta0, key, schedule: SimulatedAnnealing):
    """As `anneal_theta`, plus the chain's best point after every proposal, shape
    `(n_iter, n)`: row `k` is the best of the first `k + 2` evaluations (to measure how many
    evaluations annealing needs for a given accuracy)."""
    n = schedule.n_iter
    st, path = anneal_steps(problem, anneal_start(problem, theta0, schedule), key, schedule, n)
    return st.best, st.best_cost, st.accepted / n, jnp.asarray(n + 1), path


@eqx.filter_jit
def _anneal_jit(problem, theta0, key, schedule):
    return anneal_theta(problem, theta0, key, schedule)


def simulated_annealing(
    problem, start=None, *, key, schedule=SimulatedAnnealing()
) -> AnnealingResult:
    """One annealing chain from `start` (physical, default nominal); `key` is keyword-only."""
    problem = as_problem(problem)
    theta0 = start_theta(problem.transform, start)
    tic = time.perf_counter()
    best, f_best, rate, nfev = jax.block_until_ready(_anneal_jit(problem, theta0, key, schedule))
    return AnnealingResult(
        names=param_names(problem.transform, theta0.size),
        estimates=problem.transform.to_physical(best),
        theta=best,
        cost=f_best,
        acceptance_rate=rate,
        num_fn_evals=nfev,
        wall_time=np.asarray(time.perf_counter() - tic),
    )


def fit_hybrid(
    problem,
    *,
    key,
    n_chains: int = 4,
    schedule=SimulatedAnnealing(),
    method="lm",
    design="lhs",
    max_steps: int = 256,
    chunk_size: int | None = None,
    devices=None,
    cluster_tol: float = 1e-4,
    bound_tol: float = 1e-6,
    throw: bool = True,
):
    """The paper's hybrid: `n_chains` annealing chains from space-filling starts, then a local
    fit from each chain's best point; the chains run as one batch through `batch_runner`, the
    fits as `fit_multistart`'s (the Levenberg-Marquardt's as a queue, `lanes` "auto").

    **Returns:** a `MultistartResult` whose `starts` are the chains' starts, `ends` the local
    fits' ends, and whose evaluation counts include the annealing evaluations.
    """
    problem = as_problem(problem)
    method = as_method(method)
    bounds(problem.transform)
    design_key, chain_key = jr.split(key)
    thetas = design_starts(problem, design_key, n_chains, design)
    keys = jr.split(chain_key, n_chains)

    def chain(inputs):
        theta0, k = inputs
        return anneal_theta(problem, theta0, k, schedule)[0]

    tic = time.perf_counter()
    chains = batch_runner(chain, chunk_size=chunk_size, devices=devices)((thetas, keys))
    lanes = queue_lanes("auto", thetas.shape[1], devices)
    batch = local_fits(
        problem, method, np.asarray(chains.outputs), max_steps, lanes=lanes,
        chunk_size=chunk_size, devices=devices,
    )  # fmt: skip
    wall = time.perf_counter() - tic
    return collect(
        problem,
        thetas,
        batch,
        wall,
        cluster_tol=cluster_tol,
        bound_tol=bound_tol,
        throw=throw,
        extra_fevs=np.full(n_chains, schedule.n_iter + 1),
    )
