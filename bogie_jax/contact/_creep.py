"""Kalker linear creep forces and Shen-Hedrick-Elkins saturation (reference doc 2.1)."""

import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from ._kalker import CreepCoefficients


def linear_creep_forces(
    xi_x: ArrayLike, xi_y: ArrayLike, xi_spin: ArrayLike, coeffs: CreepCoefficients
) -> tuple[Array, Array]:
    """Kalker's linear creep forces on the wheel, in the contact plane (reference doc 2.1).

    `F_x = -f11 xi_x` and `F_y = -f22 xi_y - f23 xi_spin`. The spin moment `M_z` is not
    returned: it needs `C33`, which no source opened for the reference doc confirms (reference
    doc 2.3), and it is negligible for bogie lateral dynamics (ORVD and dytsi drop it as well).

    **Arguments:**

    - `xi_x`: longitudinal creepage [-].
    - `xi_y`: lateral creepage [-].
    - `xi_spin`: spin creepage [1/m].
    - `coeffs`: [`CreepCoefficients`][] of the contact (`f11`, `f22` [N], `f23` [N m]).

    **Returns:**

    `(F_x, F_y)` [N].
    """
    fx = -coeffs.f11 * xi_x
    fy = -coeffs.f22 * xi_y - coeffs.f23 * xi_spin
    return fx, fy


def shen_hedrick_elkins(
    fx: ArrayLike, fy: ArrayLike, normal_force: ArrayLike, friction: ArrayLike
) -> tuple[Array, Array]:
    """Saturate linear creep forces with the Shen-Hedrick-Elkins law (reference doc 2.1).

    With `F_lin = |(F_x, F_y)|` and `u = F_lin / (mu N)`, the resultant becomes
    `mu N (u - u^2/3 + u^3/27)` for `u < 3` and `mu N` beyond; both components are scaled by
    the same factor `F / F_lin` (`1 - u/3 + u^2/27`, resp. `1/u`; continuous with its slope at
    `u = 3`). Forces are returned unchanged to first order at zero creep force, and are zero
    where `mu N <= 0` (loss of contact). Gradients stay finite in both cases.

    **Arguments:**

    - `fx`, `fy`: linear (unsaturated) creep forces [N].
    - `normal_force`: normal load `N` [N].
    - `friction`: friction coefficient `mu` [-].

    **Returns:**

    The saturated `(F_x, F_y)` [N].
    """
    fx = jnp.asarray(fx)
    fy = jnp.asarray(fy)
    limit = jnp.asarray(friction) * jnp.asarray(normal_force)
    in_contact = limit > 0.0
    safe_limit = jnp.where(in_contact, limit, 1.0)
    # Double-where: |F| has an undefined gradient at 0, so take the root of a safe value.
    squared = fx**2 + fy**2
    nonzero = squared > 0.0
    magnitude = jnp.where(nonzero, jnp.sqrt(jnp.where(nonzero, squared, 1.0)), 0.0)
    u = magnitude / safe_limit
    saturated = u >= 3.0
    scale = jnp.where(saturated, 1.0 / jnp.where(saturated, u, 3.0), 1.0 - u / 3.0 + u**2 / 27.0)
    scale = jnp.where(in_contact, scale, 0.0)
    return scale * fx, scale * fy
