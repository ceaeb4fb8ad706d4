"""The least-squares objective (paper eq. 12) over selected parameters in unconstrained
coordinates: the single definition used by gradients, identification and sensitivity, with its
one residual Jacobian (`residual_jacobian`) and one covariance computation
(`covariance_from_jacobian`); per-run position and speed corrections fitted as nuisance
parameters through `Objective.with_run_corrections()` (`CorrectedObjective`, `RunCorrections`)."""

from ._covariance import (
    Covariance as Covariance,
    covariance_from_jacobian as covariance_from_jacobian,
    hac_bandwidth as hac_bandwidth,
    long_run_covariance as long_run_covariance,
    relative_to_nominal as relative_to_nominal,
    sandwich_covariance as sandwich_covariance,
    score_series as score_series,
    with_model_error as with_model_error,
)
from ._jacobian import forward_mode as forward_mode, residual_jacobian as residual_jacobian
from ._joint import (
    JointResidualModel as JointResidualModel,
    joint_residual_model as joint_residual_model,
    make_joint_objective as make_joint_objective,
)
from ._lead_in import (
    DEFAULT_DECAY as DEFAULT_DECAY,
    default_lead_in as default_lead_in,
    slowest_decay_rate as slowest_decay_rate,
    window_lead_in as window_lead_in,
)
from ._make import make_objective as make_objective
from ._noise import (
    S2_FLOOR as S2_FLOOR,
    RunChannels as RunChannels,
    channel_variances as channel_variances,
    channel_weights as channel_weights,
    leverage as leverage,
)
from ._objective import Objective as Objective, ResidualModel as ResidualModel
from ._rest_state import fixed_rest_state as fixed_rest_state
from ._run_corrections import (
    CorrectedObjective as CorrectedObjective,
    RunCorrections as RunCorrections,
)
from ._scenario import synthetic_objective as synthetic_objective
from ._selection import (
    ParameterSelection as ParameterSelection,
    get_parameter as get_parameter,
    select_parameters as select_parameters,
)
from ._statistics import (
    COVARIANCES as COVARIANCES,
    NOISE_MODELS as NOISE_MODELS,
    AbstractCovariance as AbstractCovariance,
    AbstractNoiseModel as AbstractNoiseModel,
    EstimatedNoise as EstimatedNoise,
    GaussNewtonCovariance as GaussNewtonCovariance,
    MaxNoise as MaxNoise,
    NominalNoise as NominalNoise,
    PerChannelNoise as PerChannelNoise,
    SandwichCovariance as SandwichCovariance,
)
