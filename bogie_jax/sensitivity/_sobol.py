"""Variance-based (Sobol') first-order and total indices from Saltelli's design.

Estimators are strategy objects (`Saltelli2010`, `Jansen`) acting on the model outputs
`f_a = f(A)`, `f_b = f(B)`, `f_ab[:, i] = f(AB_i)`; confidence intervals come from a
bootstrap over the `n` base rows with an explicit `key`. Model evaluations go through
`bogie_jax.runtime.batch.batch_runner` (vmapped in chunks, sharded over devices).
"""

import abc
from collections.abc import Callable, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
from jaxtyping import Array, Bool, Float, Int, PRNGKeyArray

from ..runtime.batch import batch_runner
from ._sampling import saltelli_sample
from ._validation import (
    check_bounds,
    check_positive_int,
    check_power_of_two,
    default_names,
)


class AbstractSobolEstimator(eqx.Module):
    """Estimators of the first-order and total indices from centred outputs and the variance."""

    @abc.abstractmethod
    def first_order(self, f_a, f_b, f_ab, variance) -> Float[Array, " d"]:
        """First-order indices S_i from `f_a`, `f_b` `(n,)`, `f_ab` `(n, d)`."""

    @abc.abstractmethod
    def total(self, f_a, f_b, f_ab, variance) -> Float[Array, " d"]:
        """Total indices S_Ti from `f_a`, `f_b` `(n,)`, `f_ab` `(n, d)`."""


def _jansen_total(f_a, f_ab, variance):
    return 0.5 * jnp.mean((f_a[:, None] - f_ab) ** 2, axis=0) / variance


class Saltelli2010(AbstractSobolEstimator):
    """The pair recommended by Saltelli et al. (2010), Table 2: (b) for S_i, (f) (Jansen) for
    S_Ti; the estimators of SALib's `sobol.analyze`.

    S_i = mean(f_B (f_ABi - f_A)) / V,  S_Ti = mean((f_A - f_ABi)^2) / (2 V).
    """

    def first_order(self, f_a, f_b, f_ab, variance):
        return jnp.mean(f_b[:, None] * (f_ab - f_a[:, None]), axis=0) / variance

    def total(self, f_a, f_b, f_ab, variance):
        return _jansen_total(f_a, f_ab, variance)


class Jansen(AbstractSobolEstimator):
    """Jansen (1999) estimators for both indices (Saltelli et al. 2010, Table 2 (d) and (f)).

    S_i = 1 - mean((f_B - f_ABi)^2) / (2 V),  S_Ti = mean((f_A - f_ABi)^2) / (2 V).
    """

    def first_order(self, f_a, f_b, f_ab, variance):
        return 1.0 - 0.5 * jnp.mean((f_b[:, None] - f_ab) ** 2, axis=0) / variance

    def total(self, f_a, f_b, f_ab, variance):
        return _jansen_total(f_a, f_ab, variance)


class SobolIndices(eqx.Module):
    """First-order and total Sobol' indices with bootstrap confidence intervals.

    **Fields:**
    - `names`: parameter names, in the order of the index vectors.
    - `first_order`, `total`: `(d,)` indices.
    - `first_order_ci`, `total_ci`: `(d, 2)` percentile-bootstrap intervals `[lower, upper]`.
    - `confidence`: level of the intervals (e.g. 0.95).
    - `n_evaluations`: model evaluations used, `n (d + 2)`.
    - `n_failed`: evaluations that failed (non-finite or flagged); if non-zero the indices are
      NaN.
    """

    names: tuple[str, ...] = eqx.field(static=True)
    first_order: Float[Array, " d"]
    total: Float[Array, " d"]
    first_order_ci: Float[Array, "d 2"]
    total_ci: Float[Array, "d 2"]
    confidence: Float[Array, ""]
    n_evaluations: Int[Array, ""]
    n_failed: Int[Array, ""]


def _estimate(estimator: AbstractSobolEstimator, f_a, f_b, f_ab):
    """Centre on the mean of all outputs (as SALib does) and apply `estimator`."""
    n_all = f_a.size + f_b.size + f_ab.size
    mean = (jnp.sum(f_a) + jnp.sum(f_b) + jnp.sum(f_ab)) / n_all
    f_a, f_b, f_ab = f_a - mean, f_b - mean, f_ab - mean
    variance = jnp.var(jnp.concatenate([f_a, f_b]))
    # A constant output has no variance to apportion: all indices are 0 (double where, no NaN).
    # A NaN variance (failed evaluations) stays NaN.
    ok = jnp.logical_not(variance <= jnp.finfo(variance.dtype).tiny)
    safe_var = jnp.where(ok, variance, 1.0)
    first = jnp.where(ok, estimator.first_order(f_a, f_b, f_ab, safe_var), 0.0)
    total = jnp.where(ok, estimator.total(f_a, f_b, f_ab, safe_var), 0.0)
    return first, total


@eqx.filter_jit
def _indices_and_intervals(estimator, f_a, f_b, f_ab, key, n_resamples, confidence):
    n, d = f_ab.shape
    first, total = _estimate(estimator, f_a, f_b, f_ab)
    rows = jr.randint(key, (n_resamples, n), 0, n)

    def resample(r):
        return _estimate(estimator, f_a[r], f_b[r], f_ab[r])

    # Bounded memory: about 2^22 resampled outputs at a time.
    batch = max(1, min(n_resamples, 2**22 // (n * (d + 2))))
    boot_first, boot_total = jax.lax.map(resample, rows, batch_size=batch)
    alpha = 1.0 - confidence
    q = jnp.array([alpha / 2, 1.0 - alpha / 2], dtype=first.dtype)
    first_ci = jnp.quantile(boot_first, q, axis=0).T
    total_ci = jnp.quantile(boot_total, q, axis=0).T
    return first, total, first_ci, total_ci


def _check_confidence(confidence) -> float:
    if not 0.0 < float(confidence) < 1.0:
        raise ValueError(f"`confidence` must lie in (0, 1), got {confidence!r}")
    return float(confidence)


def sobol_indices(
    f_a: Float[Array, " n"],
    f_b: Float[Array, " n"],
    f_ab: Float[Array, "n d"],
    *,
    key: PRNGKeyArray,
    estimator: AbstractSobolEstimator = Saltelli2010(),
    n_resamples: int = 1000,
    confidence: float = 0.95,
    names: Sequence[str] | None = None,
    n_failed=0,
) -> SobolIndices:
    """Sobol' indices from outputs already evaluated on a Saltelli design.

    **Arguments:**
    - `f_a`, `f_b`: outputs on the base matrices A and B, shape `(n,)`.
    - `f_ab`: outputs on AB_i (A with column i from B), shape `(n, d)`.
    - `key`: PRNG key of the bootstrap (rows resampled with replacement).
    - `estimator`: `Saltelli2010()` (default) or `Jansen()`.
    - `n_resamples`: bootstrap replicates; `confidence`: level of the percentile intervals.
    - `names`: parameter names (default `x0, x1, ...`).
    - `n_failed`: failed evaluations, recorded in the result.

    **Returns:** `SobolIndices`.
    """
    f_a, f_b, f_ab = jnp.asarray(f_a), jnp.asarray(f_b), jnp.asarray(f_ab)
    if f_a.ndim != 1 or f_b.shape != f_a.shape or f_ab.ndim != 2 or f_ab.shape[0] != f_a.size:
        raise ValueError(
            "need `f_a`, `f_b` of shape (n,) and `f_ab` of shape (n, d), got "
            f"{f_a.shape}, {f_b.shape}, {f_ab.shape}"
        )
    n, d = f_ab.shape
    names = tuple(names) if names is not None else default_names(d)
    if len(names) != d:
        raise ValueError(f"`names` has {len(names)} entries but `f_ab` has {d} columns")
    n_resamples = check_positive_int("n_resamples", n_resamples, lo=2)
    confidence = _check_confidence(confidence)
    first, total, first_ci, total_ci = _indices_and_intervals(
        estimator, f_a, f_b, f_ab, key, n_resamples, confidence
    )
    return SobolIndices(
        names=names,
        first_order=first,
        total=total,
        first_order_ci=first_ci,
        total_ci=total_ci,
        confidence=jnp.asarray(confidence),
        n_evaluations=jnp.asarray(n * (d + 2)),
        n_failed=jnp.asarray(n_failed, dtype=jnp.int32),
    )


def check_scalar_function(fn: Callable, d: int, dtype) -> None:
    """Raise unless `fn` maps a `(d,)` vector to a scalar (traced, never evaluated)."""
    out = jax.eval_shape(fn, jax.ShapeDtypeStruct((d,), dtype))
    if not (hasattr(out, "shape") and out.shape == ()):
        raise ValueError(f"`fn` must map a ({d},) vector to a scalar, got {out}")


def evaluate(fn, points, *, chunk_size, devices, failure_fn):
    """`fn` on each row of `points` through the batch runner; failed members become NaN."""
    result = batch_runner(fn, chunk_size=chunk_size, devices=devices, failure_fn=failure_fn)(points)
    failed: Bool[Array, " m"] = result.failed
    outputs = jnp.where(failed, jnp.nan, result.outputs)
    return outputs, failed


def sobol_analysis(
    fn: Callable[[Float[Array, " d"]], Float[Array, ""]],
    lower,
    upper,
    *,
    n: int,
    key: PRNGKeyArray,
    names: Sequence[str] | None = None,
    estimator: AbstractSobolEstimator = Saltelli2010(),
    n_resamples: int = 1000,
    confidence: float = 0.95,
    chunk_size: int | None = None,
    devices=None,
    failure_fn: Callable | None = None,
) -> SobolIndices:
    """First-order and total Sobol' indices of a scalar `fn` with inputs uniform on a box.

    Samples Saltelli's design (scrambled Sobol' points), evaluates `fn` on its `n (d + 2)`
    points with `batch_runner` (vmapped chunks of `chunk_size`, sharded over `devices`) and
    applies `estimator` with a bootstrap.

    **Arguments:**
    - `fn`: pure function of a `(d,)` parameter vector returning a scalar (a cost, an RMS
      acceleration, ...).
    - `lower`, `upper`: `(d,)` bounds, `lower < upper`.
    - `n`: base sample size, a power of two.
    - `key`: PRNG key (split for the scrambling and the bootstrap).
    - `names`: parameter names (default `x0, x1, ...`).
    - `estimator`, `n_resamples`, `confidence`: as in `sobol_indices`.
    - `chunk_size`, `devices`, `failure_fn`: passed to `batch_runner`.

    **Returns:** `SobolIndices` (NaN indices and `n_failed > 0` if any evaluation failed).

    **Raises:** `ValueError` for bounds with `lower >= upper`, `n` not a power of two, names of
    the wrong length, a bad `confidence` or a non-scalar `fn`, all before any evaluation.
    """
    lo, hi = check_bounds(lower, upper, names)
    names = tuple(names) if names is not None else default_names(lo.size)
    n = check_power_of_two("n", n)
    n_resamples = check_positive_int("n_resamples", n_resamples, lo=2)
    _check_confidence(confidence)
    sample_key, boot_key = jr.split(key)
    sample = saltelli_sample(lo, hi, n, key=sample_key)
    check_scalar_function(fn, lo.size, sample.a.dtype)
    y, failed = evaluate(
        fn, sample.stacked(), chunk_size=chunk_size, devices=devices, failure_fn=failure_fn
    )
    d = lo.size
    return sobol_indices(
        y[:n],
        y[n : 2 * n],
        y[2 * n :].reshape(d, n).T,
        key=boot_key,
        estimator=estimator,
        n_resamples=n_resamples,
        confidence=confidence,
        names=names,
        n_failed=jnp.sum(failed),
    )
