"""Wheel-rail contact: contact geometry (a cone on a circular rail head, or a table from real
wheel and rail profiles), Hertz normal contact, Kalker creep (ref. doc 1-3)."""

from ._conicity import equivalent_conicity as equivalent_conicity
from ._creep import (
    linear_creep_forces as linear_creep_forces,
    shen_hedrick_elkins as shen_hedrick_elkins,
)
from ._geometry import ConeGeometry as ConeGeometry, cone_geometry as cone_geometry
from ._hertz import (
    HertzContact as HertzContact,
    cone_on_rail_curvatures as cone_on_rail_curvatures,
    ellipe as ellipe,
    ellipk as ellipk,
    hertz_axis_ratio as hertz_axis_ratio,
    hertz_contact as hertz_contact,
)
from ._kalker import (
    KALKER_TABLE_A_OVER_B as KALKER_TABLE_A_OVER_B,
    KALKER_TABLE_E3 as KALKER_TABLE_E3,
    CreepCoefficients as CreepCoefficients,
    creep_coefficients as creep_coefficients,
    kalker_coefficients as kalker_coefficients,
    shear_modulus as shear_modulus,
)
from ._named import (
    PROFILE_PAIRS as PROFILE_PAIRS,
    measured_wheel as measured_wheel,
    named_contact_table as named_contact_table,
    profile_pair as profile_pair,
    shipped_profile as shipped_profile,
)
from ._placement import (
    PlacedProfiles as PlacedProfiles,
    ProfileSetup as ProfileSetup,
    place_profiles as place_profiles,
)
from ._profile import (
    Profile as Profile,
    ProfileError as ProfileError,
    read_profile as read_profile,
    write_csv as write_csv,
)
from ._profile_geometry import (
    QUANTITIES as QUANTITIES,
    ProfileGeometry as ProfileGeometry,
    blend_geometries as blend_geometries,
    profile_geometry as profile_geometry,
    scale_conicity as scale_conicity,
)
from ._search import (
    COLUMNS as COLUMNS,
    ContactTable as ContactTable,
    contact_table as contact_table,
)
