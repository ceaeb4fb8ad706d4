"""Sensitivity of an `Objective` (paper eq. 12): thin adapters over the generic core.

Parameters vary in physical units, uniformly over their bounds (the selection's, or `lower` /
`upper` given here); the function analysed is `objective.cost` or any scalar `output(theta)`
of the objective's unconstrained coordinates (e.g. an RMS frame acceleration from
`objective.predict(theta)`).
"""

from collections.abc import Callable, Sequence

import numpy as np
from jaxtyping import Array, Float, PRNGKeyArray

from ..cost import Objective
from ._screening import ScreeningGrid, ScreeningSweeps, screening_grid, screening_sweeps
from ._sobol import AbstractSobolEstimator, Saltelli2010, SobolIndices, sobol_analysis


def objective_bounds(objective: Objective, lower=None, upper=None):
    """Physical `(lower, upper)` for the sensitivity of `objective`, checked before any use.

    Default: the selection's bounds. A log-scale parameter has none (0, inf): select it with
    `bounds="spec"` (or explicit bounds) or pass `lower` and `upper` here.

    **Raises:** `ValueError` naming the parameter whose bounds are missing, of the wrong length,
    or outside the selection's bounds (where its transform is undefined).
    """
    sel = objective.selection
    sel_lo, sel_hi = np.asarray(sel.lower, dtype=float), np.asarray(sel.upper, dtype=float)
    lo = sel_lo if lower is None else np.asarray(lower, dtype=float)
    hi = sel_hi if upper is None else np.asarray(upper, dtype=float)
    for name, given in (("lower", lo), ("upper", hi)):
        if given.shape != sel_lo.shape:
            raise ValueError(
                f"`{name}` must have one value per selected parameter {sel.names}, got shape "
                f"{given.shape}"
            )
    for i, name in enumerate(sel.names):
        unit = f" {sel.units[i]}" if sel.units[i] else ""
        if not (np.isfinite(lo[i]) and np.isfinite(hi[i])):
            raise ValueError(
                f"`{name}` has no finite bounds ([{lo[i]:g}, {hi[i]:g}]{unit}, log scale): select "
                "it with `bounds='spec'` or pass `lower` and `upper`"
            )
        if lo[i] < sel_lo[i] or hi[i] > sel_hi[i]:
            raise ValueError(
                f"bounds of `{name}` [{lo[i]:g}, {hi[i]:g}]{unit} leave the selection's bounds "
                f"[{sel_lo[i]:g}, {sel_hi[i]:g}]{unit}"
            )
    return lo, hi


def objective_function(
    objective: Objective, output: Callable[[Float[Array, " n"]], Float[Array, ""]] | None = None
) -> Callable[[Float[Array, " n"]], Float[Array, ""]]:
    """`physical values -> output(selection.to_theta(values))`, default output `objective.cost`."""
    output = objective.cost if output is None else output
    to_theta = objective.selection.to_theta
    return lambda physical: output(to_theta(physical))


def sensitivity_sobol(
    objective: Objective,
    *,
    n: int,
    key: PRNGKeyArray,
    output: Callable | None = None,
    lower=None,
    upper=None,
    estimator: AbstractSobolEstimator = Saltelli2010(),
    n_resamples: int = 1000,
    confidence: float = 0.95,
    chunk_size: int | None = None,
    devices=None,
    failure_fn: Callable | None = None,
) -> SobolIndices:
    """Sobol' first-order and total indices of the cost (or `output`) of `objective`.

    The selected parameters are uniform over `objective_bounds(objective, lower, upper)`; the
    other arguments are those of `sobol_analysis`, which does the work (`n (d + 2)` solves,
    batched). Failed solves (infinite residuals) count in `n_failed` and make the indices NaN.

    **Raises:** `ValueError` for missing or bad bounds or `n` not a power of two, before any
    evaluation.
    """
    lo, hi = objective_bounds(objective, lower, upper)
    return sobol_analysis(
        objective_function(objective, output),
        lo,
        hi,
        n=n,
        key=key,
        names=objective.selection.names,
        estimator=estimator,
        n_resamples=n_resamples,
        confidence=confidence,
        chunk_size=chunk_size,
        devices=devices,
        failure_fn=failure_fn,
    )


def sensitivity_sweeps(
    objective: Objective,
    *,
    n_points: int,
    params: Sequence[str] | None = None,
    output: Callable | None = None,
    lower=None,
    upper=None,
    chunk_size: int | None = None,
    devices=None,
    failure_fn: Callable | None = None,
) -> ScreeningSweeps:
    """One-parameter sweeps of the cost (or `output`) about the selection's nominal values.

    **Arguments:** `params`: selected names to sweep (default all); the rest as
    `screening_sweeps` and `objective_bounds`.

    **Raises:** `ValueError` for an unknown parameter or bad bounds, before any evaluation.
    """
    lo, hi = objective_bounds(objective, lower, upper)
    sel = objective.selection
    return screening_sweeps(
        objective_function(objective, output),
        sel.nominal,
        lo,
        hi,
        n_points=n_points,
        params=params,
        names=sel.names,
        chunk_size=chunk_size,
        devices=devices,
        failure_fn=failure_fn,
    )


def sensitivity_grid(
    objective: Objective,
    *,
    params: tuple[str, str],
    n_points: int | tuple[int, int],
    output: Callable | None = None,
    lower=None,
    upper=None,
    chunk_size: int | None = None,
    devices=None,
    failure_fn: Callable | None = None,
) -> ScreeningGrid:
    """The cost (or `output`) over a grid of two selected parameters, the others nominal
    (paper figure 4).

    **Raises:** `ValueError` for unknown parameters or bad bounds, before any evaluation.
    """
    lo, hi = objective_bounds(objective, lower, upper)
    sel = objective.selection
    return screening_grid(
        objective_function(objective, output),
        sel.nominal,
        lo,
        hi,
        params=params,
        n_points=n_points,
        names=sel.names,
        chunk_size=chunk_size,
        devices=devices,
        failure_fn=failure_fn,
    )
