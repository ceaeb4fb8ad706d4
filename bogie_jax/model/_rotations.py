"""Elementary rotation matrices (right-handed, track axes x forward, y left, z up)."""

import jax.numpy as jnp


def rot_x(angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    one, zero = jnp.ones_like(c), jnp.zeros_like(c)
    return jnp.array([[one, zero, zero], [zero, c, -s], [zero, s, c]])


def rot_y(angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    one, zero = jnp.ones_like(c), jnp.zeros_like(c)
    return jnp.array([[c, zero, s], [zero, one, zero], [-s, zero, c]])


def rot_z(angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    one, zero = jnp.ones_like(c), jnp.zeros_like(c)
    return jnp.array([[c, -s, zero], [s, c, zero], [zero, zero, one]])
