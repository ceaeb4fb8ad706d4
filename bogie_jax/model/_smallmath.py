"""3-vector and small-matrix helpers written as broadcast-and-sum.

On a CPU, XLA runs each tiny `dot` as a separate library call; broadcast-and-sum fuses with the
surrounding elementwise work, which makes the vector field several times faster.
"""

import jax.numpy as jnp


def matvec(a, x):
    """a @ x for a (..., n, m) and x (..., m)."""
    return jnp.sum(a * x[..., None, :], axis=-1)


def rows_times(points, rotation):
    """points @ rotation.T: rotate each row of `points` (n, 3) by `rotation` (3, 3)."""
    return jnp.sum(points[:, None, :] * rotation[None, :, :], axis=-1)


def solve_spd2(a, b):
    """Solve the 2 x 2 system a x = b by Cramer's rule."""
    det = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    return jnp.stack([a[1, 1] * b[0] - a[0, 1] * b[1], a[0, 0] * b[1] - a[1, 0] * b[0]]) / det


def solve3(a, b):
    """Solve the 3 x 3 system a x = b with the adjugate (a well conditioned, e.g. an inertia)."""
    c0 = jnp.cross(a[1], a[2])
    c1 = jnp.cross(a[2], a[0])
    c2 = jnp.cross(a[0], a[1])
    det = jnp.sum(a[0] * c0)
    return (c0 * b[0] + c1 * b[1] + c2 * b[2]) / det
