"""Kinetic energy (paper eq. 7) and Lagrange's inertia terms (paper eq. 6, 11), body by body.

For each body with coordinates p and kinetic energy T(p, p_dot, w, w_dot), Lagrange's equations
give M(p, w) p_ddot + h = Q with
    M = d^2 T / d p_dot^2,    h = d/dt(dT/dp_dot)|_{p_ddot = 0} - dT/dp,
the time derivative following p, the track input w and w_dot. The bodies are inertially
uncoupled (each T depends on its own coordinates only), so M is block diagonal: frame (6 x 6,
translation m I and rotation E_b^T J E_b) and one 2 x 2 block per wheelset (y, yaw).
"""

import jax
import jax.numpy as jnp

from ..params import BogieParams
from ._constants import ModelConstants
from . import _kinematics as kin
from ._smallmath import matvec


def _lagrange_terms(energy, p, pd, extra, extra_rate):
    """M and h of a body with kinetic energy `energy(p, pd, extra)`; `extra` (e.g. w, w_dot)
    changes at `extra_rate`."""
    momentum = jax.grad(energy, argnums=1)
    mass = jax.jacfwd(momentum, argnums=1)(p, pd, extra)
    _, rate = jax.jvp(momentum, (p, pd, extra), (pd, jnp.zeros_like(pd), extra_rate))
    return mass, rate - jax.grad(energy, argnums=0)(p, pd, extra)


def frame_rotation_terms(angles, rates, params: BogieParams):
    """Rotational M (3 x 3) and h (3,) of the frame, angles (roll, pitch, yaw)."""
    inertia = jnp.stack([params.masses.frame.ixx, params.masses.frame.iyy, params.masses.frame.izz])

    def energy(a, ad, _):
        omega_body = matvec(kin.frame_body_rates_matrix(a), ad)
        return 0.5 * jnp.sum(inertia * omega_body**2)

    return _lagrange_terms(energy, angles, rates, (), ())


def wheelset_energy(p, pd, track, params: BogieParams, const: ModelConstants, spin):
    """Kinetic energy [J] of one wheelset; p = (y, yaw), track = (w, w_dot)."""
    w, wd = track
    m = params.masses.wheelset
    inertia = jnp.stack([m.ixx, m.iyy, m.izz])
    _, z_rate = jax.jvp(
        lambda p_, w_: kin.height(p_[0], p_[1], w_, params, const), (p, w), (pd, wd)
    )
    omega = kin.angular_velocity(p[0], p[1], pd[0], pd[1], w, wd, params, const, spin)
    omega_body = matvec(kin.rotation(p[0], p[1], w, params, const).T, omega)
    return 0.5 * m.mass * (pd[0] ** 2 + z_rate**2) + 0.5 * jnp.sum(inertia * omega_body**2)


def wheelset_terms(p, pd, w, wd, wdd, params: BogieParams, const: ModelConstants, spin):
    """M (2 x 2) and h (2,) of one wheelset with coordinates p = (y, yaw)."""

    def energy(p_, pd_, track):
        return wheelset_energy(p_, pd_, track, params, const, spin)

    return _lagrange_terms(energy, p, pd, (w, wd), (wd, wdd))
