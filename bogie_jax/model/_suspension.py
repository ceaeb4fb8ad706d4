"""Suspension elements between bodies: deformations at the coupling points and element forces.

Each element joins a frame point A to a point B on a wheelset (primary) or on the car body
(secondary, anti-yaw dampers; the car body moves at constant speed). The deformation
Delta = r_A - r_B is measured in track (inertial) axes from the static equilibrium, so it is zero
for q = 0 on a perfect track. The force on A is -(K Delta + C Delta_dot + P), on B the opposite;
P is the static preload (primary springs carry frame and car body, secondary springs the car body).

Element order (8 elements): primary (wheelset 1 left, 1 right, 2 left, 2 right),
secondary (left, right), anti-yaw dampers (left, right).
"""

import jax
import jax.numpy as jnp

from ..params import BogieParams, ModelOptions
from ._constants import ModelConstants
from . import _kinematics as kin
from ._kinematics import axle_positions, frame_points, SIDES
from ._smallmath import rows_times


N_PRIMARY, N_SECONDARY, N_YAW = 4, 2, 2


def _frame_attachments(params: BogieParams):
    """Attachment points on the frame relative to its CG, frame axes, shape (8, 3)."""
    g = params.geometry
    r0 = params.contact.wheel_radius
    x = jnp.repeat(axle_positions(params), 2)
    s = jnp.tile(SIDES, 2)
    primary = jnp.stack([x, s * g.primary_semi_spacing, jnp.full(4, r0 - g.frame_cg_height)], -1)
    dz = g.secondary_height - g.frame_cg_height
    secondary = jnp.stack([jnp.zeros(2), SIDES * g.secondary_semi_spacing, jnp.full(2, dz)], -1)
    yaw = jnp.stack([jnp.zeros(2), SIDES * g.yaw_damper_semi_spacing, jnp.full(2, dz)], -1)
    return jnp.concatenate([primary, secondary, yaw])


def _body_attachments(q, w, params: BogieParams, const: ModelConstants):
    """Points B: axleboxes on the wheelsets, then car-body points (fixed), shape (8, 3)."""
    g = params.geometry
    local = jnp.stack([jnp.zeros(2), SIDES * g.primary_semi_spacing, jnp.zeros(2)], -1)
    y, psi, x = q[6:8], q[8:10], axle_positions(params)
    centres = jax.vmap(kin.centre, in_axes=(0, 0, 0, 0, None, None))(y, psi, w, x, params, const)
    rots = jax.vmap(kin.rotation, in_axes=(0, 0, 0, None, None))(y, psi, w, params, const)
    axleboxes = (centres[:, None, :] + jax.vmap(rows_times, in_axes=(None, 0))(local, rots)).reshape(4, 3)
    body_secondary = jnp.stack(
        [jnp.zeros(2), SIDES * g.secondary_semi_spacing, jnp.full(2, g.secondary_height)], -1
    )
    body_yaw = jnp.stack(
        [jnp.zeros(2), SIDES * g.yaw_damper_semi_spacing, jnp.full(2, g.secondary_height)], -1
    )
    return jnp.concatenate([axleboxes, body_secondary, body_yaw])


def deformations(q, w, params: BogieParams, const: ModelConstants):
    """Element deformations Delta = r_A - r_B [m], shape (8, 3).

    Attachment points coincide at static equilibrium (axleboxes at axle height, secondary points
    at the secondary seat height), so Delta is zero there.
    """
    r_a = frame_points(q, _frame_attachments(params), params)
    return r_a - _body_attachments(q, w, params, const)


def blowoff_damper(rate, c, blowoff_velocity, c_blowoff):
    """Bilinear damper force [N]: slope c up to the blow-off velocity, then c_blowoff."""
    knee = c * blowoff_velocity
    beyond = knee + c_blowoff * (jnp.abs(rate) - blowoff_velocity)
    return jnp.where(jnp.abs(rate) <= blowoff_velocity, c * rate, jnp.sign(rate) * beyond)


def element_forces(delta, delta_rate, params: BogieParams, const: ModelConstants, options: ModelOptions):
    """Element forces f = K Delta + C Delta_dot + P [N], shape (8, 3); the force on A is -f."""
    p, s, yd = params.primary, params.secondary, params.yaw_dampers
    zero = jnp.zeros_like(p.kx)
    k = jnp.stack(
        [jnp.stack([p.kx, p.ky, p.kz])] * N_PRIMARY
        + [jnp.stack([s.kx, s.ky, s.kz])] * N_SECONDARY
        + [jnp.stack([zero, zero, zero])] * N_YAW
    )
    c = jnp.stack(
        [jnp.stack([p.cx, p.cy, p.cz])] * N_PRIMARY
        + [jnp.stack([zero, s.cy, s.cz])] * N_SECONDARY
        + [jnp.stack([yd.c, zero, zero])] * N_YAW
    )
    preload_z = jnp.concatenate(
        [jnp.full(N_PRIMARY, -const.primary_preload), jnp.full(N_SECONDARY, const.secondary_preload), jnp.zeros(N_YAW)]
    )
    f = k * delta + c * delta_rate + jnp.stack([jnp.zeros(8), jnp.zeros(8), preload_z], -1)
    if options.nonlinear_dampers:
        yaw_rate = delta_rate[-N_YAW:, 0]
        nonlinear = blowoff_damper(yaw_rate, yd.c, yd.blowoff_velocity, yd.c_blowoff)
        f = f.at[-N_YAW:, 0].set(nonlinear)
    return f
