"""Typed physical parameters of the bogie (SI units, with bounds).

Suspension parameters are per element: `PrimarySuspension` holds one value per axlebox
(`AXLEBOXES` = 1L, 1R, 2L, 2R: wheelset 1 leading at x = +a, L = +y), `SecondarySuspension` and
`YawDampers` one per side (`SIDES` = left, right); a scalar is broadcast to all elements.
Parameter names: tied (`primary.kz`, all four axleboxes together; `masses.frame.mass`) or one
element (`primary.1L.kz`, `secondary.left.cy`, `yaw_dampers.right.c`); see `_paths.py`.
"""

from ._bogie import BogieParams as BogieParams, ModelOptions as ModelOptions
from ._groups import (
    AXLEBOXES as AXLEBOXES,
    SIDES as SIDES,
    BodyInertia as BodyInertia,
    Geometry as Geometry,
    Masses as Masses,
    PrimarySuspension as PrimarySuspension,
    SecondarySuspension as SecondarySuspension,
    WheelRailContact as WheelRailContact,
    WheelWear as WheelWear,
    YawDampers as YawDampers,
)
from ._paths import (
    ParameterPath as ParameterPath,
    element_names as element_names,
    get_parameter as get_parameter,
    parameter_names as parameter_names,
    parameter_specs as parameter_specs,
    resolve_parameter as resolve_parameter,
    set_parameters as set_parameters,
)
from ._sets import (
    MEASURED_WHEEL as MEASURED_WHEEL,
    PARAMETER_SETS as PARAMETER_SETS,
    PROFILE_SET as PROFILE_SET,
    crh380a as crh380a,
    manchester_benchmark as manchester_benchmark,
)
from ._spec import FieldSpec as FieldSpec, ParameterError as ParameterError, physical as physical
