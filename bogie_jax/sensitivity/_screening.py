"""Factor screening (paper section 4.2, figure 4): one-parameter sweeps and two-parameter grids.

All other parameters stay at `nominal`; the points of a screening form one batch evaluated by
`bogie_jax.runtime.batch.batch_runner`.
"""

from collections.abc import Callable, Sequence

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from ._sobol import check_scalar_function, evaluate
from ._validation import (
    check_bounds,
    check_point_in_bounds,
    check_positive_int,
    default_names,
    resolve_names,
)


class ScreeningSweeps(eqx.Module):
    """One-parameter sweeps: row `k` varies `names[k]` over its bounds, the rest at nominal.

    **Fields:**
    - `names`: swept parameters.
    - `values`: `(p, n_points)` values of the swept parameter.
    - `outputs`: `(p, n_points)` function values (NaN where the evaluation failed).
    - `failed`: `(p, n_points)` failure flags.
    - `nominal`: `(d,)` point about which the sweeps are taken.
    """

    names: tuple[str, ...] = eqx.field(static=True)
    values: Float[Array, "p n"]
    outputs: Float[Array, "p n"]
    failed: Bool[Array, "p n"]
    nominal: Float[Array, " d"]


class ScreeningGrid(eqx.Module):
    """A two-parameter grid: `outputs[i, j]` at `x = x_values[i]`, `y = y_values[j]`.

    **Fields:**
    - `names`: `(x name, y name)`.
    - `x_values`, `y_values`: grid lines of the two parameters.
    - `outputs`, `failed`: `(n_x, n_y)` function values (NaN where failed) and failure flags.
    - `nominal`: `(d,)` values of the parameters held fixed.
    """

    names: tuple[str, str] = eqx.field(static=True)
    x_values: Float[Array, " nx"]
    y_values: Float[Array, " ny"]
    outputs: Float[Array, "nx ny"]
    failed: Bool[Array, "nx ny"]
    nominal: Float[Array, " d"]


def _prepare(nominal, lower, upper, names):
    lo, hi = check_bounds(lower, upper, names)
    names = tuple(names) if names is not None else default_names(lo.size)
    x0 = check_point_in_bounds("nominal", nominal, lo, hi, names)
    return lo, hi, x0, names


def screening_sweeps(
    fn: Callable[[Float[Array, " d"]], Float[Array, ""]],
    nominal,
    lower,
    upper,
    *,
    n_points: int,
    params: Sequence[str | int] | None = None,
    names: Sequence[str] | None = None,
    chunk_size: int | None = None,
    devices=None,
    failure_fn: Callable | None = None,
) -> ScreeningSweeps:
    """Sweep each of `params` over `n_points` evenly spaced values between its bounds.

    **Arguments:**
    - `fn`: pure function of a `(d,)` parameter vector returning a scalar.
    - `nominal`: `(d,)` point, inside the bounds, for the parameters not swept.
    - `lower`, `upper`: `(d,)` bounds, `lower < upper`.
    - `n_points`: values per sweep (>= 2).
    - `params`: names or positions to sweep (default: all).
    - `names`: parameter names (default `x0, x1, ...`).
    - `chunk_size`, `devices`, `failure_fn`: passed to `batch_runner`.

    **Raises:** `ValueError` for bad bounds, a nominal outside them, an unknown parameter or
    `n_points < 2`, before any evaluation.
    """
    lo, hi, x0, names = _prepare(nominal, lower, upper, names)
    idx = resolve_names(params if params is not None else names, names)
    n_points = check_positive_int("n_points", n_points, lo=2)
    check_scalar_function(fn, lo.size, jnp.result_type(float))
    idx_arr = jnp.asarray(idx)
    values = jnp.linspace(jnp.asarray(lo)[idx_arr], jnp.asarray(hi)[idx_arr], n_points, axis=1)
    p, d = len(idx), lo.size
    points = jnp.broadcast_to(jnp.asarray(x0), (p, n_points, d))
    mask = jnp.arange(d)[None, None, :] == idx_arr[:, None, None]
    points = jnp.where(mask, values[:, :, None], points)
    y, failed = evaluate(
        fn, points.reshape(-1, d), chunk_size=chunk_size, devices=devices, failure_fn=failure_fn
    )
    return ScreeningSweeps(
        names=tuple(names[i] for i in idx),
        values=values,
        outputs=y.reshape(p, n_points),
        failed=failed.reshape(p, n_points),
        nominal=jnp.asarray(x0),
    )


def screening_grid(
    fn: Callable[[Float[Array, " d"]], Float[Array, ""]],
    nominal,
    lower,
    upper,
    *,
    params: tuple[str | int, str | int],
    n_points: int | tuple[int, int],
    names: Sequence[str] | None = None,
    chunk_size: int | None = None,
    devices=None,
    failure_fn: Callable | None = None,
) -> ScreeningGrid:
    """Evaluate `fn` on a grid over two parameters, the others at `nominal` (figure 4).

    **Arguments:**
    - `params`: the two parameters (names or positions): x, then y.
    - `n_points`: grid lines per parameter, one int or `(n_x, n_y)` (each >= 2).
    - the others as in `screening_sweeps`.

    **Raises:** `ValueError` as `screening_sweeps`, and unless exactly two distinct parameters
    are given, before any evaluation.
    """
    lo, hi, x0, names = _prepare(nominal, lower, upper, names)
    if isinstance(params, str) or len(params) != 2:
        raise ValueError(f"`params` must name exactly two parameters, got {params!r}")
    i, j = resolve_names(params, names)
    nx, ny = (n_points, n_points) if isinstance(n_points, int) else tuple(n_points)
    nx = check_positive_int("n_points", nx, lo=2)
    ny = check_positive_int("n_points", ny, lo=2)
    check_scalar_function(fn, lo.size, jnp.result_type(float))
    xs = jnp.linspace(lo[i], hi[i], nx)
    ys = jnp.linspace(lo[j], hi[j], ny)
    gx, gy = jnp.meshgrid(xs, ys, indexing="ij")
    points = jnp.broadcast_to(jnp.asarray(x0), (nx * ny, lo.size))
    points = points.at[:, i].set(gx.ravel()).at[:, j].set(gy.ravel())
    y, failed = evaluate(fn, points, chunk_size=chunk_size, devices=devices, failure_fn=failure_fn)
    return ScreeningGrid(
        names=(names[i], names[j]),
        x_values=xs,
        y_values=ys,
        outputs=y.reshape(nx, ny),
        failed=failed.reshape(nx, ny),
        nominal=jnp.asarray(x0),
    )
