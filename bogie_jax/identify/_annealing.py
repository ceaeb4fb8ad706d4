"""Simulated annealing (paper section 5.4) and the hybrid: annealing chains, then local fits.

Annealing works in the unconstrained coordinates `theta`: Gaussian proposals whose scale
shrinks with the temperature, Metropolis acceptance, geometric cooling, all in one `lax.scan`
(a fixed evaluation budget, counted exactly: `n_iter + 1` cost evaluations per chain).
"""

import time

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from ._local import as_method
from ._multistart import collect, design_starts, run_batch
from ._problem import as_problem, bounds, param_names, start_theta


class SimulatedAnnealing(eqx.Module):
    """Annealing schedule.

    - `n_iter`: proposals (cost evaluations) per chain.
    - `initial_temperature`: in cost units; `None` = the cost at the start.
    - `final_ratio`: final / initial temperature (geometric cooling).
    - `step_size`, `min_step`: proposal scale in `theta` at `T0`, shrinking as `sqrt(T / T0)`.
    """

    n_iter: int = eqx.field(static=True, default=2000)
    initial_temperature: float | None = None
    final_ratio: float = 1e-8
    step_size: float = 1.0
    min_step: float = 1e-3


class AnnealingResult(eqx.Module):
    names: tuple[str, ...] = eqx.field(static=True)
    estimates: jax.Array
    theta: jax.Array
    cost: jax.Array
    acceptance_rate: jax.Array
    num_fn_evals: jax.Array
    wall_time: float = eqx.field(static=True)


def anneal_theta(problem, theta0, key, schedule: SimulatedAnnealing):
    """Best `(theta, cost)`, acceptance rate and evaluation count of one chain (jit/vmap-safe)."""
    return _anneal(problem, theta0, key, schedule, keep_path=False)[:4]


def anneal_path(problem, theta0, key, schedule: SimulatedAnnealing):
    """As `anneal_theta`, plus the chain's best point after every proposal, shape
    `(n_iter, n)`: row `k` is the best of the first `k + 2` evaluations (to measure how many
    evaluations annealing needs for a given accuracy)."""
    return _anneal(problem, theta0, key, schedule, keep_path=True)


def _anneal(problem, theta0, key, schedule, keep_path):
    cost = lambda th: jnp.nan_to_num(problem.cost(th), nan=jnp.inf)
    f0 = cost(theta0)
    t0 = (
        jnp.maximum(f0, 1e-300)
        if schedule.initial_temperature is None
        else jnp.asarray(schedule.initial_temperature)
    )
    n = schedule.n_iter

    def step(carry, inputs):
        theta, f, best, f_best, accepted = carry
        k, key = inputs
        frac = k / n
        temp = t0 * schedule.final_ratio**frac
        scale = jnp.maximum(
            schedule.step_size * jnp.sqrt(schedule.final_ratio**frac), schedule.min_step
        )
        k_prop, k_acc = jr.split(key)
        trial = theta + scale * jr.normal(k_prop, theta.shape, theta.dtype)
        f_trial = cost(trial)
        accept = (f_trial < f) | (jr.uniform(k_acc) < jnp.exp(-(f_trial - f) / temp))
        accept = accept & jnp.isfinite(f_trial)
        theta = jnp.where(accept, trial, theta)
        f = jnp.where(accept, f_trial, f)
        improved = f < f_best
        best = jnp.where(improved, theta, best)
        f_best = jnp.where(improved, f, f_best)
        return (theta, f, best, f_best, accepted + accept), (best if keep_path else None)

    keys = jr.split(key, n)
    init = (theta0, f0, theta0, f0, jnp.asarray(0))
    (_, _, best, f_best, accepted), path = jax.lax.scan(step, init, (jnp.arange(n), keys))
    return best, f_best, accepted / n, jnp.asarray(n + 1), path


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
        wall_time=time.perf_counter() - tic,
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
    fit from each chain's best point; chains and fits run as one batch through `batch_runner`.

    **Returns:** a `MultistartResult` whose `starts` are the chains' starts, `ends` the local
    fits' ends, and whose evaluation counts include the annealing evaluations.
    """
    problem = as_problem(problem)
    method = as_method(method)
    bounds(problem.transform)
    design_key, chain_key = jr.split(key)
    thetas = design_starts(problem, design_key, n_chains, design)
    keys = jr.split(chain_key, n_chains)

    def member(inputs):
        theta0, k = inputs
        best, _, _, _ = anneal_theta(problem, theta0, k, schedule)
        out = method.solve(problem, best, max_steps)
        return out, problem.cost(out.theta)

    tic = time.perf_counter()
    batch = run_batch(member, (thetas, keys), chunk_size=chunk_size, devices=devices)
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
