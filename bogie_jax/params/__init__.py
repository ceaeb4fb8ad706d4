"""Typed physical parameters of the bogie (SI units, with bounds)."""

from ._bogie import BogieParams as BogieParams, ModelOptions as ModelOptions
from ._groups import (
    BodyInertia as BodyInertia,
    Geometry as Geometry,
    Masses as Masses,
    PrimarySuspension as PrimarySuspension,
    SecondarySuspension as SecondarySuspension,
    WheelRailContact as WheelRailContact,
    YawDampers as YawDampers,
)
from ._paths import parameter_names as parameter_names, parameter_specs as parameter_specs
from ._sets import (
    PARAMETER_SETS as PARAMETER_SETS,
    crh380a as crh380a,
    manchester_benchmark as manchester_benchmark,
)
from ._spec import FieldSpec as FieldSpec, ParameterError as ParameterError, physical as physical
