"""Linearised contact geometry of a conical wheel on a circular rail head (reference doc 1.2)."""

import equinox as eqx
import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike


class ConeGeometry(eqx.Module):
    """Geometry constants of a cone on a circular rail head, linearised about centred running.

    Reference doc 1.2 (own derivation, checked there against exact 2-D/3-D tangency solves).
    With `y` the lateral and `psi` the yaw displacement of the wheelset relative to the track:

    - `conicity` [-]: lambda in `r_l,r = r0 +- lambda*y`.
    - `roll_coefficient` [-]: sigma in `roll = gamma_d + (sigma/e0)*y`.
    - `contact_angle_coefficient` [-]: epsilon in `tan(delta_l,r) = tan(delta0) +- (eps/e0)*y`,
      contact angle measured from the **track plane** (not from the axle; see reference doc 1.4).
    - `vertical_lateral_coefficient` [1/m]: zeta in `u_z = ... + (zeta/2)*y^2`.
    - `vertical_yaw_coefficient` [m]: xi in `u_z = ... - (xi/2)*psi^2`.
    - `cone_angle` [rad]: delta0 = arctan(cone slope).
    """

    conicity: Array
    roll_coefficient: Array
    contact_angle_coefficient: Array
    vertical_lateral_coefficient: Array
    vertical_yaw_coefficient: Array
    cone_angle: Array


def cone_geometry(
    wheel_radius: ArrayLike,
    contact_semi_distance: ArrayLike,
    cone_slope: ArrayLike,
    rail_head_radius: ArrayLike,
) -> ConeGeometry:
    """Geometry constants of a conical wheel on a circular rail head (reference doc 1.2).

    Exact offset-surface reduction (reference doc 1.2): the cone on a circle of radius `R_r` is
    a cone on a knife edge at `e0 + R_r sin(delta0)`, `r0 + R_r cos(delta0)`. With
    `t = tan(delta0)` and `k = t / (e0 - r0 t)`:

    - `lambda = t (e0 + R_r sin(delta0)) / (e0 - r0 t)`
    - `sigma = e0 k`, `eps = sigma / cos^2(delta0)`
    - `zeta = 2k + k^2 (e0 t + r0 + R_r / cos(delta0))`, `xi = t (e0 - r0 t)`

    !!! note
        `e0` is the **half** distance between the nominal contact points (about 0.75 m for
        standard gauge). Some papers write these formulas with the full distance; the reference
        doc (and this function) use the half distance.

    **Arguments:**

    - `wheel_radius`: nominal rolling radius `r0` [m].
    - `contact_semi_distance`: half distance `e0` between the nominal contact points [m].
    - `cone_slope`: `t = tan(delta0)` of the wheel tread [-], radius decreasing outwards.
    - `rail_head_radius`: rail head crown radius `R_r` [m].

    **Returns:**

    A [`ConeGeometry`][] with arrays broadcast from the inputs.
    """
    r0 = jnp.asarray(wheel_radius)
    e0 = jnp.asarray(contact_semi_distance)
    t = jnp.asarray(cone_slope)
    rail_radius = jnp.asarray(rail_head_radius)
    delta0 = jnp.arctan(t)
    cos_d = jnp.cos(delta0)
    lever = e0 - r0 * t
    k = t / lever
    sigma = e0 * k
    return ConeGeometry(
        conicity=t * (e0 + rail_radius * jnp.sin(delta0)) / lever,
        roll_coefficient=sigma,
        contact_angle_coefficient=sigma / cos_d**2,
        vertical_lateral_coefficient=2.0 * k + k**2 * (e0 * t + r0 + rail_radius / cos_d),
        vertical_yaw_coefficient=t * lever,
        cone_angle=delta0,
    )
