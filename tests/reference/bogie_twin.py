# long: an independent Newton-Euler twin of the whole model is one derivation;
# split, it would hide its independence.
"""Independent numpy twin of the 10-DOF bogie model (test oracle for `bogie_jax.model`).

Contract: `docs/model.md`. The JAX model derives its equations of motion from a Lagrangian by
automatic differentiation; this twin derives the same equations a different way, by hand:

- Kinematics written out explicitly: positions, velocities and accelerations of every body as
  functions of (q, q_dot, q_ddot) and the track inputs (w, w_dot, w_ddot), with all time
  derivatives differentiated by hand (no autodiff, no jax in this file).
- Newton-Euler per body plus virtual power (Kane's method):

      sum_bodies [ (dv/dq_dot)^T (F - m a) + (domega/dq_dot)^T (M - dH/dt) ] = 0,

  with F, M the resultant applied force and moment about the body's centre of gravity,
  a the CG acceleration and dH/dt = J_world omega_dot + omega x (J_world omega) the rate of the
  angular momentum in world (track) axes, J_world = R J R^T.
- Partial velocities dv/dq_dot, domega/dq_dot are exact by linearity: the hand-written velocity
  is evaluated at q_dot = 0 and at q_dot = each unit vector, and the difference taken.
  Likewise the q_ddot-linear part of the accelerations (giving the mass matrix) is the
  difference between accelerations at q_ddot = unit vectors and at q_ddot = 0; what remains at
  q_ddot = 0 is the velocity-dependent (gyroscopic, centripetal, track-driven) term.
- Point forces (suspension elements at their attachment points, creep forces at the wheel
  material points) enter as resultant force and moment r x F about the CG, which is the same as
  mapping them with the partial velocities of the material points
  (v_P = v_cg + omega x r, so dv_P/dq_dot . F = dv/dq_dot . F + domega/dq_dot . (r x F)).
- Gravity is the force m g on each CG. Wheel-rail normal forces are constraint forces and do
  not appear (the wheelset kinematics already satisfy the contact constraints).

Only the derived contact constants (contact geometry coefficients, static normal load and
Kalker coefficients) are taken from `bogie_jax.model.model_constants`; they are tested against
published tables elsewhere. Suspension parameters are per element (primary per axlebox 1L, 1R,
2L, 2R; secondary and anti-yaw dampers per side left, right), and the spring preloads are
computed here from the masses and the vertical stiffnesses (docs/model.md: equal free lengths in
each group of vertical springs).

The wheelset inertia must be axisymmetric (ixx == izz): the specification describes the
orientation of the spinning wheelset by the non-spinning R_i, which is exact only then.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


GRAVITY = 9.81
E_X = np.array([1.0, 0.0, 0.0])
E_Y = np.array([0.0, 1.0, 0.0])
E_Z = np.array([0.0, 0.0, 1.0])
N_DOF = 10

TrackInputs = Callable[[float], tuple[np.ndarray, np.ndarray, np.ndarray]]


def rot_x(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def cross(a, b) -> np.ndarray:
    """Cross product of 3-vectors, broadcasting over leading axes (np.cross is slow here)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    if a.ndim == 1 and b.ndim == 1:
        a0, a1, a2 = a.tolist()
        b0, b1, b2 = b.tolist()
        return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def perfect_track_inputs(t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Track inputs of a perfect track: all zeros."""
    z = np.zeros((2, 3))
    return z, z.copy(), z.copy()


@dataclass(frozen=True)
class TwinOptions:
    creep_saturation: bool = False
    flange_contact: bool = False
    nonlinear_dampers: bool = False


@dataclass(frozen=True)
class TwinConstants:
    """Plain-float copy of the parameters and derived constants the twin needs."""

    # masses
    m_f: float
    j_f: np.ndarray  # (3,) principal inertias of the frame
    m_w: float
    j_w: np.ndarray  # (3,) principal inertias of a wheelset
    m_c: float
    # geometry
    a: float
    b_p: float
    b_s: float
    b_yd: float
    h_f: float
    h_s: float
    # contact
    r0: float
    e0: float
    tan_delta0: float
    mu: float
    clearance: float
    k_flange: float
    # suspension, per element: rows 1L, 1R, 2L, 2R (primary) and left, right (secondary, yaw)
    k_p: np.ndarray  # (4, 3) stiffness (x, y, z) per axlebox
    c_p: np.ndarray  # (4, 3) damping per axlebox
    k_s: np.ndarray  # (2, 3) per side
    c_s: np.ndarray  # (2, 3) per side (no longitudinal damping)
    c_yd: np.ndarray  # (2,) anti-yaw damper per side
    v_blowoff: np.ndarray  # (2,)
    c_blowoff: np.ndarray  # (2,)
    # derived (from bogie_jax.model.model_constants)
    lam: float
    sigma: float
    eps: float
    zeta: float
    xi: float
    delta0: float
    f_p: np.ndarray  # (4,) static force of each primary spring at q = 0
    f_s: np.ndarray  # (2,) static force of each secondary spring at q = 0
    n0: float
    f11: float
    f22: float
    f23: float
    table: object = None  # a profile contact table (`reference.twin_table.TwinTable`) or None

    @classmethod
    def from_params(cls, params, derived=None) -> TwinConstants:
        """Read `params` (a `bogie_jax.params.BogieParams`) as floats. `derived` defaults to
        `bogie_jax.model.model_constants(params)`."""
        if derived is None:
            from bogie_jax.model import model_constants

            derived = model_constants(params)
        f = float
        m, g, c = params.masses, params.geometry, params.contact
        p, s, yd = params.primary, params.secondary, params.yaw_dampers
        geo, creep = derived.geometry, derived.creep
        table = None
        if not hasattr(geo, "conicity"):  # a profile table: the twin reads the same table
            try:
                from reference.twin_table import TwinTable
            except ImportError:  # tests/ imported as a package
                from tests.reference.twin_table import TwinTable
            table = TwinTable(geo)

        def per(x, n):
            return np.broadcast_to(np.asarray(x, dtype=float), (n,)).copy()

        k_p = np.stack([per(p.kx, 4), per(p.ky, 4), per(p.kz, 4)], axis=1)
        k_s = np.stack([per(s.kx, 2), per(s.ky, 2), per(s.kz, 2)], axis=1)
        # design loads: frame and car body on four primary springs, car body on two secondary
        load_p = (f(m.frame.mass) + f(m.carbody_mass)) * GRAVITY / 4
        load_s = f(m.carbody_mass) * GRAVITY / 2
        return cls(
            m_f=f(m.frame.mass),
            j_f=np.array([f(m.frame.ixx), f(m.frame.iyy), f(m.frame.izz)]),
            m_w=f(m.wheelset.mass),
            j_w=np.array([f(m.wheelset.ixx), f(m.wheelset.iyy), f(m.wheelset.izz)]),
            m_c=f(m.carbody_mass),
            a=f(g.semi_wheelbase),
            b_p=f(g.primary_semi_spacing),
            b_s=f(g.secondary_semi_spacing),
            b_yd=f(g.yaw_damper_semi_spacing),
            h_f=f(g.frame_cg_height),
            h_s=f(g.secondary_height),
            r0=f(c.wheel_radius),
            e0=f(c.contact_semi_distance),
            tan_delta0=f(c.cone_slope),
            mu=f(c.friction),
            clearance=f(c.flange_clearance),
            k_flange=f(c.flange_stiffness),
            k_p=k_p,
            c_p=np.stack([per(p.cx, 4), per(p.cy, 4), per(p.cz, 4)], axis=1),
            k_s=k_s,
            c_s=np.stack([np.zeros(2), per(s.cy, 2), per(s.cz, 2)], axis=1),
            c_yd=per(yd.c, 2),
            v_blowoff=per(yd.blowoff_velocity, 2),
            c_blowoff=per(yd.c_blowoff, 2),
            lam=np.nan if table else f(geo.conicity),
            sigma=np.nan if table else f(geo.roll_coefficient),
            eps=np.nan if table else f(geo.contact_angle_coefficient),
            zeta=np.nan if table else f(geo.vertical_lateral_coefficient),
            xi=f(geo.vertical_yaw_coefficient),
            delta0=f(geo.cone_angle),
            f_p=_equal_free_length_loads(k_p[:, 2], load_p),
            f_s=_equal_free_length_loads(k_s[:, 2], load_s),
            n0=f(derived.static_normal_load),
            f11=f(creep.f11),
            f22=f(creep.f22),
            f23=f(creep.f23),
            table=table,
        )


def _equal_free_length_loads(kz: np.ndarray, design_load: float) -> np.ndarray:
    """Static forces [N] at q = 0 of vertical springs with equal free lengths: compressed by
    d = design_load / mean(kz), spring i carries kz_i d (the design load each when all kz are
    equal; the design load each when the group has no stiffness)."""
    mean = float(np.mean(kz))
    if mean <= 0.0:
        return np.full(kz.shape, design_load)
    return kz * (design_load / mean)


@dataclass
class _WheelsetPose:
    """Configuration-level quantities of one wheelset (depend on q and w only)."""

    x: float  # longitudinal position of the centre (+a or -a)
    y: float
    psi: float
    y_rel: float
    gamma: float  # cross level under the wheelset
    u_z: float
    phi: float
    centre: np.ndarray  # (3,)
    rot: np.ndarray  # R_i = Rz(psi) Rx(phi)
    axis_x: np.ndarray  # Rz(psi) e_x: direction of the roll rate
    axle: np.ndarray  # e_a = R_i e_y
    table: tuple | None = None  # profile table (values, d/dy, d2/dy2) at y_rel, or None (cone)


@dataclass
class _Pose:
    rot_f: np.ndarray
    cg_f: np.ndarray
    # frame angular-velocity directions for roll_dot, pitch_dot, yaw_dot
    b_roll: np.ndarray
    b_pitch: np.ndarray
    b_yaw: np.ndarray
    wheelsets: tuple[_WheelsetPose, _WheelsetPose]


class BogieTwin:
    """Numpy reference of the bogie equations of motion M q_ddot + h = Q (docs/model.md).

    **Arguments:**

    - `params`: a `bogie_jax.params.BogieParams` (read as floats).
    - `speed`: forward speed v [m/s].
    - `track_inputs`: callable `t -> (w, w_dot, w_ddot)`, each (2, 3) (rows: wheelset 1, 2;
      columns: d_y, d_z, gamma_d); default a perfect track.
    - `options`: anything with boolean attributes `creep_saturation`, `flange_contact`,
      `nonlinear_dampers` (e.g. `bogie_jax.params.ModelOptions`); default all off.
    - `constants`: a `TwinConstants` (default derived from `params`).
    """

    def __init__(
        self,
        params=None,
        speed: float = 50.0,
        track_inputs: TrackInputs | None = None,
        options=None,
        constants: TwinConstants | None = None,
    ):
        if constants is None:
            constants = TwinConstants.from_params(params)
        self.k = constants
        if not np.isclose(constants.j_w[0], constants.j_w[2], rtol=1e-12, atol=0.0):
            raise ValueError("the twin needs an axisymmetric wheelset inertia (ixx == izz)")
        self.speed = float(speed)
        self.spin = self.speed / constants.r0
        self.track_inputs = perfect_track_inputs if track_inputs is None else track_inputs
        opts = TwinOptions() if options is None else options
        self.options = TwinOptions(
            creep_saturation=bool(getattr(opts, "creep_saturation", False)),
            flange_contact=bool(getattr(opts, "flange_contact", False)),
            nonlinear_dampers=bool(getattr(opts, "nonlinear_dampers", False)),
        )
        self._eye = np.eye(N_DOF)
        self._zero_and_units = np.vstack([np.zeros(N_DOF), self._eye])  # (11, 10)
        self.n_rhs_calls = 0

    # ------------------------------------------------------------------------------------
    # Track
    # ------------------------------------------------------------------------------------
    def _track(self, t):
        w, wd, wdd = self.track_inputs(t)
        return (
            np.asarray(w, dtype=float).reshape(2, 3),
            np.asarray(wd, dtype=float).reshape(2, 3),
            np.asarray(wdd, dtype=float).reshape(2, 3),
        )

    # ------------------------------------------------------------------------------------
    # Kinematics, written by hand
    # ------------------------------------------------------------------------------------
    def pose(self, q: np.ndarray, w: np.ndarray) -> _Pose:
        k = self.k
        roll, pitch, yaw = q[3], q[4], q[5]
        rz = rot_z(yaw)
        rzy = rz @ rot_y(pitch)
        rot_f = rzy @ rot_x(roll)
        cg_f = np.array([q[0], q[1], k.h_f + q[2]])
        wheelsets = []
        for i, x_i in enumerate((k.a, -k.a)):
            d_y, d_z, gamma = w[i]
            y, psi = q[6 + i], q[8 + i]
            y_rel = y - d_y + k.r0 * gamma
            table = None if k.table is None else k.table(y_rel)
            if table is None:
                u_z = d_z - k.r0 * gamma**2 / 2 + k.zeta * y_rel**2 / 2 - k.xi * psi**2 / 2
                phi = gamma + (k.sigma / k.e0) * y_rel
            else:  # centre height Z(y_rel) (index 7) and roll Phi(y_rel) (index 6) of the table
                u_z = d_z - k.r0 * gamma**2 / 2 + table[0][7] - k.xi * psi**2 / 2
                phi = gamma + table[0][6]
            rzi = rot_z(psi)
            rot = rzi @ rot_x(phi)
            wheelsets.append(
                _WheelsetPose(
                    x=x_i,
                    y=y,
                    psi=psi,
                    y_rel=y_rel,
                    gamma=gamma,
                    u_z=u_z,
                    phi=phi,
                    centre=np.array([x_i, y, k.r0 + u_z]),
                    rot=rot,
                    axis_x=rzi[:, 0],
                    axle=rot[:, 1],
                    table=table,
                )
            )
        return _Pose(
            rot_f=rot_f,
            cg_f=cg_f,
            b_roll=rzy[:, 0],
            b_pitch=rz[:, 1],
            b_yaw=E_Z,
            wheelsets=tuple(wheelsets),
        )

    def _slopes(self, ws: _WheelsetPose):
        """d(u_z)/d(y_rel) and d(phi)/d(y_rel) of a wheelset: cone laws or the profile table."""
        k = self.k
        if ws.table is None:
            return k.zeta * ws.y_rel, k.sigma / k.e0
        return ws.table[1][7], ws.table[1][6]

    def velocities(self, pose: _Pose, qd: np.ndarray, wd: np.ndarray, *, spin: bool = True):
        """Body velocities for (a batch of) q_dot, shape (..., 10).

        Returns [(v_cg, omega)] for frame, wheelset 1, wheelset 2, each (..., 3), in track axes
        (v_cg relative to the moving track axes; the forward speed v e_x is added where a
        material velocity is needed).
        """
        k = self.k
        qd = np.asarray(qd, dtype=float)
        col = lambda j: qd[..., j, None]  # noqa: E731
        v_f = qd[..., 0:3]
        om_f = col(3) * pose.b_roll + col(4) * pose.b_pitch + col(5) * pose.b_yaw
        out = [(v_f, om_f)]
        for i, ws in enumerate(pose.wheelsets):
            d_y_dot, d_z_dot, gamma_dot = wd[i]
            y_dot, psi_dot = qd[..., 6 + i], qd[..., 8 + i]
            y_rel_dot = y_dot - d_y_dot + k.r0 * gamma_dot
            dz_dy, dphi_dy = self._slopes(ws)
            u_z_dot = (
                d_z_dot - k.r0 * ws.gamma * gamma_dot + dz_dy * y_rel_dot - k.xi * ws.psi * psi_dot
            )
            phi_dot = gamma_dot + dphi_dy * y_rel_dot
            c_dot = np.stack([np.zeros_like(y_dot), y_dot, u_z_dot], axis=-1)
            om = psi_dot[..., None] * E_Z + phi_dot[..., None] * ws.axis_x
            if spin:
                om = om + self.spin * ws.axle
            out.append((c_dot, om))
        return out

    def accelerations(self, pose: _Pose, qd: np.ndarray, qdd: np.ndarray, wd, wdd):
        """Body accelerations for q_dot (10,) and (a batch of) q_ddot, shape (..., 10).

        Returns [(a_cg, omega_dot)] for frame, wheelset 1, wheelset 2, each (..., 3).
        """
        k = self.k
        qdd = np.asarray(qdd, dtype=float)
        col = lambda j: qdd[..., j, None]  # noqa: E731
        # frame: omega = roll_dot b_roll + pitch_dot b_pitch + yaw_dot e_z,
        # b_pitch = Rz e_y turns with yaw_dot e_z,
        # b_roll = Rz Ry e_x turns with yaw_dot e_z + pitch_dot b_pitch
        roll_d, pitch_d, yaw_d = qd[3], qd[4], qd[5]
        b_pitch_dot = yaw_d * cross(E_Z, pose.b_pitch)
        b_roll_dot = cross(yaw_d * E_Z + pitch_d * pose.b_pitch, pose.b_roll)
        a_f = qdd[..., 0:3]
        al_f = (
            col(3) * pose.b_roll
            + col(4) * pose.b_pitch
            + col(5) * pose.b_yaw
            + roll_d * b_roll_dot
            + pitch_d * b_pitch_dot
        )
        out = [(a_f, al_f)]
        for i, ws in enumerate(pose.wheelsets):
            d_y_dot, d_z_dot, gamma_dot = wd[i]
            d_y_ddot, d_z_ddot, gamma_ddot = wdd[i]
            y_dot, psi_dot = qd[6 + i], qd[8 + i]
            y_ddot, psi_ddot = qdd[..., 6 + i], qdd[..., 8 + i]
            y_rel_dot = y_dot - d_y_dot + k.r0 * gamma_dot
            y_rel_ddot = y_ddot - d_y_ddot + k.r0 * gamma_ddot
            dz_dy, dphi_dy = self._slopes(ws)
            d2z, d2phi = (k.zeta, 0.0) if ws.table is None else (ws.table[2][7], ws.table[2][6])
            u_z_ddot = (
                d_z_ddot
                - k.r0 * (gamma_dot**2 + ws.gamma * gamma_ddot)
                + d2z * y_rel_dot**2
                + dz_dy * y_rel_ddot
                - k.xi * (psi_dot**2 + ws.psi * psi_ddot)
            )
            phi_dot = gamma_dot + dphi_dy * y_rel_dot
            phi_ddot = gamma_ddot + d2phi * y_rel_dot**2 + dphi_dy * y_rel_ddot
            a_c = np.stack([np.zeros_like(y_ddot), y_ddot, u_z_ddot], axis=-1)
            # omega = psi_dot e_z + phi_dot axis_x + Omega axle,
            # axis_x = Rz(psi) e_x turns with psi_dot e_z, axle = R_i e_y with omega_R
            omega_r = psi_dot * E_Z + phi_dot * ws.axis_x
            axis_x_dot = psi_dot * cross(E_Z, ws.axis_x)
            axle_dot = cross(omega_r, ws.axle)
            al = (
                psi_ddot[..., None] * E_Z
                + phi_ddot[..., None] * ws.axis_x
                + phi_dot * axis_x_dot
                + self.spin * axle_dot
            )
            out.append((a_c, al))
        return out

    def partial_velocities(self, pose: _Pose, wd: np.ndarray):
        """[(dv_cg/dq_dot, domega/dq_dot)] per body, each (10, 3) (row j: w.r.t. q_dot_j),
        exact by linearity of the velocities in q_dot."""
        vel = self.velocities(pose, self._zero_and_units, wd)
        return [(v[1:] - v[0], om[1:] - om[0]) for v, om in vel]

    # ------------------------------------------------------------------------------------
    # Inertia
    # ------------------------------------------------------------------------------------
    def _inertia_world(self, pose: _Pose):
        k = self.k
        j_f = (pose.rot_f * k.j_f) @ pose.rot_f.T
        return [j_f] + [(ws.rot * k.j_w) @ ws.rot.T for ws in pose.wheelsets]

    def _masses(self):
        return [self.k.m_f, self.k.m_w, self.k.m_w]

    def _mass_matrix(self, pose, partials, inertias, qd, wd, wdd):
        acc = self.accelerations(pose, qd, self._zero_and_units, wd, wdd)
        mass = np.zeros((N_DOF, N_DOF))
        for (pv, pw), (a, al), m, j in zip(partials, acc, self._masses(), inertias):
            a_lin = a[1:] - a[0]  # (10, 3): row k = d a / d q_ddot_k
            al_lin = al[1:] - al[0]
            mass += m * pv @ a_lin.T + pw @ (al_lin @ j.T).T
        return mass

    def mass_matrix(self, q, t: float = 0.0) -> np.ndarray:
        """M(q, w(t)): sum over bodies of m (dv/dq_dot)^T (da/dq_ddot)
        + (domega/dq_dot)^T J_world (domega_dot/dq_ddot)."""
        q = np.asarray(q, dtype=float)
        w, wd, wdd = self._track(t)
        pose = self.pose(q, w)
        partials = self.partial_velocities(pose, wd)
        return self._mass_matrix(
            pose, partials, self._inertia_world(pose), np.zeros(N_DOF), wd, wdd
        )

    def _velocity_terms(self, pose, partials, inertias, vel, qd, wd, wdd):
        acc0 = self.accelerations(pose, qd, np.zeros(N_DOF), wd, wdd)
        h = np.zeros(N_DOF)
        for (pv, pw), (a0, al0), (v, om), m, j in zip(
            partials, acc0, vel, self._masses(), inertias
        ):
            dh = j @ al0 + cross(om, j @ om)
            h += pv @ (m * a0) + pw @ dh
        return h

    # ------------------------------------------------------------------------------------
    # Applied forces: resultant force and moment about each CG
    # ------------------------------------------------------------------------------------
    def _yaw_damper_force(self, side: int, rate: float) -> float:
        k = self.k
        c, v_b, c_b = k.c_yd[side], k.v_blowoff[side], k.c_blowoff[side]
        if not self.options.nonlinear_dampers or abs(rate) <= v_b:
            return c * rate
        return np.sign(rate) * (c * v_b + c_b * (abs(rate) - v_b))

    def applied_loads(self, t, q, qd, *, pose=None, vel=None, track=None, details=None):
        """Resultant applied force and moment (about the CG) on frame, wheelset 1, wheelset 2,
        plus a direct generalised force (flange springs act on y_i).

        Returns (loads, q_direct) with loads [(F, M)] per body.
        """
        k = self.k
        q = np.asarray(q, dtype=float)
        qd = np.asarray(qd, dtype=float)
        w, wd, wdd = self._track(t) if track is None else track
        if pose is None:
            pose = self.pose(q, w)
        if vel is None:
            vel = self.velocities(pose, qd, wd)
        (v_f, om_f), ws_vel = vel[0], vel[1:]
        force = [np.zeros(3) for _ in range(3)]
        moment = [np.zeros(3) for _ in range(3)]
        q_direct = np.zeros(N_DOF)

        def add(body, r_rel, f):
            force[body] += f
            moment[body] += cross(r_rel, f)

        # gravity
        add(0, np.zeros(3), np.array([0.0, 0.0, -k.m_f * GRAVITY]))
        for i in (1, 2):
            add(i, np.zeros(3), np.array([0.0, 0.0, -k.m_w * GRAVITY]))

        # primary suspension: frame point A, axlebox point B on the (non-spinning) axle
        vertical_loads = np.zeros((2, 2))  # [wheelset, side (0 left, 1 right)]
        for i, ws in enumerate(pose.wheelsets):
            c_dot, om = ws_vel[i]
            om_r = om - self.spin * ws.axle  # the axlebox does not spin
            for side, sgn in enumerate((1.0, -1.0)):
                ra = pose.rot_f @ np.array([ws.x, sgn * k.b_p, k.r0 - k.h_f])
                rb = ws.rot @ np.array([0.0, sgn * k.b_p, 0.0])
                delta = (pose.cg_f + ra) - (ws.centre + rb)
                delta_dot = (v_f + cross(om_f, ra)) - (c_dot + cross(om_r, rb))
                e = 2 * i + side  # axlebox 1L, 1R, 2L, 2R
                f_b = k.k_p[e] * delta + k.c_p[e] * delta_dot + np.array([0.0, 0.0, -k.f_p[e]])
                add(0, ra, -f_b)
                add(1 + i, rb, f_b)
                vertical_loads[i, side] = -f_b[2]

        # secondary suspension and anti-yaw dampers: frame point A, car-body point B fixed
        for side, sgn in enumerate((1.0, -1.0)):
            ra = pose.rot_f @ np.array([0.0, sgn * k.b_s, k.h_s - k.h_f])
            delta = pose.cg_f + ra - np.array([0.0, sgn * k.b_s, k.h_s])
            delta_dot = v_f + cross(om_f, ra)
            f = k.k_s[side] * delta + k.c_s[side] * delta_dot + np.array([0.0, 0.0, k.f_s[side]])
            add(0, ra, -f)
            ra = pose.rot_f @ np.array([0.0, sgn * k.b_yd, k.h_s - k.h_f])
            delta_dot = v_f + cross(om_f, ra)
            add(0, ra, -np.array([self._yaw_damper_force(side, delta_dot[0]), 0.0, 0.0]))

        # creep forces at the wheel material points
        for i, ws in enumerate(pose.wheelsets):
            c_dot, om = ws_vel[i]
            v_l, v_r = vertical_loads[i]
            common = (k.m_w * (GRAVITY + wdd[i, 1]) + v_l + v_r) / 2
            moment_part = (k.b_p / (2 * k.e0)) * (v_l - v_r)
            rx_track = rot_x(ws.gamma)
            for side, sgn in enumerate((1.0, -1.0)):
                if ws.table is None:
                    radius = k.r0 + sgn * k.lam * ws.y_rel
                    tan_delta = k.tan_delta0 + sgn * (k.eps / k.e0) * ws.y_rel
                    lateral = sgn * k.e0
                else:  # table columns: radii 0-1, tan(contact angle) 2-3, wheel contact y 4-5
                    radius, tan_delta, lateral = ws.table[0][[side, 2 + side, 4 + side]]
                delta = np.arctan(tan_delta)
                normal = rx_track @ np.array([0.0, -sgn * np.sin(delta), np.cos(delta)])
                t_y = cross(normal, E_X)
                rho = ws.rot @ np.array([0.0, lateral, -radius])
                u = self.speed * E_X + c_dot + cross(om, rho)
                xi_x = u @ E_X / self.speed
                xi_y = u @ t_y / self.speed
                xi_sp = om @ normal / self.speed
                n_load = (common + sgn * moment_part) / np.cos(k.delta0)
                if n_load > 0.0:
                    ratio = n_load / k.n0
                    f11 = k.f11 * ratio ** (2.0 / 3.0)
                    f22 = k.f22 * ratio ** (2.0 / 3.0)
                    f23 = k.f23 * ratio
                else:
                    f11 = f22 = f23 = 0.0
                f_x = -f11 * xi_x
                f_y = -f22 * xi_y - f23 * xi_sp
                if self.options.creep_saturation:
                    f_x, f_y = self._saturate(f_x, f_y, n_load)
                f = f_x * E_X + f_y * t_y
                add(1 + i, rho, f)
                if details is not None:
                    details.append(
                        dict(
                            wheelset=i,
                            side=side,
                            xi_x=xi_x,
                            xi_y=xi_y,
                            xi_sp=xi_sp,
                            normal_load=n_load,
                            f_x=f_x,
                            f_y=f_y,
                            rho=rho,
                            normal=normal,
                        )
                    )

        # flange springs (option): generalised force on y_i
        if self.options.flange_contact:
            for i, ws in enumerate(pose.wheelsets):
                excess = abs(ws.y_rel) - k.clearance
                if excess > 0.0:
                    q_direct[6 + i] += -k.k_flange * excess * np.sign(ws.y_rel)

        return list(zip(force, moment)), q_direct

    def _saturate(self, f_x, f_y, n_load):
        """Shen-Hedrick-Elkins: F = mu N (u - u^2/3 + u^3/27), u = F_lin / (mu N), F = mu N for
        u >= 3; both components scaled by F / F_lin."""
        f_lin = np.hypot(f_x, f_y)
        limit = self.k.mu * max(n_load, 0.0)
        if f_lin == 0.0:
            return f_x, f_y
        if limit <= 0.0:
            return 0.0, 0.0
        u = f_lin / limit
        f_sat = limit * (u - u**2 / 3 + u**3 / 27) if u < 3.0 else limit
        scale = f_sat / f_lin
        return f_x * scale, f_y * scale

    def generalised_forces(self, t, q, qd) -> np.ndarray:
        """Q_j = sum_bodies dv/dq_dot_j . F + domega/dq_dot_j . M (applied loads only)."""
        q = np.asarray(q, dtype=float)
        qd = np.asarray(qd, dtype=float)
        track = self._track(t)
        pose = self.pose(q, track[0])
        partials = self.partial_velocities(pose, track[1])
        loads, q_direct = self.applied_loads(t, q, qd, pose=pose, track=track)
        return self._project(partials, loads) + q_direct

    @staticmethod
    def _project(partials, loads):
        out = np.zeros(N_DOF)
        for (pv, pw), (f, m) in zip(partials, loads):
            out += pv @ f + pw @ m
        return out

    def velocity_terms(self, t, q, qd) -> np.ndarray:
        """h(q, q_dot, w, w_dot, w_ddot): the inertia terms at q_ddot = 0."""
        q = np.asarray(q, dtype=float)
        qd = np.asarray(qd, dtype=float)
        w, wd, wdd = self._track(t)
        pose = self.pose(q, w)
        partials = self.partial_velocities(pose, wd)
        vel = self.velocities(pose, qd, wd)
        return self._velocity_terms(pose, partials, self._inertia_world(pose), vel, qd, wd, wdd)

    # ------------------------------------------------------------------------------------
    # Equations of motion
    # ------------------------------------------------------------------------------------
    def qddot(self, t, q, qd) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        qd = np.asarray(qd, dtype=float)
        track = self._track(t)
        w, wd, wdd = track
        pose = self.pose(q, w)
        partials = self.partial_velocities(pose, wd)
        inertias = self._inertia_world(pose)
        vel = self.velocities(pose, qd, wd)
        mass = self._mass_matrix(pose, partials, inertias, qd, wd, wdd)
        h = self._velocity_terms(pose, partials, inertias, vel, qd, wd, wdd)
        loads, q_direct = self.applied_loads(t, q, qd, pose=pose, vel=vel, track=track)
        q_applied = self._project(partials, loads) + q_direct
        return np.linalg.solve(mass, q_applied - h)

    def rhs(self, t, y) -> np.ndarray:
        """dy/dt for the 20-entry state y = (q, q_dot)."""
        self.n_rhs_calls += 1
        y = np.asarray(y, dtype=float)
        q, qd = y[:N_DOF], y[N_DOF:]
        return np.concatenate([qd, self.qddot(t, q, qd)])

    def creep_details(self, t, y) -> list[dict]:
        """Creepages, normal loads and creep forces at the four contacts (for diagnostics)."""
        y = np.asarray(y, dtype=float)
        out: list[dict] = []
        self.applied_loads(t, y[:N_DOF], y[N_DOF:], details=out)
        return out
