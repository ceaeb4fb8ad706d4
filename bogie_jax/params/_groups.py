"""Typed parameter groups of the bogie model. All values in SI units.

Defaults are not given here: named parameter sets live in `_sets.py`. Each field carries its
unit, its physically valid range (outside raises `ParameterError`) and plausible bounds used by
identification and sensitivity studies (reference doc section 5 "Typical parameter values").
Suspension fields hold one value per element (axlebox or side, see `AXLEBOXES`, `SIDES`).
"""

import math

import equinox as eqx

from ._spec import ParameterError, _is_concrete, physical, validate_fields


INF = math.inf


class _Group(eqx.Module):
    """Base of all parameter groups: validates its physical fields on construction."""

    def __check_init__(self):
        validate_fields(self, type(self).__name__)


class BodyInertia(_Group):
    """Mass and principal moments of inertia of one rigid body about its centre of gravity."""

    mass: float = physical(unit="kg", valid=(1.0, 1e6), bounds=(500.0, 5000.0), doc="mass")
    ixx: float = physical(unit="kg m^2", valid=(1e-3, 1e8), bounds=(50.0, 1e4), doc="roll inertia")
    iyy: float = physical(unit="kg m^2", valid=(1e-3, 1e8), bounds=(50.0, 1e4), doc="pitch inertia")
    izz: float = physical(unit="kg m^2", valid=(1e-3, 1e8), bounds=(50.0, 1e4), doc="yaw inertia")


class Masses(_Group):
    """Masses and inertias: bogie frame, one wheelset (both identical), car-body share.

    `carbody_mass` is the part of the car body mass carried by this bogie [kg]; it loads the
    secondary springs statically (the car body itself moves at constant speed).
    """

    frame: BodyInertia
    wheelset: BodyInertia
    carbody_mass: float = physical(
        unit="kg", valid=(0.0, 1e6), bounds=(5e3, 4e4), doc="car body mass carried by the bogie"
    )

    def __check_init__(self):
        ixx, izz = self.wheelset.ixx, self.wheelset.izz
        if (
            _is_concrete(ixx)
            and _is_concrete(izz)
            and abs(float(ixx) - float(izz)) > 1e-9 * float(ixx)
        ):
            raise ParameterError(
                f"`Masses.wheelset.izz` = {float(izz):g} kg m^2 must equal `Masses.wheelset.ixx` = "
                f"{float(ixx):g} kg m^2: a wheelset is axisymmetric about its axle (docs/model.md)"
            )


class Geometry(_Group):
    """Bogie geometry [m]. Heights are above rail level; lateral spacings are half-distances."""

    semi_wheelbase: float = physical(
        unit="m", valid=(0.1, 10.0), bounds=(0.9, 1.6), doc="half the distance between axles (a)"
    )
    primary_semi_spacing: float = physical(
        unit="m", valid=(0.05, 3.0), bounds=(0.8, 1.2), doc="lateral half-distance of axleboxes"
    )
    secondary_semi_spacing: float = physical(
        unit="m",
        valid=(0.05, 3.0),
        bounds=(0.8, 1.4),
        doc="lateral half-distance of secondary springs",
    )
    yaw_damper_semi_spacing: float = physical(
        unit="m",
        valid=(0.05, 3.0),
        bounds=(1.0, 1.6),
        doc="lateral half-distance of anti-yaw dampers",
    )
    frame_cg_height: float = physical(
        unit="m", valid=(0.05, 3.0), bounds=(0.45, 0.9), doc="frame centre of gravity above rail"
    )
    secondary_height: float = physical(
        unit="m", valid=(0.05, 3.0), bounds=(0.6, 1.2), doc="secondary suspension seat above rail"
    )


class WheelRailContact(_Group):
    """Conical wheel on a circular rail head, Hertz/Kalker material data (reference doc 1-3)."""

    wheel_radius: float = physical(
        unit="m", valid=(0.1, 2.0), bounds=(0.40, 0.50), doc="nominal rolling radius r0"
    )
    contact_semi_distance: float = physical(
        unit="m",
        valid=(0.3, 1.5),
        bounds=(0.70, 0.80),
        doc="half distance between contact points e0",
    )
    cone_slope: float = physical(
        unit="-", valid=(1e-4, 0.6), bounds=(0.02, 0.40), doc="wheel cone slope tan(delta0)"
    )
    rail_head_radius: float = physical(
        unit="m", valid=(0.01, 10.0), bounds=(0.20, 0.50), doc="rail head crown radius R_r"
    )
    young_modulus: float = physical(
        unit="Pa",
        valid=(1e9, 1e13),
        bounds=(1.9e11, 2.2e11),
        doc="Young's modulus (wheel and rail)",
    )
    poisson_ratio: float = physical(
        unit="-", valid=(0.0, 0.5), bounds=(0.25, 0.30), doc="Poisson's ratio (wheel and rail)"
    )
    creep_factor: float = physical(
        unit="-", valid=(0.0, 2.0), bounds=(0.3, 1.0), doc="reduction factor on Kalker coefficients"
    )
    friction: float = physical(
        unit="-", valid=(0.0, 2.0), bounds=(0.1, 0.5), doc="wheel-rail friction coefficient mu"
    )
    flange_clearance: float = physical(
        unit="m",
        valid=(0.0, 0.1),
        bounds=(0.005, 0.012),
        doc="lateral clearance before flange contact",
    )
    flange_stiffness: float = physical(
        unit="N/m", valid=(0.0, 1e10), bounds=(1e7, 1e8), doc="lateral flange contact stiffness"
    )


AXLEBOXES = ("1L", "1R", "2L", "2R")
"""Primary suspension elements: wheelset 1 (leading, x = +a) and 2 (x = -a), left (+y) and
right (-y) axlebox, in this order."""
SIDES = ("left", "right")
"""Secondary suspension and anti-yaw damper elements: left (+y), right (-y), in this order."""


def _axlebox(**kw):
    return physical(elements=AXLEBOXES, **kw)


def _side(**kw):
    return physical(elements=SIDES, **kw)


class PrimarySuspension(_Group):
    """Primary suspension, one value per axlebox (`AXLEBOXES`: 1L, 1R, 2L, 2R), track axes.

    Each field is an array of shape (4,); a scalar is broadcast (all four axleboxes equal, the
    named sets). Parameter names: `primary.kz` for the four tied together, `primary.1L.kz` for
    one axlebox.
    """

    kx: float = _axlebox(
        unit="N/m", valid=(0.0, 1e10), bounds=(5e6, 4e7), doc="longitudinal stiffness"
    )
    ky: float = _axlebox(unit="N/m", valid=(0.0, 1e10), bounds=(2e6, 1e7), doc="lateral stiffness")
    kz: float = _axlebox(unit="N/m", valid=(0.0, 1e10), bounds=(4e5, 2e6), doc="vertical stiffness")
    cx: float = _axlebox(
        unit="N s/m", valid=(0.0, 1e8), bounds=(5e3, 3e4), doc="longitudinal damping"
    )
    cy: float = _axlebox(unit="N s/m", valid=(0.0, 1e8), bounds=(1e3, 1e4), doc="lateral damping")
    cz: float = _axlebox(
        unit="N s/m", valid=(0.0, 1e8), bounds=(2e3, 1.5e4), doc="vertical damping"
    )


class SecondarySuspension(_Group):
    """Secondary suspension between frame and car body, one value per side (`SIDES`: left,
    right), track axes. Fields of shape (2,); a scalar is broadcast. Names: `secondary.cy` (both
    sides tied) or `secondary.left.cy`."""

    kx: float = _side(
        unit="N/m", valid=(0.0, 1e10), bounds=(1e5, 3e5), doc="longitudinal stiffness"
    )
    ky: float = _side(unit="N/m", valid=(0.0, 1e10), bounds=(1e5, 3e5), doc="lateral stiffness")
    kz: float = _side(unit="N/m", valid=(0.0, 1e10), bounds=(1.5e5, 6e5), doc="vertical stiffness")
    cy: float = _side(unit="N s/m", valid=(0.0, 1e8), bounds=(1e4, 8e4), doc="lateral damping")
    cz: float = _side(unit="N s/m", valid=(0.0, 1e8), bounds=(1e4, 8e4), doc="vertical damping")


class YawDampers(_Group):
    """Anti-yaw (longitudinal) dampers between frame and car body, one per side (`SIDES`: left,
    right). Fields of shape (2,); a scalar is broadcast. Names: `yaw_dampers.c` (both tied) or
    `yaw_dampers.left.c`.

    Linear with `c` up to `blowoff_velocity`, then slope `c_blowoff` (used only when the model
    option `nonlinear_dampers` is on; reference doc 5.2, CRH380A yaw damper).
    """

    c: float = _side(unit="N s/m", valid=(0.0, 1e8), bounds=(1e5, 2e6), doc="damping per damper")
    blowoff_velocity: float = _side(
        unit="m/s", valid=(1e-6, 10.0), bounds=(0.005, 0.05), doc="blow-off velocity"
    )
    c_blowoff: float = _side(
        unit="N s/m", valid=(0.0, 1e8), bounds=(1e3, 1e5), doc="damping above blow-off velocity"
    )


class WheelWear(_Group):
    """Wear of a profile pair's wheel as two differentiable scalars (only with a profile contact
    geometry, `BogieParams.contact_geometry` = `"s1002-uic60"`): the contact table is the blend
    (1 - level) new + level worn of the new S1002's and the measured worn wheel's tables (both on
    UIC60 1:40), its rolling radii then moved from their centred value `conicity_factor` times as
    far (`bogie_jax.contact.scale_conicity`; 1 leaves the blend as it is). The equivalent
    conicity, a linear functional of Delta r, follows: tan(gamma_e) = conicity_factor ((1 -
    level) tan(gamma_e, new) + level tan(gamma_e, worn)) at every amplitude. The level moves
    along the one measured wear path, the factor scales the conicity off it; a wheel whose
    contact points jump elsewhere than any blend's needs its own profile
    (`bogie_jax.contact.measured_wheel`; docs/contact.md)."""

    level: float = physical(
        unit="-", valid=(0.0, 1.0), bounds=(0.0, 1.0), doc="wheel wear: 0 new, 1 the worn profile"
    )
    conicity_factor: float = physical(
        unit="-",
        valid=(0.0, 10.0),
        bounds=(0.5, 2.0),
        doc="the blend's rolling radius difference (and equivalent conicity) times this",
    )
