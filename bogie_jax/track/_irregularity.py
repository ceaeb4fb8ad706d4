"""`TrackIrregularity`: sampled track irregularities and their C2 spline evaluation.

The three channels, in this order: 0 = lateral alignment `d_y` [m], 1 = vertical level `d_z` [m],
2 = cross-level angle `gamma_d` [rad] (positive = left rail higher).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.lax.linalg import tridiagonal_solve
from jaxtyping import Array, ArrayLike, Float


Channels = Float[Array, "3"]


class TrackSampleError(ValueError):
    """Invalid irregularity samples. `row`/`column` locate the offending sample (or are None)."""

    def __init__(self, message: str, *, row: int | None = None, column: int | None = None):
        super().__init__(message)
        self.row = row
        self.column = column


@jax.jit
def natural_spline_curvatures(values: Float[Array, "n c"], ds: ArrayLike) -> Float[Array, "n c"]:
    """Second derivatives `M` of the natural cubic spline through uniform samples.

    Solves `M[i-1] + 4 M[i] + M[i+1] = 6 (y[i-1] - 2 y[i] + y[i+1]) / ds^2` for the interior knots
    with `M[0] = M[n-1] = 0` (natural end conditions; de Boor, *A Practical Guide to Splines*,
    ch. IV). `ds` [m], `values` in channel units, result in channel units per m^2.
    """
    n = values.shape[0]
    if n < 3:
        return jnp.zeros_like(values)
    m = n - 2
    rhs = 6.0 * (values[:-2] - 2.0 * values[1:-1] + values[2:]) / jnp.square(ds)
    ones = jnp.ones(m, dtype=rhs.dtype)
    lower = ones.at[0].set(0.0)
    upper = ones.at[-1].set(0.0)
    interior = tridiagonal_solve(lower, 4.0 * ones, upper, rhs)
    edge = jnp.zeros((1, values.shape[1]), dtype=rhs.dtype)
    return jnp.concatenate([edge, interior, edge], axis=0)


class TrackIrregularity(eqx.Module):
    """Irregularity samples on a uniform distance grid, interpolated by a natural cubic spline.

    The spline is C2 (value, slope and curvature continuous), so the model may use `d2w/ds2`
    without discontinuities (at constant speed `v` the vertical and roll accelerations the track
    imposes on a wheelset are `v^2 d2w/ds2`).
    Outside `[s0, s0 + (n - 1) ds]` the track is perfect: all three outputs are zero (use faded
    samples, as `synthesise_track` makes, to avoid a step at the ends).

    **Fields:**

    - `s0`: distance of the first sample [m].
    - `ds`: sample spacing [m].
    - `values`: samples, shape `(n, 3)`: alignment [m], vertical [m], cross level [rad].
    - `curvatures`: the spline's second derivatives at the samples, shape `(n, 3)` [unit/m^2],
      computed once at construction.
    """

    s0: Float[Array, ""]
    ds: Float[Array, ""]
    values: Float[Array, "n 3"]
    curvatures: Float[Array, "n 3"]

    def __init__(self, s0: ArrayLike, ds: ArrayLike, values: ArrayLike):
        """**Arguments:** `s0` [m], `ds` [m] > 0, `values` of shape `(n, 3)` with `n >= 2`.

        Traceable (no value checks): use `TrackIrregularity.from_samples` for checked input.
        """
        values = jnp.asarray(values)
        if values.ndim != 2 or values.shape[1] != 3 or values.shape[0] < 2:
            raise ValueError(f"`values` must have shape (n, 3) with n >= 2; got {values.shape}")
        if not jnp.issubdtype(values.dtype, jnp.floating):
            values = values.astype(float)
        self.values = values
        self.s0 = jnp.asarray(s0, dtype=values.dtype)
        self.ds = jnp.asarray(ds, dtype=values.dtype)
        self.curvatures = natural_spline_curvatures(self.values, self.ds)

    @classmethod
    def from_samples(cls, distance: ArrayLike, values: ArrayLike) -> "TrackIrregularity":
        """Build from concrete samples, checking them first.

        **Arguments:**

        - `distance`: 1-D, strictly increasing, uniformly spaced (relative tolerance 1e-6)
          distances [m], at least 2.
        - `values`: shape `(len(distance), 3)`, finite: alignment [m], vertical [m],
          cross level [rad].

        **Raises:** `TrackSampleError` (a `ValueError`) naming the argument, the offending value
        and what is valid.
        """
        d, v = check_samples(distance, values)
        ds = (d[-1] - d[0]) / (d.size - 1)
        return cls(s0=d[0], ds=ds, values=v)

    @classmethod
    def perfect_track(cls) -> "TrackIrregularity":
        """A perfect track: zero irregularity everywhere."""
        return cls(s0=0.0, ds=1.0, values=np.zeros((2, 3)))

    @property
    def num_samples(self) -> int:
        return self.values.shape[0]

    def distance(self) -> Float[Array, " n"]:
        """The sample distances [m]."""
        return self.s0 + self.ds * jnp.arange(self.num_samples, dtype=self.values.dtype)

    def evaluate(self, s: ArrayLike) -> tuple[Channels, Channels, Channels]:
        """Irregularity and its distance derivatives at a scalar distance `s` [m].

        O(1): the interval is found by index arithmetic on the uniform grid. Differentiable in
        `s` and in the fields; jit- and vmap-compatible.

        **Returns:** `(w, dw_ds, d2w_ds2)`, each of shape `(3,)`: channel units, per m, per m^2.
        """
        return _evaluate(self, jnp.asarray(s, dtype=self.values.dtype))


@jax.jit
def _evaluate(track: TrackIrregularity, s: Array) -> tuple[Channels, Channels, Channels]:
    """The spline on `[s_i, s_i + h]` from knot values and curvatures (de Boor ch. IV).

    Written as one product: the value, slope and curvature rows of weights (3, 4) in the local
    coordinate t times the knot rows (y_i, y_i+1, M_i, M_i+1) (4, 3). XLA computes the `dot` once
    and its consumers read it; written as elementwise formulas, the dynamic slices and the cubic
    would be copied into every fusion that reads the track, i.e. all of the vector field.
    """
    h = track.ds
    x = (s - track.s0) / h
    last = track.num_samples - 1
    i = jnp.clip(jnp.floor(x), 0, last - 1).astype(jnp.int32)
    t = x - i
    u = 1.0 - t
    # rows i and i + 1 in one slice per array (i is in range, so no index wrapping or clamping)
    knots = jnp.concatenate(
        [
            jax.lax.dynamic_slice_in_dim(track.values, i, 2),
            jax.lax.dynamic_slice_in_dim(track.curvatures, i, 2),
        ]
    )
    zero, one = jnp.zeros_like(t), jnp.ones_like(t)
    weights = jnp.stack(
        [
            jnp.stack([u, t, h**2 / 6.0 * (u**3 - u), h**2 / 6.0 * (t**3 - t)]),
            jnp.stack(
                [-one / h, one / h, -h / 6.0 * (3.0 * u**2 - 1.0), h / 6.0 * (3.0 * t**2 - 1.0)]
            ),
            jnp.stack([zero, zero, u, t]),
        ]
    )
    inside = (x >= 0.0) & (x <= last)  # outside the samples the track is perfect
    weights = jnp.where(inside, weights, jnp.zeros_like(weights))
    w, dw, d2w = jnp.dot(weights, knots, precision=jax.lax.Precision.HIGHEST)
    return w, dw, d2w


def perfect_track() -> TrackIrregularity:
    """A perfect track: zero irregularity everywhere (same as `TrackIrregularity.perfect_track`)."""
    return TrackIrregularity.perfect_track()


def check_samples(distance: ArrayLike, values: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Validate concrete samples (see `TrackIrregularity.from_samples`); returns float arrays.

    **Raises:** `TrackSampleError` with `row`/`column` set to the offending sample where known.
    """
    d = np.asarray(distance, dtype=float)
    if d.ndim != 1 or d.size < 2:
        raise TrackSampleError(
            f"`distance` must be 1-D with at least 2 samples; got shape {d.shape}"
        )
    _check_finite("distance", d)
    steps = np.diff(d)
    bad = np.flatnonzero(steps <= 0.0)
    if bad.size:
        i = int(bad[0]) + 1
        raise TrackSampleError(
            f"`distance` must be strictly increasing; got distance[{i}] = {float(d[i])!r} after "
            f"distance[{i - 1}] = {float(d[i - 1])!r}",
            row=i,
        )
    bad = np.flatnonzero(np.abs(steps - steps[0]) > 1e-6 * steps[0])
    if bad.size:
        i = int(bad[0]) + 1
        raise TrackSampleError(
            f"`distance` must be uniformly spaced (relative tolerance 1e-6); got step "
            f"distance[{i}] - distance[{i - 1}] = {float(steps[i - 1])!r} m, expected "
            f"{float(steps[0])!r} m (the first step)",
            row=i,
        )
    v = np.asarray(values, dtype=float)
    if v.shape != (d.size, 3):
        raise TrackSampleError(
            f"`values` must have shape ({d.size}, 3) (alignment, vertical, cross level) to match "
            f"`distance`; got {v.shape}"
        )
    _check_finite("values", v)
    return d, v


def _check_finite(name: str, a: np.ndarray) -> None:
    bad = np.argwhere(~np.isfinite(a))
    if bad.size:
        idx = tuple(int(j) for j in bad[0])
        where = ", ".join(map(str, idx))
        raise TrackSampleError(
            f"`{name}` must be finite; got {name}[{where}] = {float(a[idx])!r}",
            row=idx[0],
            column=idx[1] if len(idx) > 1 else None,
        )
