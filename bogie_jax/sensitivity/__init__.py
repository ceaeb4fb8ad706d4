"""Sensitivity analysis: factor screening and variance-based (Sobol') indices.

Generic core (`screening_*`, `sobol_*`): a pure scalar function of a parameter vector and the
box bounds of the parameters; model evaluations go through `bogie_jax.runtime.batch.batch_runner`.
Objective adapters (`sensitivity_*`): the same on `bogie_jax.cost.Objective`.
Identifiability (`fisher_information`, `profile_likelihood`): Fisher information, collinearity
indices and profile likelihood of an `Objective` or any least-squares problem.
"""

from ._identifiability import (
    CHI2_1_95 as CHI2_1_95,
    PROFILE_THRESHOLD as PROFILE_THRESHOLD,
    CollinearityIndices as CollinearityIndices,
    FisherInformation as FisherInformation,
    ParameterCombination as ParameterCombination,
    ProfileLikelihood as ProfileLikelihood,
    collinearity_indices as collinearity_indices,
    fisher_from_jacobian as fisher_from_jacobian,
    fisher_information as fisher_information,
    physical_jacobian as physical_jacobian,
    profile_interval as profile_interval,
    profile_likelihood as profile_likelihood,
)
from ._layouts import LAYOUTS as LAYOUTS, sensor_layouts as sensor_layouts
from ._objective import (
    objective_bounds as objective_bounds,
    objective_function as objective_function,
    sensitivity_grid as sensitivity_grid,
    sensitivity_sobol as sensitivity_sobol,
    sensitivity_sweeps as sensitivity_sweeps,
)
from ._sampling import (
    MAX_DIMENSION as MAX_DIMENSION,
    SaltelliSample as SaltelliSample,
    saltelli_sample as saltelli_sample,
    sobol_sequence as sobol_sequence,
)
from ._screening import (
    ScreeningGrid as ScreeningGrid,
    ScreeningSweeps as ScreeningSweeps,
    screening_grid as screening_grid,
    screening_sweeps as screening_sweeps,
)
from ._sobol import (
    AbstractSobolEstimator as AbstractSobolEstimator,
    Jansen as Jansen,
    Saltelli2010 as Saltelli2010,
    SobolIndices as SobolIndices,
    sobol_analysis as sobol_analysis,
    sobol_indices as sobol_indices,
)
