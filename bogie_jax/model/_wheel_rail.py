"""Wheel-rail contact forces of one wheelset: creepages (paper eq. 9), normal loads, Kalker creep
(paper eq. 10).

Creepages are the velocity of the wheel material at the contact point relative to the
(stationary) rail, divided by the speed, resolved in the contact frame (t_x along the track,
t_y = n x t_x in the contact plane, n the contact normal); the spin creepage is the wheel angular
velocity about n divided by the speed [1/m]. Terms (1)-(5) of paper eq. 9 all follow from this
rigid-body velocity; linearised they are the forms of reference doc 2.1.

Normal forces are constraint reactions of eq. 2-3 and do no virtual work (this is where the
gravitational stiffness W zeta comes from). The normal load used for the Hertz patch and the
creep coefficients is the static share plus the dynamic change from a quasi-static balance of the
wheelset: vertical forces and the roll moment of the axlebox forces (reference doc 3, 4.5).
Hertz with fixed curvatures gives a, b ~ N^(1/3), hence f11, f22 ~ N^(2/3) and f23 ~ N.
"""

import jax.numpy as jnp

from ..contact import CreepCoefficients, linear_creep_forces, shen_hedrick_elkins
from ..params import BogieParams, ModelOptions
from . import _kinematics as kin
from ._constants import ModelConstants
from ._kinematics import SIDES
from ._layout import GRAVITY
from ._smallmath import matvec


def contact_velocities(p, pd, w, wd, x, params: BogieParams, const: ModelConstants, speed):
    """Wheel material velocity relative to the rail at the (left, right) contact points [m/s].

    `x` [m], the wheelset's fixed longitudinal position, does not enter the velocity."""
    spin = speed / params.contact.wheel_radius
    omega = kin.angular_velocity(p[0], p[1], pd[0], pd[1], w, wd, params, const, spin)
    offsets = kin.contact_offsets(p[0], p[1], w, params, const)
    return _contact_velocities(p, pd, w, wd, omega, offsets, params, const, speed)


def _contact_velocities(p, pd, w, wd, omega, offsets, params, const, speed):
    """v e_x + centre rate (0, y_dot, z_dot) (eq. 2) + omega x offsets [m/s], (2, 3)."""
    z_dot = kin.height_rate(p[0], p[1], pd[0], pd[1], w, wd, params, const)
    centre = jnp.stack([speed, pd[0], z_dot])
    return centre + jnp.cross(omega, offsets)


def creepages(velocity, omega, normals, speed):
    """Longitudinal, lateral [-] and spin [1/m] creepages (left, right) from the contact
    velocities (2, 3), the wheelset angular velocity (3,) and the contact normals (2, 3)."""
    xi_x = velocity[:, 0] / speed
    xi_y = (velocity[:, 1] * normals[:, 2] - velocity[:, 2] * normals[:, 1]) / speed  # . n x e_x
    return xi_x, xi_y, matvec(normals, omega) / speed


def normal_loads(axlebox_forces, wdd, params: BogieParams, const: ModelConstants):
    """Normal force per wheel (left, right) [N]: static share plus dynamic change.

    `axlebox_forces` (2, 3) are the primary element forces on the (left, right) axleboxes; the
    downward load is minus their z component. Vertical balance with the wheelset inertia
    m (g + d_z''), roll balance about the axle centre N_l - N_r = b_p (V_l - V_r) / e0; then
    N = N_vertical / cos(delta0).
    """
    load = -axlebox_forces[:, 2]
    total = params.masses.wheelset.mass * (GRAVITY + wdd[1]) + load.sum()
    lever = params.geometry.primary_semi_spacing / params.contact.contact_semi_distance
    vertical = 0.5 * total + 0.5 * SIDES * lever * (load[0] - load[1])
    return vertical / jnp.cos(const.geometry.cone_angle)


def scaled_creep_coefficients(normal_load, const: ModelConstants) -> CreepCoefficients:
    """Creep coefficients at `normal_load` from those at the static load; zero without contact."""
    ratio = normal_load / const.static_normal_load
    in_contact = ratio > 0
    safe = jnp.where(in_contact, ratio, 1.0)
    two_thirds = jnp.where(in_contact, safe ** (2.0 / 3.0), 0.0)
    c = const.creep
    return CreepCoefficients(
        f11=c.f11 * two_thirds, f22=c.f22 * two_thirds, f23=c.f23 * jnp.where(in_contact, safe, 0.0)
    )


def contact_generalised_forces(
    p,
    pd,
    w,
    wd,
    x,
    normal_load,
    params: BogieParams,
    const: ModelConstants,
    options: ModelOptions,
    speed,
):
    """Generalised forces on (y, yaw) [N, N m] of the creep forces, Q = (dv_c/dp_dot)^T F.

    v_c = v e_x + (0, y_dot, z_dot) + omega x r_c with z_dot = dz/dp . p_dot + ... (eq. 2) and
    omega = psi_dot e_z + phi_dot Rz(psi) e_x + ... with phi_dot = (dphi/dy) y_dot + ... (eq. 3),
    so, summed over the two contacts with moments M = sum r_c x F about the centre,
        Q_y = sum F_y + dz/dy sum F_z + dphi/dy (Rz e_x) . M,   Q_yaw = dz/dpsi sum F_z + M_z.
    """
    spin = speed / params.contact.wheel_radius
    omega = kin.angular_velocity(p[0], p[1], pd[0], pd[1], w, wd, params, const, spin)
    offsets = kin.contact_offsets(p[0], p[1], w, params, const)
    velocity = _contact_velocities(p, pd, w, wd, omega, offsets, params, const, speed)
    normals = kin.contact_normals(p[0], w, params, const)
    xi_x, xi_y, xi_spin = creepages(velocity, omega, normals, speed)
    fx, fy = linear_creep_forces(xi_x, xi_y, xi_spin, scaled_creep_coefficients(normal_load, const))
    if options.creep_saturation:
        fx, fy = shen_hedrick_elkins(fx, fy, normal_load, params.contact.friction)
    forces = jnp.stack(
        [fx, fy * normals[:, 2], -fy * normals[:, 1]], axis=-1
    )  # fx e_x + fy n x e_x
    total = jnp.sum(forces, axis=0)
    moment = jnp.sum(jnp.cross(offsets, forces), axis=0)
    dz = kin.height_gradient(p[0], p[1], w, params, const)
    roll_axis = jnp.stack([jnp.cos(p[1]), jnp.sin(p[1]), jnp.zeros_like(p[1])])  # Rz(psi) e_x
    return jnp.stack(
        [
            total[1]
            + dz[0] * total[2]
            + kin.roll_slope_at(p[0], w, params, const) * jnp.sum(roll_axis * moment),
            dz[1] * total[2] + moment[2],
        ]
    )
