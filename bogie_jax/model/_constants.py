"""Quantities derived once per parameter set (outside the time loop), differentiably."""

import equinox as eqx
import jax.numpy as jnp

from ..contact import (
    ConeGeometry,
    CreepCoefficients,
    ProfileGeometry,
    blend_geometries,
    cone_geometry,
    cone_on_rail_curvatures,
    creep_coefficients,
    hertz_contact,
    named_contact_table,
    profile_geometry,
    scale_conicity,
)
from ..params import BogieParams
from ._layout import GRAVITY


class ModelConstants(eqx.Module):
    """Derived constants of the bogie model.

    - `geometry`: the contact geometry strategy, chosen by `params.contact_geometry`: the
      cone-on-circular-rail coefficients lambda, sigma, epsilon, zeta, xi (`ConeGeometry`,
      reference doc 1.2) or a profile pair's interpolated contact table (`ProfileGeometry`).
    - `primary_preload` [N]: static vertical force of each primary spring,
      (m_frame + m_carbody) g / 4.
    - `secondary_preload` [N]: static vertical force of each secondary spring, m_carbody g / 2.
    - `static_normal_load` [N]: static normal force per wheel,
      (m_wheelset g / 2 + 2 F_primary / 2) / cos(delta0) (reference doc 4.5).
    - `creep`: Kalker creep coefficients f11, f22 [N], f23 [N m] at the static load, Hertz patch
      from the nominal curvatures (reference doc 2, 3), times `contact.creep_factor`.
    """

    geometry: ConeGeometry | ProfileGeometry
    primary_preload: jnp.ndarray
    secondary_preload: jnp.ndarray
    static_normal_load: jnp.ndarray
    creep: CreepCoefficients


@eqx.filter_jit
def model_constants(params: BogieParams) -> ModelConstants:
    """Derive the `ModelConstants` of `params` (pure, differentiable; a `jit` of its own, traced
    once per program as `accelerations`)."""
    c = params.contact
    m = params.masses
    if params.contact_geometry == "cone":
        geometry = cone_geometry(
            c.wheel_radius, c.contact_semi_distance, c.cone_slope, c.rail_head_radius
        )
    else:  # a named profile pair: its table, built once per process outside the trace
        geometry = profile_geometry(named_contact_table(params.contact_geometry))
        if params.wear is not None:  # blend towards the worn wheel, scale (differentiable)
            worn = profile_geometry(named_contact_table("worn-uic60"))
            geometry = blend_geometries(geometry, worn, params.wear.level)
            geometry = scale_conicity(geometry, params.wear.conicity_factor)
    primary_preload = (m.frame.mass + m.carbody_mass) * GRAVITY / 4
    secondary_preload = m.carbody_mass * GRAVITY / 2
    vertical_wheel_load = (m.wheelset.mass * GRAVITY + 2 * primary_preload) / 2
    normal_load = vertical_wheel_load / jnp.cos(geometry.cone_angle)
    if isinstance(geometry, ProfileGeometry):
        curv_a, curv_b = geometry.hertz_curvatures[0], geometry.hertz_curvatures[1]
    else:
        curv_a, curv_b = cone_on_rail_curvatures(
            c.wheel_radius, geometry.cone_angle, c.rail_head_radius
        )
    patch = hertz_contact(normal_load, curv_a, curv_b, c.young_modulus, c.poisson_ratio)
    shear_modulus = c.young_modulus / (2 * (1 + c.poisson_ratio))
    creep = creep_coefficients(patch.a, patch.b, shear_modulus, c.poisson_ratio)
    creep = CreepCoefficients(
        f11=c.creep_factor * creep.f11,
        f22=c.creep_factor * creep.f22,
        f23=c.creep_factor * creep.f23,
    )
    return ModelConstants(
        geometry=geometry,
        primary_preload=jnp.asarray(primary_preload),
        secondary_preload=jnp.asarray(secondary_preload),
        static_normal_load=jnp.asarray(normal_load),
        creep=creep,
    )
