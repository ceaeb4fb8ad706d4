"""The bogie's equations of motion as a pure vector field for diffrax (paper eq. 11).

    M(q, w) q_ddot = Q(q, q_dot, w, w_dot) - h(q, q_dot, w, w_dot, w_ddot)

with M and h from the kinetic energy, body by body (`_lagrangian.py`), and Q the generalised
forces of gravity, suspension elements, creep forces and optional flange contact (paper eq. 8).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl

from ..params import BogieParams, ModelOptions
from ..track import TrackIrregularity
from . import _kinematics as kin
from ._constants import ModelConstants, model_constants
from ._lagrangian import frame_rotation_terms, wheelset_terms
from ._layout import GRAVITY, N_DOF
from ._smallmath import solve3, solve_spd2
from ._suspension import N_PRIMARY, generalised_forces as suspension_generalised_forces
from ._wheel_rail import contact_generalised_forces, normal_loads


class BogieModel(eqx.Module):
    """Everything the vector field needs: parameters, derived constants, track and speed.

    Build it with `build_model`; pass it as `args` to diffrax so every adjoint (including
    `BacksolveAdjoint`) can differentiate with respect to it.
    """

    params: BogieParams
    constants: ModelConstants
    track: TrackIrregularity
    speed: jax.Array  # [m/s]
    options: ModelOptions = ModelOptions()


def build_model(
    params: BogieParams, *, speed, track: TrackIrregularity, options: ModelOptions = ModelOptions()
) -> BogieModel:
    """Assemble a `BogieModel` (derives the constants once; pure and differentiable)."""
    return BogieModel(
        params=params,
        constants=model_constants(params),
        track=track,
        speed=jnp.asarray(speed, dtype=float),
        options=options,
    )


def track_inputs(model: BogieModel, t):
    """Irregularities under the wheelsets and their time derivatives, each (2, 3).

    Wheelset i is at distance s = v t + x_i along the track (x_1 = a, x_2 = -a), so the trailing
    wheelset sees the leading one's input delayed by 2a/v.
    """
    s = model.speed * t + kin.axle_positions(model.params)
    w, dw, d2w = jax.vmap(model.track.evaluate)(s)
    return w, model.speed * dw, model.speed**2 * d2w


def _wheelset_coordinates(q):
    """(2 wheelsets, 2) coordinates (y, yaw) from q."""
    return jnp.stack([q[6:8], q[8:10]], axis=-1)


def _to_q_order(per_wheelset):
    """Inverse of `_wheelset_coordinates` for a (2, 2) array: (y1, y2, yaw1, yaw2)."""
    return per_wheelset.T.reshape(4)


def _suspension_forces(model: BogieModel, q, qd, w, wd):
    """Generalised suspension forces (10,) and the element forces (8, 3)."""
    return suspension_generalised_forces(q, qd, w, wd, model.params, model.constants, model.options)


def _wheelset_forces(model: BogieModel, q, qd, w, wd, wdd, axlebox_forces):
    """Generalised gravity, creep and flange forces on (y, yaw) of each wheelset, (2, 2)."""
    p, const, options = model.params, model.constants, model.options
    x = kin.axle_positions(p)

    def one(pos, vel, w_, wd_, wdd_, x_, boxes):
        slope = kin.height_gradient(pos[0], pos[1], w_, p, const)
        gravity = -p.masses.wheelset.mass * GRAVITY * slope
        loads = normal_loads(boxes, wdd_, p, const)
        creep = contact_generalised_forces(
            pos, vel, w_, wd_, x_, loads, p, const, options, model.speed
        )
        total = gravity + creep
        if options.flange_contact:
            c = p.contact
            y_rel = kin.relative_lateral(pos[0], w_, c.wheel_radius)
            excess = jnp.sign(y_rel) * jnp.maximum(jnp.abs(y_rel) - c.flange_clearance, 0.0)
            total = total.at[0].add(-c.flange_stiffness * excess)
        return total

    boxes = axlebox_forces.reshape(2, 2, 3)
    return jax.vmap(one)(_wheelset_coordinates(q), _wheelset_coordinates(qd), w, wd, wdd, x, boxes)


def _inertia_blocks(model: BogieModel, q, qd, w, wd, wdd):
    """Frame rotational (M, h) and per-wheelset (M, h) blocks."""
    p, const = model.params, model.constants
    spin = model.speed / p.contact.wheel_radius
    frame_m, frame_h = frame_rotation_terms(q[3:6], qd[3:6], p)
    ws_m, ws_h = jax.vmap(lambda a, b, c, d, e: wheelset_terms(a, b, c, d, e, p, const, spin))(
        _wheelset_coordinates(q), _wheelset_coordinates(qd), w, wd, wdd
    )
    return (frame_m, frame_h), (ws_m, ws_h)


@eqx.filter_jit
def accelerations(model: BogieModel, t, q, qd):
    """Generalised accelerations q_ddot (10,) from the equations of motion.

    A `jit` of its own, also inside other programs: JAX then traces it once per argument
    signature and reuses the jaxpr (and its derivative and batching rules) at every call site
    (ODE stages, static equilibrium, sampled accelerations) instead of tracing it again at
    each. XLA inlines it, so the compiled program and its results are unchanged; only tracing,
    which the persistent compilation cache cannot save, gets shorter."""
    w, wd, wdd = track_inputs(model, t)
    return accelerations_from_inputs(model, q, qd, w, wd, wdd)


def accelerations_from_inputs(model: BogieModel, q, qd, w, wd, wdd):
    """q_ddot (10,) from the equations of motion with the track inputs under the wheelsets
    given: `w`, `wd`, `wdd` (2, 3) as `track_inputs` returns them (per wheelset alignment [m],
    level [m], cross level [rad] and their time derivatives)."""
    p = model.params
    suspension, f = _suspension_forces(model, q, qd, w, wd)
    wheelset_q = _wheelset_forces(model, q, qd, w, wd, wdd, f[:N_PRIMARY])
    (frame_m, frame_h), (ws_m, ws_h) = _inertia_blocks(model, q, qd, w, wd, wdd)
    frame_translation = suspension[0:3] / p.masses.frame.mass - jnp.array([0.0, 0.0, GRAVITY])
    frame_rotation = solve3(frame_m, suspension[3:6] - frame_h)
    rhs_ws = jnp.stack([suspension[6:8], suspension[8:10]], axis=-1) + wheelset_q - ws_h
    wheelset = jax.vmap(solve_spd2)(ws_m, rhs_ws)
    return jnp.concatenate([frame_translation, frame_rotation, _to_q_order(wheelset)])


def vector_field(t, y, model: BogieModel):
    """dy/dt for the state y = (q, q_dot) (20,); signature `(t, y, args)` for `diffrax.ODETerm`."""
    q, qd = y[:N_DOF], y[N_DOF:]
    return jnp.concatenate([qd, accelerations(model, t, q, qd)])


def mass_matrix(model: BogieModel, q, t=0.0):
    """Mass matrix M(q, w(t)) (10, 10) [kg, kg m, kg m^2] of Lagrange's equations."""
    w, wd, wdd = track_inputs(model, t)
    zero = jnp.zeros_like(q)
    (frame_m, _), (ws_m, _) = _inertia_blocks(model, q, zero, w, wd, wdd)
    m_f = model.params.masses.frame.mass
    frame = jsl.block_diag(m_f * jnp.eye(3), frame_m)
    wheelsets = jnp.zeros((4, 4), dtype=frame.dtype)
    for i in range(2):  # wheelset i: (y_i, yaw_i) sit at rows (i, 2 + i) of the wheelset block
        idx = jnp.array([i, 2 + i])
        wheelsets = wheelsets.at[idx[:, None], idx[None, :]].set(ws_m[i])
    return jsl.block_diag(frame, wheelsets)
