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


class FramePoint(AbstractLocation):
    """A point fixed to the bogie frame, `offset` = (x, y, z) [m] from the frame centre of
    gravity in frame axes (the CG is `geometry.frame_cg_height` above rail at equilibrium)."""

    offset: Float[Array, "3"]

    def __init__(self, x: float, y: float, z: float):
        self.offset = np.asarray([x, y, z], dtype=float)

    def position(self, q, w, model: BogieModel):
        del w
        return kin.frame_points(q, self.offset[None, :], model.params)[0]

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


class SampleState(NamedTuple):
    """Everything a sensor reads at one sample time: coordinates q (10,), q_dot, q_ddot (from the
    equations of motion) and the track inputs under the wheelsets w, w_dot, w_ddot (2, 3)."""

    q: Array
    qd: Array
    qdd: Array
    w: Array
    wd: Array
    wdd: Array


def sample_state(model: BogieModel, t, q, qd, qdd) -> SampleState:
    """The `SampleState` at time `t` [s] (track inputs from `bogie_jax.model.track_inputs`)."""
    return SampleState(q, qd, qdd, *track_inputs(model, t))


def point_motion(location: AbstractLocation, model: BogieModel, state: SampleState):
    """Position [m], velocity [m/s] and acceleration [m/s^2] of `location` in track axes.

    The point follows r(q(t), w(t)). Along the path q(t + s) = q + s q_dot + s^2/2 q_ddot (and the
    same for the track input w), which agrees with the motion to second order, two nested
    `jax.jvp`s in s give r, dr/dt and d^2r/dt^2 = J q_ddot + (dJ/dt) q_dot + track terms exactly;
    q_ddot comes from the equations of motion.
    """
    q, qd, qdd, w, wd, wdd = state
    zero, one = jnp.zeros((), q.dtype), jnp.ones((), q.dtype)

    def path(s):
        return location.position(
            q + s * qd + 0.5 * s**2 * qdd, w + s * wd + 0.5 * s**2 * wdd, model
        )

    def with_rate(s):
        return jax.jvp(path, (s,), (one,))

    (r, v), (_, a) = jax.jvp(with_rate, (zero,), (one,))
    return r, v, a
