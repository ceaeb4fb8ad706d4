"""The 10-DOF bogie model: kinematics, Lagrangian, forces and the diffrax vector field.

The building blocks (`kinematics`, the closed-form inertia terms, the contact forces) are
public so that they can be checked term by term against independent oracles.
"""

from . import _kinematics as kinematics  # noqa: F401 (a public submodule)
from ._constants import ModelConstants as ModelConstants, model_constants as model_constants
from ._dynamics import (
    BogieModel as BogieModel,
    accelerations as accelerations,
    accelerations_from_inputs as accelerations_from_inputs,
    build_model as build_model,
    mass_matrix as mass_matrix,
    track_inputs as track_inputs,
    vector_field as vector_field,
)
from ._equilibrium import (
    REST_ATOL as REST_ATOL,
    equilibrium_residual as equilibrium_residual,
    rests_at_zero as rests_at_zero,
    static_equilibrium as static_equilibrium,
    static_equilibrium_solve as static_equilibrium_solve,
)
from ._lagrangian import (
    frame_rotation_terms as frame_rotation_terms,
    wheelset_terms as wheelset_terms,
)
from ._layout import (
    DOF_NAMES as DOF_NAMES,
    DOF_UNITS as DOF_UNITS,
    GRAVITY as GRAVITY,
    N_DOF as N_DOF,
    dof_index as dof_index,
)
from ._stability import (
    CriticalSpeed as CriticalSpeed,
    StabilitySweep as StabilitySweep,
    critical_speed as critical_speed,
    eigenvalues as eigenvalues,
    stability_sweep as stability_sweep,
    system_matrix as system_matrix,
)
from ._state_space import (
    N_INPUTS as N_INPUTS,
    SmallMotionSystem as SmallMotionSystem,
    inputs_vector as inputs_vector,
    small_motion_system as small_motion_system,
)
from ._table_range import beyond_contact_table as beyond_contact_table
from ._wheel_rail import (
    contact_generalised_forces as contact_generalised_forces,
    contact_velocities as contact_velocities,
    creepages as creepages,
    scaled_creep_coefficients as scaled_creep_coefficients,
)
