"""Body kinematics: frame points, wheelset constraint coordinates (paper eq. 2-5), contact points.

Track axes: x forward, y left, z up, origin at rail level on the track centreline, moving with the
bogie at constant speed v. Wheelset 1 (leading) sits at x = +a, wheelset 2 at x = -a.
Per-wheelset functions take the wheelset's lateral displacement `y` [m], yaw `psi` [rad] and the
track irregularity under it, `w` (3,): alignment d_y [m], vertical level d_z [m], cross level
gamma_d [rad]. e0 is HALF the distance between the contact points (the paper uses the full one).

The contact geometry is a strategy (`ModelConstants.geometry`): a `ConeGeometry` gives the linear
laws of paper eq. 2-5 (this code path is unchanged); a `ProfileGeometry` gives the same
quantities as smooth functions of y_rel read from a profile pair's contact table (radii, contact
angles and contact positions per wheel, roll, centre height), with the yaw term of eq. 2 kept.
"""

import jax.numpy as jnp

from ..contact import ProfileGeometry
from ..params import BogieParams
from ._constants import ModelConstants
from ._rotations import cardan_zyx, cardan_zyx_rates, yaw_roll
from ._smallmath import rows_times


E_X = jnp.array([1.0, 0.0, 0.0])
E_Y = jnp.array([0.0, 1.0, 0.0])
E_Z = jnp.array([0.0, 0.0, 1.0])
SIDES = jnp.array([1.0, -1.0])  # left (+y), right (-y)


def axle_positions(params: BogieParams):
    """Longitudinal positions of the wheelsets relative to the frame centre [m], shape (2,)."""
    a = params.geometry.semi_wheelbase
    return jnp.stack([a, -a])


# ---------------------------------------------------------------------------------------- frame
def frame_rotation(angles):
    """Frame rotation matrix R = Rz(yaw) Ry(pitch) Rx(roll) for angles (roll, pitch, yaw)."""
    return cardan_zyx(jnp.cos(angles), jnp.sin(angles))


def frame_points(q, body_points, params: BogieParams):
    """Positions [m] of frame-fixed points (n, 3) given relative to the CG in frame axes."""
    cg = jnp.stack([q[0], q[1], params.geometry.frame_cg_height + q[2]])
    return cg + rows_times(body_points, frame_rotation(q[3:6]))


def frame_body_rates_matrix(angles):
    """E_b with omega_body = E_b (roll_dot, pitch_dot, yaw_dot) for the z-y-x Cardan sequence."""
    return cardan_zyx_rates(jnp.cos(angles), jnp.sin(angles))


# ------------------------------------------------------------------------ one wheelset (eq. 2-5)
def relative_lateral(y, w, r0):
    """Lateral displacement relative to the rolled track, u_y - d_y + r0 gamma_d [m]."""
    return y - w[0] + r0 * w[2]


def is_profile(const: ModelConstants) -> bool:
    """Whether the contact geometry is a profile table (a trace-time fact)."""
    return isinstance(const.geometry, ProfileGeometry)


def profile_terms(y, w, params: BogieParams, const: ModelConstants):
    """The table's quantities (values, d/dy, d2/dy2), each (8, ...), at y_rel (`QUANTITIES`)."""
    return const.geometry.evaluate(relative_lateral(y, w, params.contact.wheel_radius))


def height(y, psi, w, params: BogieParams, const: ModelConstants):
    """Rise of the wheelset centre above r0 [m], paper eq. 2."""
    g = const.geometry
    r0 = params.contact.wheel_radius
    if is_profile(const):
        rise = profile_terms(y, w, params, const)[0][7]
        return w[1] - 0.5 * r0 * w[2] ** 2 + rise - 0.5 * g.vertical_yaw_coefficient * psi**2
    y_rel = relative_lateral(y, w, r0)
    return (
        w[1]
        - 0.5 * r0 * w[2] ** 2
        + 0.5 * g.vertical_lateral_coefficient * y_rel**2
        - 0.5 * g.vertical_yaw_coefficient * psi**2
    )


def height_gradient(y, psi, w, params: BogieParams, const: ModelConstants):
    """Gradient of `height` with respect to (y, psi) [m/m, m/rad], shape (2,)."""
    g = const.geometry
    if is_profile(const):
        slope = profile_terms(y, w, params, const)[1][7]
        return jnp.stack([slope, -g.vertical_yaw_coefficient * psi])
    y_rel = relative_lateral(y, w, params.contact.wheel_radius)
    return jnp.stack([g.vertical_lateral_coefficient * y_rel, -g.vertical_yaw_coefficient * psi])


def roll_slope(params: BogieParams, const: ModelConstants):
    """d(roll)/dy [rad/m] of paper eq. 3 (cone: a constant)."""
    return const.geometry.roll_coefficient / params.contact.contact_semi_distance


def roll_slope_at(y, w, params: BogieParams, const: ModelConstants):
    """d(roll)/dy [rad/m] at the wheelset's lateral displacement `y` (the cone's constant, or
    the slope of the profile table's roll)."""
    if is_profile(const):
        return profile_terms(y, w, params, const)[1][6]
    return roll_slope(params, const)


def roll(y, w, params: BogieParams, const: ModelConstants):
    """Wheelset roll angle [rad], paper eq. 3."""
    if is_profile(const):
        return w[2] + profile_terms(y, w, params, const)[0][6]
    y_rel = relative_lateral(y, w, params.contact.wheel_radius)
    return w[2] + roll_slope(params, const) * y_rel


def rotation(y, psi, w, params, const):
    """Non-spinning wheelset rotation matrix Rz(yaw) Rx(roll)."""
    phi = roll(y, w, params, const)
    return yaw_roll(jnp.cos(psi), jnp.sin(psi), jnp.cos(phi), jnp.sin(phi))


def roll_rate(yd, wd, params: BogieParams, const: ModelConstants, y=None, w=None):
    """Time derivative of `roll` [rad/s] for the lateral rate `yd` [m/s] and track rates `wd`
    (a profile table needs the position `y`, `w` too)."""
    if is_profile(const):
        slope = roll_slope_at(y, w, params, const)
        return wd[2] + slope * relative_lateral(yd, wd, params.contact.wheel_radius)
    return wd[2] + roll_slope(params, const) * relative_lateral(yd, wd, params.contact.wheel_radius)


def height_rate(y, psi, yd, psid, w, wd, params: BogieParams, const: ModelConstants):
    """Time derivative of `height` (eq. 2) [m/s]."""
    g = const.geometry
    r0 = params.contact.wheel_radius
    if is_profile(const):
        slope = profile_terms(y, w, params, const)[1][7]
        return (
            wd[1]
            - r0 * w[2] * wd[2]
            + slope * relative_lateral(yd, wd, r0)
            - g.vertical_yaw_coefficient * psi * psid
        )
    return (
        wd[1]
        - r0 * w[2] * wd[2]
        + g.vertical_lateral_coefficient * relative_lateral(y, w, r0) * relative_lateral(yd, wd, r0)
        - g.vertical_yaw_coefficient * psi * psid
    )


def centre(y, psi, w, x, params: BogieParams, const: ModelConstants):
    """Wheelset centre [m] at longitudinal position `x`."""
    return jnp.stack([x, y, params.contact.wheel_radius + height(y, psi, w, params, const)])


def angular_velocity(y, psi, yd, psid, w, wd, params, const, spin):
    """Angular velocity [rad/s] with the constant spin `spin` = v/r0 about the axle:
    psi_dot e_z + phi_dot Rz(psi) e_x + spin Rz(psi) Rx(phi) e_y."""
    phi = roll(y, w, params, const)
    phi_rate = roll_rate(yd, wd, params, const, y, w)
    c, s, c_phi = jnp.cos(psi), jnp.sin(psi), jnp.cos(phi)
    return jnp.stack(
        [
            phi_rate * c - spin * s * c_phi,
            phi_rate * s + spin * c * c_phi,
            psid + spin * jnp.sin(phi),
        ]
    )


def rolling_radii(y, w, params: BogieParams, const: ModelConstants):
    """Rolling radii (left, right) r = r0 +- lambda y_rel [m], paper eq. 4."""
    r0 = params.contact.wheel_radius
    if is_profile(const):
        return profile_terms(y, w, params, const)[0][0:2]
    return r0 + const.geometry.conicity * relative_lateral(y, w, r0) * SIDES


def contact_normals(y, w, params: BogieParams, const: ModelConstants):
    """Unit contact normals (rail to wheel) (2 sides, 3), paper eq. 5.

    tan(delta) = tan(delta0) +- (eps/e0) y_rel is the contact angle in the track plane; the track
    plane is rolled by the cross level gamma_d.
    """
    e0 = params.contact.contact_semi_distance
    y_rel = relative_lateral(y, w, params.contact.wheel_radius)
    if is_profile(const):
        slope = profile_terms(y, w, params, const)[0][2:4]
    else:
        slope = (
            params.contact.cone_slope
            + const.geometry.contact_angle_coefficient / e0 * y_rel * SIDES
        )
    cos_delta = 1.0 / jnp.sqrt(1.0 + slope**2)  # cos(arctan(slope)), sin = slope cos
    local_y, local_z = -SIDES * slope * cos_delta, cos_delta
    c, s = jnp.cos(w[2]), jnp.sin(w[2])  # Rx(gamma_d) (0, local_y, local_z)
    return jnp.stack([jnp.zeros(2), c * local_y - s * local_z, s * local_y + c * local_z], axis=-1)


def contact_offsets(y, psi, w, params: BogieParams, const: ModelConstants):
    """Contact points relative to the centre [m], R_w (0, +-e0, -r) (2 sides, 3); a profile
    table gives the lateral positions (e_left, e_right) of the contact on the wheels."""
    e0 = params.contact.contact_semi_distance
    radii = rolling_radii(y, w, params, const)
    rot = rotation(y, psi, w, params, const)  # R (0, +-e0, -r) = +-e0 R e_y - r R e_z
    if is_profile(const):
        lateral = profile_terms(y, w, params, const)[0][4:6]
        return lateral[:, None] * rot[:, 1] - radii[:, None] * rot[:, 2]
    return (SIDES * e0)[:, None] * rot[:, 1] - radii[:, None] * rot[:, 2]
