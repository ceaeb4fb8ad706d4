"""The bogie's small-motion model: its equations of motion linearised about the rest state in
both the state and the track's inputs, a linear time-invariant system at constant speed.

With y = (q, q_dot) (20,) and the track inputs under the two wheelsets u = (w, w_dot, w_ddot)
(18,: per wheelset alignment [m], level [m] and cross level [rad], then their first and second
time derivatives, as `track_inputs` returns them),

    d(dy)/dt = a dy + b u,    q_ddot = a[10:] dy + b[10:] u,

dy = y - y_rest, a = d f / d y and b = d f / d u at (y_rest, 0) (by `jax.jacfwd`), f the first-
order vector field (`vector_field`). The rest state is the static equilibrium on a perfect
track (`rest_state`), where f vanishes, so there is no constant term. This is the model of
linear stability analysis (`system_matrix` is `a`) driven by the track: exact for the linear
terms of the equations of motion, it leaves out their products of small quantities (the
kinematics' and the contact geometry's second-order terms), an error proportional to the
motion's size (docs/model.md, "The small-motion model").
"""

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ..params import BogieParams, ModelOptions
from ..track import perfect_track
from ._dynamics import accelerations_from_inputs, build_model
from ._layout import N_DOF
from ._stability import rest_state


N_INPUTS = 18
"""Track inputs u of the small-motion model: (w, w_dot, w_ddot), each (2 wheelsets, 3)."""


class SmallMotionSystem(eqx.Module):
    """The linearised equations of motion d(dy)/dt = a dy + b u (module docstring).

    - `a` (20, 20): d(dy/dt)/dy at the rest state [1/s, 1/s^2, ...];
    - `b` (20, 18): d(dy/dt)/du, u = (w, w_dot, w_ddot) flattened wheelset by wheelset
      (`inputs_vector`);
    - `rest` (20,): the rest state y_rest = (q0, 0) the motion is measured from.
    """

    a: Float[Array, "20 20"]
    b: Float[Array, "20 18"]
    rest: Float[Array, "20"]


def inputs_vector(w, wd, wdd):
    """u (..., 18) from the track inputs (..., 2, 3) each, in the order of `SmallMotionSystem.b`."""
    flat = lambda x: x.reshape(*x.shape[:-2], 6)
    return jnp.concatenate([flat(w), flat(wd), flat(wdd)], axis=-1)


def _field(model, y, u):
    """dy/dt (20,) at state y with the track inputs u (18,)."""
    w, wd, wdd = (u[6 * i : 6 * i + 6].reshape(2, 3) for i in range(3))
    q, qd = y[:N_DOF], y[N_DOF:]
    return jnp.concatenate([qd, accelerations_from_inputs(model, q, qd, w, wd, wdd)])


def small_motion_system(
    params: BogieParams, speed, options: ModelOptions = ModelOptions()
) -> SmallMotionSystem:
    """The small-motion model of `params` at `speed` [m/s] (module docstring); pure and
    differentiable in `params` and `speed` (forward and reverse mode). Where the rest state's
    Newton solve fails it is taken at q = 0 (`rest_state`)."""
    model = build_model(params, speed=speed, track=perfect_track(), options=options)
    rest = rest_state(params, options)
    zero = jnp.zeros(N_INPUTS, dtype=rest.dtype)
    n = rest.size  # one jacfwd over (y, u) together: one batched evaluation of the field
    jac = jax.jacfwd(lambda yu: _field(model, yu[:n], yu[n:]))(jnp.concatenate([rest, zero]))
    return SmallMotionSystem(a=jac[:, :n], b=jac[:, n:], rest=rest)
