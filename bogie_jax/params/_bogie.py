"""`BogieParams`: the complete, typed parameter tree of the bogie model, and model options."""

import equinox as eqx

from ._groups import (
    Geometry,
    Masses,
    PrimarySuspension,
    SecondarySuspension,
    WheelRailContact,
    WheelWear,
    YawDampers,
)


class ModelOptions(eqx.Module):
    """Switches for the nonlinear model options (all off by default: the paper's model is linear
    in its suspension and creep laws). These are compile-time facts (static).

    - `creep_saturation`: Shen-Hedrick-Elkins saturation of the Kalker creep forces with the
      friction coefficient `contact.friction` (reference doc 2.1).
    - `flange_contact`: a lateral flange spring `contact.flange_stiffness` beyond
      `contact.flange_clearance` of wheelset displacement relative to the track.
    - `nonlinear_dampers`: blow-off characteristic of the anti-yaw dampers (`YawDampers`).
    """

    creep_saturation: bool = eqx.field(default=False, static=True)
    flange_contact: bool = eqx.field(default=False, static=True)
    nonlinear_dampers: bool = eqx.field(default=False, static=True)


class BogieParams(eqx.Module):
    """All physical parameters of the bogie: a pytree whose leaves are arrays in SI units,
    scalars except the suspension fields (one value per element: (4,) per axlebox, (2,) per
    side).

    Parameter names are the tree paths, e.g. `primary.kz` (all four axleboxes tied) or
    `masses.frame.mass`, or element names, e.g. `primary.1L.kz` or `yaw_dampers.left.c`
    (`bogie_jax.params.parameter_names(params, elements=True)` lists both kinds).
    """

    masses: Masses
    geometry: Geometry
    contact: WheelRailContact
    primary: PrimarySuspension
    secondary: SecondarySuspension
    yaw_dampers: YawDampers
    wear: WheelWear | None = None
    """Wheel wear of a profile contact geometry (`WheelWear`, parameter `wear.level`); None for
    the cone and for an unworn profile pair."""
    contact_geometry: str = eqx.field(default="cone", static=True)
    """The wheel/rail contact geometry: `"cone"` (a cone on a circular rail head from the
    `contact` fields, reference doc 1.2) or a named profile pair of `bogie_jax.contact`
    (`PROFILE_PAIRS`, e.g. `"s1002-uic60"`) or a measured wheel on their rail
    (`measured_wheel`), tabulated once and interpolated (a compile-time choice: a name, not
    data)."""
