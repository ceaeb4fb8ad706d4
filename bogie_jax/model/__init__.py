"""The 10-DOF bogie model: kinematics, Lagrangian, forces and the diffrax vector field."""

from ._constants import model_constants as model_constants, ModelConstants as ModelConstants
from ._dynamics import (
    accelerations as accelerations,
    build_model as build_model,
    BogieModel as BogieModel,
    mass_matrix as mass_matrix,
    track_inputs as track_inputs,
    vector_field as vector_field,
)
from ._equilibrium import (
    equilibrium_residual as equilibrium_residual,
    static_equilibrium as static_equilibrium,
    static_equilibrium_solve as static_equilibrium_solve,
)
from ._layout import (
    DOF_NAMES as DOF_NAMES,
    DOF_UNITS as DOF_UNITS,
    dof_index as dof_index,
    N_DOF as N_DOF,
)
from ._stability import (
    critical_speed as critical_speed,
    CriticalSpeed as CriticalSpeed,
    eigenvalues as eigenvalues,
    stability_sweep as stability_sweep,
    StabilitySweep as StabilitySweep,
    system_matrix as system_matrix,
)
