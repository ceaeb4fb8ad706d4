"""Named points of the bogie where sensors sit: frame-fixed points and axleboxes.

Positions are in track axes (x forward, y left, z up; origin at rail level under the bogie
centre, docs/model.md) as functions of the coordinates q (10,) and the track inputs under the
wheelsets w (2, 3). Both kinds of point are rigid-body points, so their velocity and
acceleration follow from q, q_dot, q_ddot and w, w_dot, w_ddot by the chain rule
(`point_motion`); nothing is finite-differenced.
"""

import abc
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..model import BogieModel, _kinematics as kin, track_inputs


SIDES = {"left": 1.0, "right": -1.0}
WHEELSETS = (1, 2)


class AbstractLocation(eqx.Module):
    """A material point of the bogie."""

    @abc.abstractmethod
    def position(self, q, w, model: BogieModel) -> Float[Array, "3"]:
        """Position [m] in track axes for coordinates `q` (10,) and track inputs `w` (2, 3)."""

    @abc.abstractmethod
    def describe(self) -> dict:
        """JSON-ready description (inverse of `location_from_description`)."""

    def attachment(self, model: BogieModel):
        """`(body, offset)` of a point fixed to body `body` (0 frame, 1 and 2 the wheelsets) at
        `offset` (3,) [m] in body axes from the body's origin (`body_poses`), or None (then
        `point_motion` differentiates `position`)."""
        del model
        return None


class FramePoint(AbstractLocation):
    """A point fixed to the bogie frame, `offset` = (x, y, z) [m] from the frame centre of
    gravity in frame axes (the CG is `geometry.frame_cg_height` above rail at equilibrium)."""

    offset: Float[Array, "3"]

    def __init__(self, x: float, y: float, z: float):
        self.offset = np.asarray([x, y, z], dtype=float)

    def position(self, q, w, model: BogieModel):
        del w
        return kin.frame_points(q, self.offset[None, :], model.params)[0]

    def attachment(self, model: BogieModel):
        del model
        return 0, self.offset

    def describe(self) -> dict:
        return {"frame": [float(v) for v in np.asarray(self.offset)]}


class Axlebox(AbstractLocation):
    """The axlebox of wheelset 1 (leading) or 2 (trailing) on the left (+y) or right side.

    It moves with the non-spinning wheelset frame (paper eq. 2-3): centre c_i plus
    R_i (0, +-b_p, 0), b_p = `geometry.primary_semi_spacing` (docs/model.md, primary elements).
    """

    wheelset: int = eqx.field(static=True)
    side: str = eqx.field(static=True)

    def __check_init__(self):
        if self.wheelset not in WHEELSETS:
            raise ValueError(f"`wheelset` must be 1 or 2, got {self.wheelset!r}")
        if self.side not in SIDES:
            raise ValueError(f"`side` must be 'left' or 'right', got {self.side!r}")

    def position(self, q, w, model: BogieModel):
        i = self.wheelset - 1
        p, const = model.params, model.constants
        y, psi, w_i = q[6 + i], q[8 + i], w[i]
        centre = kin.centre(y, psi, w_i, kin.axle_positions(p)[i], p, const)
        rotation = kin.rotation(y, psi, w_i, p, const)
        return centre + rotation[:, 1] * (SIDES[self.side] * p.geometry.primary_semi_spacing)

    def attachment(self, model: BogieModel):
        lateral = SIDES[self.side] * model.params.geometry.primary_semi_spacing
        zero = jnp.zeros_like(lateral)
        return self.wheelset, jnp.stack([zero, lateral, zero])

    def describe(self) -> dict:
        return {"axlebox": [self.wheelset, self.side]}


def location_from_description(d: dict) -> AbstractLocation:
    """Inverse of `AbstractLocation.describe`."""
    if isinstance(d, dict) and len(d) == 1:
        ((kind, value),) = d.items()
        if kind == "frame" and isinstance(value, list) and len(value) == 3:
            return FramePoint(*[float(v) for v in value])
        if kind == "axlebox" and isinstance(value, list) and len(value) == 2:
            return Axlebox(int(value[0]), str(value[1]))
    raise ValueError(
        f"bad sensor location {d!r}: expected {{'frame': [x, y, z]}} or "
        "{'axlebox': [wheelset, 'left' | 'right']}"
    )


def body_poses(q, w, model: BogieModel):
    """Origins (3, 3) [m] and rotation matrices (3, 3, 3) of the frame (CG, R_f) and of the
    wheelsets 1 and 2 (centre c_i, non-spinning R_i; paper eq. 2-3, docs/model.md)."""
    p, const = model.params, model.constants
    y, psi, x = q[6:8], q[8:10], kin.axle_positions(p)
    cg = jnp.stack([q[0], q[1], p.geometry.frame_cg_height + q[2]])
    centres = jax.vmap(kin.centre, in_axes=(0, 0, 0, 0, None, None))(y, psi, w, x, p, const)
    rotations = jax.vmap(kin.rotation, in_axes=(0, 0, 0, None, None))(y, psi, w, p, const)
    origins = jnp.concatenate([cg[None], centres])
    return origins, jnp.concatenate([kin.frame_rotation(q[3:6])[None], rotations])


class BodyMotion(NamedTuple):
    """Origins (3, 3) and rotations (3, 3, 3) of the three bodies (`body_poses`) with their first
    and second time derivatives (`origin_rate` [m/s], `origin_acc` [m/s^2], ...)."""

    origin: Array
    rotation: Array
    origin_rate: Array
    rotation_rate: Array
    origin_acc: Array
    rotation_acc: Array


class SampleState(NamedTuple):
    """Everything a sensor reads at one sample time: coordinates q (10,), q_dot, q_ddot (from the
    equations of motion), the track inputs under the wheelsets w, w_dot, w_ddot (2, 3) and,
    optionally, the `BodyMotion` they imply (shared by all sensors; `sample_state` fills it)."""

    q: Array
    qd: Array
    qdd: Array
    w: Array
    wd: Array
    wdd: Array
    bodies: BodyMotion | None = None


def _second_order(f, x, xd, xdd):
    """f, df/dt and d^2f/dt^2 along x(t + s) = x + s x_dot + s^2/2 x_ddot, which agrees with the
    motion to second order: two nested `jax.jvp`s in s (exact chain rule, no differencing)."""
    zero, one = jnp.zeros((), xd[0].dtype), jnp.ones((), xd[0].dtype)

    def path(s):
        return f(*(a + s * b + 0.5 * s**2 * c for a, b, c in zip(x, xd, xdd)))

    def with_rate(s):
        return jax.jvp(path, (s,), (one,))

    (value, rate), (_, acc) = jax.jvp(with_rate, (zero,), (one,))
    return value, rate, acc


def body_motion(model: BogieModel, q, qd, qdd, w, wd, wdd) -> BodyMotion:
    """`BodyMotion` of the bodies for q, q_dot, q_ddot (10,) and w, w_dot, w_ddot (2, 3)."""
    value, rate, acc = _second_order(
        lambda q_, w_: body_poses(q_, w_, model), (q, w), (qd, wd), (qdd, wdd)
    )
    return BodyMotion(*value, *rate, *acc)


def sample_state(model: BogieModel, t, q, qd, qdd) -> SampleState:
    """The `SampleState` at time `t` [s] (track inputs from `bogie_jax.model.track_inputs`)."""
    w, wd, wdd = track_inputs(model, t)
    return SampleState(q, qd, qdd, w, wd, wdd, body_motion(model, q, qd, qdd, w, wd, wdd))


def point_motion(location: AbstractLocation, model: BogieModel, state: SampleState):
    """Position [m], velocity [m/s] and acceleration [m/s^2] of `location` in track axes.

    The point follows r(q(t), w(t)); `_second_order` gives r, dr/dt and
    d^2r/dt^2 = J q_ddot + (dJ/dt) q_dot + track terms exactly, q_ddot from the equations of
    motion. A point fixed to a body (`attachment`) is r = o + R p with the body's origin o and
    rotation R (`state.bodies`, computed once for all sensors), so its derivatives are
    o' + R' p and o'' + R'' p.
    """
    attached = location.attachment(model)
    if attached is None:
        q, qd, qdd, w, wd, wdd = state[:6]
        return _second_order(
            lambda q_, w_: location.position(q_, w_, model), (q, w), (qd, wd), (qdd, wdd)
        )
    bodies = state.bodies
    if bodies is None:
        bodies = body_motion(model, *state[:6])
    i, offset = attached
    pairs = (
        (bodies.origin, bodies.rotation),
        (bodies.origin_rate, bodies.rotation_rate),
        (bodies.origin_acc, bodies.rotation_acc),
    )
    return tuple(o[i] + jnp.sum(r[i] * offset, axis=-1) for o, r in pairs)
