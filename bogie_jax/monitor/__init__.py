"""Condition monitoring: verdicts per suspension element and trends over dated runs.

`from bogie_jax.monitor import monitor, MonitorOptions`: `monitor(measurements, tracks,
params=..., options=MonitorOptions(...))`.
"""

from ..cost import (  # the noise model and covariance rules, shared with identify
    COVARIANCES as COVARIANCES,
    NOISE_MODELS as NOISE_MODELS,
    S2_FLOOR as S2_FLOOR,
    AbstractCovariance as AbstractCovariance,
    AbstractNoiseModel as AbstractNoiseModel,
    EstimatedNoise as EstimatedNoise,
    GaussNewtonCovariance as GaussNewtonCovariance,
    MaxNoise as MaxNoise,
    NominalNoise as NominalNoise,
    PerChannelNoise as PerChannelNoise,
    RunChannels as RunChannels,
    SandwichCovariance as SandwichCovariance,
    channel_variances as channel_variances,
    channel_weights as channel_weights,
    leverage as leverage,
)
from ..identify import (  # the one t distribution and the one Levenberg-Marquardt
    HostFit as HostFit,
    levenberg_marquardt as levenberg_marquardt,
    satterthwaite_dof as satterthwaite_dof,
    t_quantile as t_quantile,
    two_sided_p_value as two_sided_p_value,
)
from ._defects import (
    DEFECT_SCENARIOS as DEFECT_SCENARIOS,
    FAILED_FLOOR as FAILED_FLOOR,
    DefectScenario as DefectScenario,
    RunSpec as RunSpec,
    as_defect_scenario as as_defect_scenario,
    scenario_layout as scenario_layout,
    scenario_measurements as scenario_measurements,
)
from ._discrepancy import Discrepancy as Discrepancy, model_discrepancy as model_discrepancy
from ._elements import (
    DEFAULT_CANDIDATES as DEFAULT_CANDIDATES,
    DEFAULT_FAILED_FRACTION as DEFAULT_FAILED_FRACTION,
    DEFAULT_TOLERANCE as DEFAULT_TOLERANCE,
    MAX_CORRELATION as MAX_CORRELATION,
    RESOLUTION as RESOLUTION,
    WEIGHT_TOLERANCE as WEIGHT_TOLERANCE,
    Coordinate as Coordinate,
    ElementStatus as ElementStatus,
    check_candidates as check_candidates,
    classify_elements as classify_elements,
    group_value as group_value,
    group_weights as group_weights,
    same_measure as same_measure,
)
from ._fit import REWEIGHTS as REWEIGHTS, SETTLED as SETTLED
from ._goodness import (
    HIGH_BAND_START as HIGH_BAND_START,
    LOW_BAND as LOW_BAND,
    GoodnessOfFit as GoodnessOfFit,
    Misfit as Misfit,
    channel_groups as channel_groups,
    goodness_of_fit as goodness_of_fit,
    not_explained_line as not_explained_line,
    not_explained_warning as not_explained_warning,
)
from ._horizon import (
    HORIZON_START as HORIZON_START,
    horizon_stages as horizon_stages,
    window_rows as window_rows,
)
from ._imperfections import (
    ERROR_SEED_OFFSET as ERROR_SEED_OFFSET,
    channel_rms as channel_rms,
    nonlinear_options as nonlinear_options,
    recorded_track as recorded_track,
    with_channel_noise as with_channel_noise,
    with_sensor_bias as with_sensor_bias,
    with_speed_error as with_speed_error,
    worn_wheels as worn_wheels,
)
from ._judgement import (
    SIMEX_MAX_SPREAD as SIMEX_MAX_SPREAD,
    estimate_of as estimate_of,
    unsettled_bias as unsettled_bias,
)
from ._misfit_scale import (
    misfit_scales as misfit_scales,
    scaled_for_misfit as scaled_for_misfit,
)
from ._monitor import compile_programs as compile_programs, monitor as monitor
from ._nuisance import (
    DEFAULT_NUISANCE as DEFAULT_NUISANCE,
    MAX_OFFSET as MAX_OFFSET,
    OFFSET_SCALE as OFFSET_SCALE,
    SPEED_SCALE as SPEED_SCALE,
    check_nuisance as check_nuisance,
    default_nuisance as default_nuisance,
)
from ._options import MonitorOptions as MonitorOptions
from ._profile import ProfilePoint as ProfilePoint, profile_point as profile_point
from ._record_shape import (
    LONG_BAND as LONG_BAND,
    LONG_SHARES as LONG_SHARES,
    RECORD_BAND as RECORD_BAND,
    least_surprising_share as least_surprising_share,
    long_wave_term as long_wave_term,
    mixed_effect as mixed_effect,
    mixed_record_term as mixed_record_term,
)
from ._result import (
    MISFIT_LIMIT as MISFIT_LIMIT,
    FitSummary as FitSummary,
    MonitorResult as MonitorResult,
    RunStatus as RunStatus,
    misfit_warning as misfit_warning,
)
from ._suspects import (
    Suspect as Suspect,
    freed_interval as freed_interval,
    freed_step as freed_step,
    omitted_elements as omitted_elements,
    recheck_alarm as recheck_alarm,
    relative_change as relative_change,
    score_tests as score_tests,
)
from ._track_error import (
    RecordError as RecordError,
    Sampling as Sampling,
    TrackErrorEffect as TrackErrorEffect,
    record_error as record_error,
    track_error_effect as track_error_effect,
)
from ._trend import (
    Trend as Trend,
    band_of_row as band_of_row,
    comparable_estimates as comparable_estimates,
    trend as trend,
    trend_of_rows as trend_of_rows,
)
from ._verdict import (
    VERDICTS as VERDICTS,
    WATCH_NOTE as WATCH_NOTE,
    ToleranceBand as ToleranceBand,
    Verdict as Verdict,
    decision_z as decision_z,
    interval_outside as interval_outside,
    judge as judge,
    verdict_label as verdict_label,
)
