"""`residual_jacobian`: the residual Jacobian dr/dtheta, the one way the library takes it.

Forward mode through the solve: one solve carries the `n` tangents of the basis vectors (`vmap`
of `jax.jvp`), which for a measurement (many residuals, few parameters) is far cheaper than
reverse mode (one backward pass per residual). An
`Objective` is switched to `diffrax.ForwardMode()` here, so callers never switch adjoints by
hand; `bogie_jax.identify.JacobianResiduals` (the residuals the least-squares solvers
linearise) materialises the same Jacobian. `residual_tangents` takes the same derivatives along
any directions in the parameters and the track records (a record's error, for
`bogie_jax.monitor`).
"""

import equinox as eqx
import jax
import jax.numpy as jnp

from ..track import TrackIrregularity


def forward_mode(objective):
    """`objective` differentiated in forward mode: `objective.forward_mode()` where it has one
    (an `Objective`), else unchanged (plain residual functions need no switch)."""
    switch = getattr(objective, "forward_mode", None)
    return switch() if callable(switch) else objective


def residual_jacobian(objective, theta, args=None):
    """`(r, J)`: residuals `r` (m,) and their Jacobian `J = dr/dtheta` (m, n) at `theta` (n,).

    `objective`: anything with `residuals(theta, args)` (an `Objective` or a
    `CorrectedObjective` over [theta, run corrections], switched to forward mode; a
    `bogie_jax.identify.LeastSquaresProblem`, with its `args`). Pure JAX: jit and vmap
    it with the objective as an argument (`eqx.filter_jit`).
    """
    objective = forward_mode(objective)
    fn = lambda th: jnp.ravel(objective.residuals(th, args))
    theta = jnp.asarray(theta)
    basis = jnp.eye(theta.size, dtype=theta.dtype)
    r, jac_t = jax.vmap(lambda v: jax.jvp(fn, (theta,), (v,)), out_axes=(None, 0))(basis)
    return r, jac_t.T


def track_part(objective):
    """`objective`'s filter spec (`equinox.filter`, `equinox.partition`) selecting the `values`
    and `curvatures` of its track records (`bogie_jax.track.TrackIrregularity`): what a change
    of a record changes (both linear in the record's samples)."""

    def mark(node):
        if not isinstance(node, TrackIrregularity):
            return False
        spec = object.__new__(TrackIrregularity)  # a spec, not a track: no __init__
        for name, on in (("s0", False), ("ds", False), ("values", True), ("curvatures", True)):
            object.__setattr__(spec, name, on)
        return spec

    return jax.tree.map(mark, objective, is_leaf=lambda x: isinstance(x, TrackIrregularity))


def residual_tangents(objective, theta, dtheta, dtracks, args=None):
    """`(r, D)`: residuals `r` (m,) at `theta` (n,) and their forward-mode derivatives `D`
    (K, m) along K directions in (theta, track records): `dtheta` (K, n) and `dtracks`, the
    track part of `objective` (`track_part`; before or after its switch to forward mode) with
    a leading axis K (the change of every record along each direction). One solve carries the K tangents; along the basis of theta with
    zero track changes, `D.T` is `residual_jacobian`'s J. Pure JAX (`eqx.filter_jit` it with
    the objective as an argument); `objective` as `residual_jacobian` takes it."""
    objective = forward_mode(objective)
    tracks, rest = eqx.partition(objective, track_part(objective))
    fn = lambda th, t: jnp.ravel(eqx.combine(t, rest).residuals(th, args))
    as_tracks = lambda b: jax.tree.unflatten(jax.tree.structure(tracks), jax.tree.leaves(b))
    jvp = lambda a, b: jax.jvp(fn, (theta, tracks), (a, as_tracks(b)))
    return jax.vmap(jvp, out_axes=(None, 0))(jnp.asarray(dtheta), dtracks)
