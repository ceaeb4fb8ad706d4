"""Rotation matrices of the model in closed form (right-handed, track axes x forward, y left,
z up), from the cosines and sines of the angles.

The products of the elementary rotations Rx, Ry, Rz are multiplied out by hand (the same
matrices as in `tests/reference/bogie_twin.py`, which builds them as products) rather than assembled
from 3 x 3 matrices and multiplied: XLA then sees a few scalar multiplies per entry.
"""

import jax.numpy as jnp


def cardan_zyx(c, s):
    """Rz(yaw) Ry(pitch) Rx(roll) (3, 3) from c = cos and s = sin of (roll, pitch, yaw)."""
    c_r, c_p, c_y = c[0], c[1], c[2]
    s_r, s_p, s_y = s[0], s[1], s[2]
    return jnp.stack(
        [
            jnp.stack([c_y * c_p, c_y * s_p * s_r - s_y * c_r, c_y * s_p * c_r + s_y * s_r]),
            jnp.stack([s_y * c_p, s_y * s_p * s_r + c_y * c_r, s_y * s_p * c_r - c_y * s_r]),
            jnp.stack([-s_p, c_p * s_r, c_p * c_r]),
        ]
    )


def cardan_zyx_rates(c, s):
    """E_b (3, 3) with omega_body = E_b (roll_dot, pitch_dot, yaw_dot) for Rz Ry Rx: the columns
    are e_x, Rx^T e_y and Rx^T Ry^T e_z; c, s = cos, sin of (roll, pitch, yaw)."""
    one, zero = jnp.ones_like(c[0]), jnp.zeros_like(c[0])
    return jnp.stack(
        [
            jnp.stack([one, zero, -s[1]]),
            jnp.stack([zero, c[0], s[0] * c[1]]),
            jnp.stack([zero, -s[0], c[0] * c[1]]),
        ]
    )


def yaw_roll(c_yaw, s_yaw, c_roll, s_roll):
    """Rz(yaw) Rx(roll) (3, 3) from the cosines and sines of yaw and roll."""
    zero = jnp.zeros_like(c_yaw)
    return jnp.stack(
        [
            jnp.stack([c_yaw, -s_yaw * c_roll, s_yaw * s_roll]),
            jnp.stack([s_yaw, c_yaw * c_roll, -c_yaw * s_roll]),
            jnp.stack([zero, s_roll, c_roll]),
        ]
    )
