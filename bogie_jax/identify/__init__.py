"""Parameter identification: local fits, vmapped multistart, simulated annealing and the hybrid."""

from .._householder import HouseholderQR as HouseholderQR
from ._annealing import (
    AnnealingResult as AnnealingResult,
    AnnealingState as AnnealingState,
    SimulatedAnnealing as SimulatedAnnealing,
    anneal_path as anneal_path,
    anneal_start as anneal_start,
    anneal_steps as anneal_steps,
    anneal_theta as anneal_theta,
    fit_hybrid as fit_hybrid,
    simulated_annealing as simulated_annealing,
)
from ._batched import (
    BatchedFits as BatchedFits,
    batched_fits as batched_fits,
    clear_runner_cache as clear_runner_cache,
    stack_objectives as stack_objectives,
)
from ._chunked import (
    ChunkedMultistart as ChunkedMultistart,
    ChunkProgress as ChunkProgress,
    fit_multistart_chunked as fit_multistart_chunked,
)
from ._fit import fit as fit
from ._jacobian import JacobianResiduals as JacobianResiduals
from ._levenberg_marquardt import (
    HostFit as HostFit,
    LevenbergMarquardt as LevenbergMarquardt,
    levenberg_marquardt as levenberg_marquardt,
    levenberg_marquardt_batch as levenberg_marquardt_batch,
    relative_offset as relative_offset,
)
from ._lm_fits import (
    LMFits as LMFits,
    default_chunk as default_chunk,
    free_parameters as free_parameters,
    queue_lanes as queue_lanes,
    supports_queue as supports_queue,
)
from ._local import (
    LOCAL_METHODS as LOCAL_METHODS,
    AbstractLocalMethod as AbstractLocalMethod,
    FitResult as FitResult,
    LeastSquaresMethod as LeastSquaresMethod,
    MinimiserMethod as MinimiserMethod,
    PatternSearch as PatternSearch,
    as_method as as_method,
    fit_statistics as fit_statistics,
    local_methods as local_methods,
    statistics as statistics,
)
from ._multistart import (
    DESIGNS as DESIGNS,
    AbstractDesign as AbstractDesign,
    Cluster as Cluster,
    LatinHypercube as LatinHypercube,
    MultistartResult as MultistartResult,
    Sobol as Sobol,
    design_starts as design_starts,
    fit_multistart as fit_multistart,
)
from ._noise_model import (
    ChannelResiduals as ChannelResiduals,
    NoiseModelFit as NoiseModelFit,
    fit_noise_model as fit_noise_model,
)
from ._problem import (
    RESULT_NAMES as RESULT_NAMES,
    BoxTransform as BoxTransform,
    LeastSquaresProblem as LeastSquaresProblem,
    as_problem as as_problem,
    is_successful as is_successful,
    results_from_names as results_from_names,
    start_theta as start_theta,
    status_name as status_name,
    status_names as status_names,
)
from ._scenarios import (
    SCENARIOS as SCENARIOS,
    Scenario as Scenario,
    SyntheticProblem as SyntheticProblem,
    relative_errors as relative_errors,
    scenario_problem as scenario_problem,
    tolerance_bounds as tolerance_bounds,
)
from ._student_t import (
    satterthwaite_dof as satterthwaite_dof,
    t_quantile as t_quantile,
    two_sided_p_value as two_sided_p_value,
)
from ._vanished import restart_vanished as restart_vanished
