"""Suspension elements between bodies: deformations at the coupling points and element forces.

Each element joins a frame point A to a point B on a wheelset (primary) or on the car body
(secondary, anti-yaw dampers; the car body moves at constant speed). The deformation
Delta = r_A - r_B is measured in track (inertial) axes from the static equilibrium, so it is zero
for q = 0 on a perfect track. The force on A is -(K Delta + C Delta_dot + P), on B the opposite;
P is the static preload (primary springs carry frame and car body, secondary springs the car body;
split over a group in proportion to the vertical stiffnesses, `spring_preloads`). Each element
has its own K and C (per-element parameters, `bogie_jax.params`).

Element order (8 elements): primary (wheelset 1 left, 1 right, 2 left, 2 right),
secondary (left, right), anti-yaw dampers (left, right).
"""

import jax
import jax.numpy as jnp

from ..params import BogieParams, ModelOptions
from . import _kinematics as kin
from ._constants import ModelConstants
from ._kinematics import SIDES, axle_positions, frame_points
from ._smallmath import matvec, rows_times


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
    axleboxes = (
        centres[:, None, :] + jax.vmap(rows_times, in_axes=(None, 0))(local, rots)
    ).reshape(4, 3)
    return jnp.concatenate([axleboxes, _carbody_attachments(params)])


def _carbody_attachments(params: BogieParams):
    """Car-body points of the secondary springs and anti-yaw dampers (fixed), shape (4, 3)."""
    g = params.geometry
    body_secondary = jnp.stack(
        [jnp.zeros(2), SIDES * g.secondary_semi_spacing, jnp.full(2, g.secondary_height)], -1
    )
    body_yaw = jnp.stack(
        [jnp.zeros(2), SIDES * g.yaw_damper_semi_spacing, jnp.full(2, g.secondary_height)], -1
    )
    return jnp.concatenate([body_secondary, body_yaw])


def deformations(q, w, params: BogieParams, const: ModelConstants):
    """Element deformations Delta = r_A - r_B [m], shape (8, 3).

    Attachment points coincide at static equilibrium (axleboxes at axle height, secondary points
    at the secondary seat height), so Delta is zero there.
    """
    r_a = frame_points(q, _frame_attachments(params), params)
    return r_a - _body_attachments(q, w, params, const)


def generalised_forces(
    q, qd, w, wd, params: BogieParams, const: ModelConstants, options: ModelOptions
):
    """Generalised suspension forces Q (10,) [N, N m] and the element forces f (8, 3) [N].

    In closed form (docs/model.md, suspension elements; paper eq. 8): with the frame lever
    l_k = R_f a_k, its angular velocity omega_f = R_f E_b (roll, pitch, yaw)_dot, and an axlebox
    at c_i + l_b, l_b = +-b_p R_i e_y, moving with omega_i = yaw_dot e_z + roll_dot Rz(yaw) e_x,
        Delta_dot = cg_dot + omega_f x l_k - (c_i_dot + omega_i x l_b),
    and Q = -(dDelta/dq)^T f: frame force -sum f, moment tau = -sum l_k x f (Q = E_b^T R_f^T tau),
    per wheelset with F = sum f and M = sum l_b x f over its axleboxes
        Q_y = F_y + dz/dy F_z + dphi/dy (Rz e_x) . M,   Q_yaw = dz/dyaw F_z + M_z
    (the structure of `_wheel_rail.contact_generalised_forces`).
    """
    g, geo = params.geometry, const.geometry
    r0 = params.contact.wheel_radius
    angles, rates = q[3:6], qd[3:6]
    rot_f = kin.frame_rotation(angles)
    body_rates = kin.frame_body_rates_matrix(angles)
    lever_a = rows_times(_frame_attachments(params), rot_f)  # (8, 3)
    omega_f = matvec(rot_f, matvec(body_rates, rates))
    cg = jnp.stack([q[0], q[1], g.frame_cg_height + q[2]])
    # wheelsets (axis 0): centres, axlebox levers and their rates (paper eq. 2-3)
    y, psi, y_dot, psi_dot = q[6:8], q[8:10], qd[6:8], qd[8:10]
    wt, wdt = w.T, wd.T  # (3, 2): alignment, level, cross level per wheelset
    y_rel = kin.relative_lateral(y, wt, r0)
    y_rel_dot = kin.relative_lateral(y_dot, wdt, r0)
    if kin.is_profile(const):  # slopes of the table's centre height and roll at y_rel
        _, slopes, _ = geo.evaluate(y_rel)
        dz_dy, k_roll = slopes[7], slopes[6]
    else:
        dz_dy = geo.vertical_lateral_coefficient * y_rel
        k_roll = kin.roll_slope(params, const)
    dz_dpsi = -geo.vertical_yaw_coefficient * psi
    z_dot = wdt[1] - r0 * wt[2] * wdt[2] + dz_dy * y_rel_dot + dz_dpsi * psi_dot
    phi_dot = wdt[2] + k_roll * y_rel_dot
    x = axle_positions(params)
    centres = jax.vmap(kin.centre, in_axes=(0, 0, 0, 0, None, None))(y, psi, w, x, params, const)
    rots = jax.vmap(kin.rotation, in_axes=(0, 0, 0, None, None))(y, psi, w, params, const)
    lever_b = (SIDES * g.primary_semi_spacing)[None, :, None] * rots[:, None, :, 1]  # (2, 2, 3)
    roll_axis = jnp.stack([jnp.cos(psi), jnp.sin(psi), jnp.zeros_like(psi)], axis=-1)  # Rz e_x
    omega_w = phi_dot[:, None] * roll_axis + psi_dot[:, None] * kin.E_Z
    centre_rate = jnp.stack([jnp.zeros_like(y_dot), y_dot, z_dot], axis=-1)
    axlebox = (centres[:, None, :] + lever_b).reshape(4, 3)
    axlebox_rate = (centre_rate[:, None, :] + jnp.cross(omega_w[:, None, :], lever_b)).reshape(4, 3)
    carbody = _carbody_attachments(params)
    delta = cg + lever_a - jnp.concatenate([axlebox, carbody])
    body_rate = jnp.concatenate([axlebox_rate, jnp.zeros_like(carbody)])
    delta_rate = qd[0:3] + jnp.cross(omega_f, lever_a) - body_rate
    f = element_forces(delta, delta_rate, params, const, options)
    torque = -jnp.sum(jnp.cross(lever_a, f), axis=0)
    frame_rotation_q = matvec(body_rates.T, matvec(rot_f.T, torque))
    box_f = f[:N_PRIMARY].reshape(2, 2, 3)
    total = jnp.sum(box_f, axis=1)  # (2, 3)
    moment = jnp.sum(jnp.cross(lever_b, box_f), axis=1)
    q_y = total[:, 1] + dz_dy * total[:, 2] + k_roll * jnp.sum(roll_axis * moment, axis=-1)
    q_psi = dz_dpsi * total[:, 2] + moment[:, 2]
    return jnp.concatenate([-jnp.sum(f, axis=0), frame_rotation_q, q_y, q_psi]), f


def blowoff_damper(rate, c, blowoff_velocity, c_blowoff):
    """Bilinear damper force [N]: slope c up to the blow-off velocity, then c_blowoff."""
    knee = c * blowoff_velocity
    beyond = knee + c_blowoff * (jnp.abs(rate) - blowoff_velocity)
    return jnp.where(jnp.abs(rate) <= blowoff_velocity, c * rate, jnp.sign(rate) * beyond)


def spring_preloads(kz, design_load):
    """Static vertical forces [N] of a group of vertical springs (the four primary or the two
    secondary springs) at q = 0, from their stiffnesses `kz` (n,) [N/m] and the group's nominal
    design load per spring `design_load` [N] (docs/model.md, "Suspension elements").

    The springs of a group have equal free lengths, set so that at q = 0 they are compressed by
    d = design_load / mean(kz): P_i = kz_i d = design_load kz_i / mean(kz). A symmetric group
    carries exactly the design load each (q = 0 is the rest state, as before per-element
    values); an uneven group carries the same total with another split at q = 0 and settles to
    a tilted rest state (`static_equilibrium`). A group without vertical stiffness (mean 0)
    carries the design load each. The mean is x_0 + mean(x - x_0), exact for equal values.
    """
    mean = kz[0] + jnp.mean(kz - kz[0])
    loaded = mean > 0
    return design_load * jnp.where(loaded, kz / jnp.where(loaded, mean, 1.0), 1.0)


def element_forces(
    delta, delta_rate, params: BogieParams, const: ModelConstants, options: ModelOptions
):
    """Element forces f = K Delta + C Delta_dot + P [N], shape (8, 3); the force on A is -f.

    K, C per element from the per-element parameters (primary per axlebox 1L, 1R, 2L, 2R;
    secondary and anti-yaw dampers per side), P from `spring_preloads`.
    """
    p, s, yd = params.primary, params.secondary, params.yaw_dampers
    per_box = lambda x: jnp.broadcast_to(x, (N_PRIMARY,))  # noqa: E731
    per_side = lambda x: jnp.broadcast_to(x, (N_SECONDARY,))  # noqa: E731
    zero = jnp.zeros(N_YAW, dtype=jnp.result_type(p.kx, float))
    k = jnp.concatenate(
        [
            jnp.stack([per_box(p.kx), per_box(p.ky), per_box(p.kz)], -1),
            jnp.stack([per_side(s.kx), per_side(s.ky), per_side(s.kz)], -1),
            jnp.stack([zero, zero, zero], -1),
        ]
    )
    yaw_c = per_side(yd.c)
    c = jnp.concatenate(
        [
            jnp.stack([per_box(p.cx), per_box(p.cy), per_box(p.cz)], -1),
            jnp.stack([zero, per_side(s.cy), per_side(s.cz)], -1),
            jnp.stack([yaw_c, zero, zero], -1),
        ]
    )
    preload_z = jnp.concatenate(
        [
            -spring_preloads(per_box(p.kz), const.primary_preload),
            spring_preloads(per_side(s.kz), const.secondary_preload),
            zero,
        ]
    )
    f = k * delta + c * delta_rate + jnp.stack([jnp.zeros(8), jnp.zeros(8), preload_z], -1)
    if options.nonlinear_dampers:
        yaw_rate = delta_rate[-N_YAW:, 0]
        nonlinear = blowoff_damper(
            yaw_rate, yaw_c, per_side(yd.blowoff_velocity), per_side(yd.c_blowoff)
        )
        f = f.at[-N_YAW:, 0].set(nonlinear)
    return f
