"""Lagrange's inertia terms (paper eq. 6, 7, 11), body by body, in closed form.

For each body with coordinates p and kinetic energy T(p, p_dot, w, w_dot), Lagrange's equations
give M(p, w) p_ddot + h = Q with
    M = d^2 T / d p_dot^2,    h = d/dt(dT/dp_dot)|_{p_ddot = 0} - dT/dp,
the time derivative following p, the track input w and w_dot. The bodies are inertially
uncoupled (each T depends on its own coordinates only), so M is block diagonal: frame (6 x 6,
translation m I and rotation E_b^T J E_b) and one 2 x 2 block per wheelset (y, yaw).

Every velocity entering T is affine in p_dot, v = A(p, w) p_dot + b(p, w, w_dot), and
T = 1/2 v^T D v with D the body's mass or principal inertia. Then M = A^T D A and
    h = A^T D v_dot|_{p_ddot = 0} + (d/dt A - dv/dp)^T D v,
where the bracket vanishes for velocities that are time derivatives of coordinates (y_dot, z_dot,
phi_dot) and gives the gyroscopic terms for the body angular rates. The terms are written out
rather than obtained by nesting automatic differentiation through T: the adjoint of the vector
field is then several times cheaper. `tests/test_closed_form_terms.py` checks them against
Lagrange's equations applied to T by automatic differentiation.
"""

import jax.numpy as jnp

from ..params import BogieParams
from . import _kinematics as kin
from ._constants import ModelConstants


def frame_rotation_terms(angles, rates, params: BogieParams):
    """Rotational M (3 x 3) [kg m^2] and h (3,) [N m] of the frame, angles (roll, pitch, yaw).

    Body rates omega = E_b(angles) angles_dot (z-y-x Cardan sequence); M = E_b^T J E_b and
    h = E_b^T (J E_b_dot angles_dot + omega x J omega) (Euler's equations projected on the
    angles).
    """
    inertia = jnp.stack([params.masses.frame.ixx, params.masses.frame.iyy, params.masses.frame.izz])
    e_b = kin.frame_body_rates_matrix(angles)
    omega = jnp.sum(e_b * rates, axis=-1)
    (s_roll, s_pitch), (c_roll, c_pitch) = jnp.sin(angles[:2]), jnp.cos(angles[:2])
    roll_rate, pitch_rate, yaw_rate = rates[0], rates[1], rates[2]
    omega_rate = jnp.stack(  # d/dt(E_b) angles_dot: omega_dot at zero angular accelerations
        [
            -c_pitch * pitch_rate * yaw_rate,
            -s_roll * roll_rate * pitch_rate
            + (c_roll * c_pitch * roll_rate - s_roll * s_pitch * pitch_rate) * yaw_rate,
            -c_roll * roll_rate * pitch_rate
            - (s_roll * c_pitch * roll_rate + c_roll * s_pitch * pitch_rate) * yaw_rate,
        ]
    )
    torque = inertia * omega_rate + jnp.cross(omega, inertia * omega)
    mass = jnp.sum(e_b[:, :, None] * inertia[:, None, None] * e_b[:, None, :], axis=0)
    return mass, jnp.sum(e_b * torque[:, None], axis=0)


def wheelset_terms(p, pd, w, wd, wdd, params: BogieParams, const: ModelConstants, spin):
    """M (2 x 2) and h (2,) of one wheelset with coordinates p = (y, yaw).

    Kinetic energy (paper eq. 7 with the constraints eq. 2-3)
        T = m/2 (y_dot^2 + z_dot^2) + 1/2 (Ix phi_dot^2 + Iy (spin + sin(phi) psi_dot)^2
            + Iz (cos(phi) psi_dot)^2),
    z = height(y, psi, w) (eq. 2), phi = roll(y, w) (eq. 3); `spin` = v / r0 [rad/s];
    w, wd, wdd: the track input (alignment, level, cross level) and its time derivatives.
    """
    ws = params.masses.wheelset
    psi_dot = pd[1]
    if kin.is_profile(const):
        dz, z_ddot0, phi, phi_dot, phi_ddot0, k_roll = _profile_constraint_terms(
            p, pd, w, wd, wdd, params, const
        )
    else:
        dz, z_ddot0, phi, phi_dot, phi_ddot0, k_roll = _cone_constraint_terms(
            p, pd, w, wd, wdd, params, const
        )
    s, c = jnp.sin(phi), jnp.cos(phi)
    omega_y = spin + s * psi_dot
    omega_z = c * psi_dot
    mass = jnp.stack(
        [
            jnp.stack([ws.mass * (1 + dz[0] ** 2) + ws.ixx * k_roll**2, ws.mass * dz[0] * dz[1]]),
            jnp.stack(
                [ws.mass * dz[0] * dz[1], ws.mass * dz[1] ** 2 + ws.iyy * s**2 + ws.izz * c**2]
            ),
        ]
    )
    h_y = (
        ws.mass * dz[0] * z_ddot0
        + ws.ixx * k_roll * phi_ddot0
        - ws.iyy * c * k_roll * psi_dot * omega_y
        + ws.izz * s * k_roll * psi_dot * omega_z
    )
    h_psi = (
        ws.mass * dz[1] * z_ddot0
        + ws.iyy * c * phi_dot * (omega_y + s * psi_dot)
        - ws.izz * s * phi_dot * (omega_z + c * psi_dot)
    )
    return mass, jnp.stack([h_y, h_psi])


def _cone_constraint_terms(p, pd, w, wd, wdd, params, const):
    """dz/dp, z_ddot and phi, phi_dot, phi_ddot at p_ddot = 0, d phi/dy of the cone's linear laws
    (eq. 2-3: z = ... + zeta y_rel^2 / 2 - xi psi^2 / 2, phi = gamma_d + (sigma / e0) y_rel)."""
    g = const.geometry
    r0 = params.contact.wheel_radius
    c_lat, c_yaw = g.vertical_lateral_coefficient, g.vertical_yaw_coefficient
    k_roll = kin.roll_slope(params, const)  # d phi / d y
    y, psi = p[0], p[1]
    y_dot, psi_dot = pd[0], pd[1]
    y_rel = kin.relative_lateral(y, w, r0)
    y_rel_dot = kin.relative_lateral(y_dot, wd, r0)
    y_rel_ddot0 = -wdd[0] + r0 * wdd[2]  # d^2 y_rel / dt^2 at y_ddot = 0
    dz = kin.height_gradient(y, psi, w, params, const)
    z_ddot0 = (
        wdd[1]
        - r0 * (wd[2] ** 2 + w[2] * wdd[2])
        + c_lat * (y_rel_dot**2 + y_rel * y_rel_ddot0)
        - c_yaw * psi_dot**2
    )
    phi = kin.roll(y, w, params, const)
    phi_dot = wd[2] + k_roll * y_rel_dot
    phi_ddot0 = wdd[2] + k_roll * y_rel_ddot0
    return dz, z_ddot0, phi, phi_dot, phi_ddot0, k_roll


def _profile_constraint_terms(p, pd, w, wd, wdd, params, const):
    """The same terms for a profile table: z = ... + Z(y_rel) - xi psi^2 / 2, phi = gamma_d +
    Phi(y_rel); with y_rel varying, z_ddot and phi_ddot gain Z'' y_rel_dot^2, Phi'' y_rel_dot^2
    (the chain rule; the cone's Z'' = zeta, Phi'' = 0)."""
    g = const.geometry
    r0 = params.contact.wheel_radius
    psi, y_dot, psi_dot = p[1], pd[0], pd[1]
    value, slope, curvature = kin.profile_terms(p[0], w, params, const)
    y_rel_dot = kin.relative_lateral(y_dot, wd, r0)
    y_rel_ddot0 = -wdd[0] + r0 * wdd[2]
    dz = jnp.stack([slope[7], -g.vertical_yaw_coefficient * psi])
    z_ddot0 = (
        wdd[1]
        - r0 * (wd[2] ** 2 + w[2] * wdd[2])
        + curvature[7] * y_rel_dot**2
        + slope[7] * y_rel_ddot0
        - g.vertical_yaw_coefficient * psi_dot**2
    )
    k_roll = slope[6]
    phi = w[2] + value[6]
    phi_dot = wd[2] + k_roll * y_rel_dot
    phi_ddot0 = wdd[2] + curvature[6] * y_rel_dot**2 + k_roll * y_rel_ddot0
    return dz, z_ddot0, phi, phi_dot, phi_ddot0, k_roll
