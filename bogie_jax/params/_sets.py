"""Named parameter sets.

- `manchester_benchmark()`: the default, built on the Manchester benchmark vehicle 1
  (Iwnicki 1998; reference doc section 5.1). The benchmark does not define a conical wheel, a rail
  head radius or anti-yaw dampers: we add a 1:20 cone (tan(delta0) = 0.05) on a 0.3 m rail head
  with e0 = 0.75 m, and yaw dampers of 400 kN s/m at 1.3 m (mid of the generic range, reference
  doc 5.2).
- `crh380a()`: the CRH380A set of the reference doc section 5.2, with its nonlinear yaw damper
  (4.9 MN s/m up to 0.015 m/s, then 0.01 MN s/m).
"""

from ._bogie import BogieParams
from ._groups import (
    BodyInertia,
    Geometry,
    Masses,
    PrimarySuspension,
    SecondarySuspension,
    WheelRailContact,
    WheelWear,
    YawDampers,
)


CONTACTS = ("cone", "s1002-uic60", "worn-uic60", "half-worn-uic60")
"""The contact geometries of `manchester_benchmark`: the cone, and the profile pairs of
`bogie_jax.contact.PROFILE_PAIRS`."""
MEASURED_WHEEL = "wheel:"
"""Prefix of a measured wheel's contact name (`bogie_jax.contact.measured_wheel`)."""


def manchester_benchmark(contact: str = "cone", wear: float | None = None) -> BogieParams:
    """Manchester benchmark vehicle 1 bogie (reference doc 5.1).

    `contact`: `"cone"` (default) a 1:20 conical wheel on a 0.3 m rail head; `"s1002-uic60"`
    the Manchester Contact Benchmark's new S1002 wheel on UIC60 inclined 1:40, gauge 1435 mm,
    flange-back spacing 1360 mm (its contact table replaces the cone's geometry; the `contact`
    fields keep the material data and r0); `"worn-uic60"` a measured worn wheel on that rail;
    `"half-worn-uic60"` a wheel whose profile lies halfway between the two; a measured wheel
    on that rail, `bogie_jax.contact.measured_wheel(path, flange_back)`.
    `wear`: with `"s1002-uic60"`, a `WheelWear` level in [0, 1] blending the new and the worn
    wheel's tables (a differentiable nuisance parameter, `wear.level`), with its conicity
    factor `wear.conicity_factor` at 1; None: no wear parameter.
    """
    if contact not in CONTACTS and not contact.startswith(MEASURED_WHEEL):
        raise ValueError(
            f"unknown contact {contact!r}; choose one of {', '.join(CONTACTS)}, or a measured "
            "wheel (`bogie_jax.contact.measured_wheel`)"
        )
    if wear is not None and contact != "s1002-uic60":
        raise ValueError(f"`wear` needs contact='s1002-uic60', got contact={contact!r}")
    return BogieParams(
        masses=Masses(
            frame=BodyInertia(mass=2615.0, ixx=1722.0, iyy=1476.0, izz=3067.0),
            wheelset=BodyInertia(mass=1813.0, ixx=1120.0, iyy=112.0, izz=1120.0),
            carbody_mass=16000.0,
        ),
        geometry=Geometry(
            semi_wheelbase=1.28,
            primary_semi_spacing=1.0,
            secondary_semi_spacing=1.0,
            yaw_damper_semi_spacing=1.3,
            frame_cg_height=0.6,
            secondary_height=0.8275,
        ),
        contact=_contact(wheel_radius=0.46, cone_slope=0.05),
        primary=PrimarySuspension(kx=31.391e6, ky=3.884e6, kz=1.22e6, cx=15e3, cy=2e3, cz=4e3),
        secondary=SecondarySuspension(kx=160e3, ky=160e3, kz=430e3, cy=32e3, cz=20e3),
        yaw_dampers=YawDampers(c=400e3, blowoff_velocity=0.015, c_blowoff=10e3),
        wear=None if wear is None else WheelWear(level=wear, conicity_factor=1.0),
        contact_geometry=contact,
    )


def crh380a() -> BogieParams:
    """CRH380A bogie (reference doc 5.2); car body 43 862 kg shared by two bogies."""
    return BogieParams(
        masses=Masses(
            frame=BodyInertia(mass=2400.0, ixx=1944.0, iyy=1314.0, izz=2400.0),
            wheelset=BodyInertia(mass=1850.0, ixx=967.0, iyy=123.0, izz=967.0),
            carbody_mass=43862.0 / 2,
        ),
        geometry=Geometry(
            semi_wheelbase=1.25,
            primary_semi_spacing=1.0,
            secondary_semi_spacing=1.23,
            yaw_damper_semi_spacing=1.4,
            frame_cg_height=0.6,
            secondary_height=0.85,
        ),
        contact=_contact(wheel_radius=0.43, cone_slope=0.05),
        primary=PrimarySuspension(kx=14.68e6, ky=6.47e6, kz=1.176e6, cx=15e3, cy=2e3, cz=13e3),
        secondary=SecondarySuspension(kx=160e3, ky=160e3, kz=190e3, cy=58.8e3, cz=40e3),
        yaw_dampers=YawDampers(c=4.9e6, blowoff_velocity=0.015, c_blowoff=0.01e6),
    )


def _contact(*, wheel_radius: float, cone_slope: float) -> WheelRailContact:
    return WheelRailContact(
        wheel_radius=wheel_radius,
        contact_semi_distance=0.75,
        cone_slope=cone_slope,
        rail_head_radius=0.3,
        young_modulus=2.1e11,
        poisson_ratio=0.3,
        creep_factor=1.0,
        friction=0.3,
        flange_clearance=0.008,
        flange_stiffness=3e7,
    )


PARAMETER_SETS = {"manchester": manchester_benchmark, "crh380a": crh380a}
PROFILE_SET = "manchester"
"""The parameter set whose wheels the profile contacts fit (`manchester_benchmark(contact=...)`)."""
