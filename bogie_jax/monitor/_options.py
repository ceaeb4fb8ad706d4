"""`MonitorOptions`: what `monitor` judges and how it fits, checked when it is built."""

import dataclasses
import math

from .._validation import check_number, check_positive_int
from ..cost import (
    COVARIANCES,
    NOISE_MODELS,
    AbstractCovariance,
    AbstractNoiseModel,
    GaussNewtonCovariance,
    PerChannelNoise,
    SandwichCovariance,
)
from ..params import ModelOptions
from ..runtime.solve_settings import SolveSettings
from ._checks import RUN_MISFIT
from ._elements import MAX_CORRELATION, RESOLUTION
from ._horizon import HORIZON_START
from ._imperfections import nonlinear_options
from ._verdict import check_false_alarm_rate


JACOBIAN_RTOL = 1e-4  # `MonitorOptions.jacobian_rtol`'s default (`_program.py`)
JACOBIANS = ("small-motion", "full")  # `MonitorOptions.jacobian`'s values (`_program.py`)


def _names(value) -> tuple[str, ...] | None:
    """`None`, one name, or a sequence of names as a tuple."""
    if value is None or isinstance(value, str):
        return value if value is None else (value,)
    return tuple(value)


@dataclasses.dataclass(frozen=True)
class MonitorOptions:
    """The options of `monitor`; every field is checked when the options are built (`ValueError`
    or `TypeError` naming the field, its value and what it may be).

    - `candidates`: the parameter names judged (default `DEFAULT_CANDIDATES`); `band`: the
      tolerance bands (`None`: nominal +- 20 %, failed below 25 %; one relative half-width; or
      `{name: ToleranceBand or half-width}`); `false_alarm_rate` in (0, 0.5): the bogie's
      probability of any false alarm (`judge`).
    - `noise`: an `AbstractNoiseModel` (default `PerChannelNoise()`); `covariance`: an
      `AbstractCovariance`, or `None`: `SandwichCovariance()`, or `GaussNewtonCovariance()`
      where `track_error` models the misfit the sandwich is there for (`bogie_jax.cost`).
    - `remove_bias`: a constant sensor bias per run and channel is eliminated
      (`bogie_jax.cost.RunChannels`); `run_corrections`: each run's position on its record and
      speed factor are fitted, and `nuisance`: parameter names fitted but never judged
      (`None`: the contact's model-form parameters, `_nuisance.default_nuisance`; `()`: none).
    - `resolution`, `max_correlation` in (0, 1]: the identifiability rule (`_elements.py`).
    - `max_steps`: Levenberg-Marquardt steps per fit; `horizon_start` [s] (> 0, or `None`): a
      longer record is fitted over growing spans (`_horizon.py`); `run_misfit` (> 0): the rule
      that leaves out a run the joint fit does not explain (`_checks.failed_runs`).
    - `track_error` [m] (>= 0): RMS of the track records' error, propagated by
      `track_error_draws` (>= 2) realisations (`_track_error.py`); 0: exact records.
    - `model`, `settings`, `weights`: the objective's `ModelOptions`, `SolveSettings` (a failed
      solve is reported, never raised: `throw=False` is set) and residual weights
      (`bogie_jax.cost.make_objective`).
    - `jacobian_rtol` in (0, 1), or `None`: the relative tolerance of the solves that give the
      Jacobian (absolute tolerance scaled alike) where no step is accepted on the residuals'
      cost: the first Jacobian, the horizon stages and the track records' term
      (`_program.py`), where `settings` has a `PIDController` with a smaller one. `None`: the
      settings' own throughout.
    - `jacobian`: the model whose derivatives give every Jacobian (`_program.py`):
      `"small-motion"` (the equations of motion linearised about the rest state,
      `bogie_jax.small_motion`) or `"full"` (the equations of motion, with `jacobian_rtol`).
      The residuals, and so the cost every step is accepted on, are the full model's in both.
    - `refit_model`: the `ModelOptions` fitted where `model`'s fit does not explain the data
      (`_goodness.py`) or leaves a run out: every step from the first Jacobian on repeated with
      it, its laws' parameters fitted as nuisance and every Jacobian the full model's, and its
      verdicts kept where that fit explains the data with every run (`FitSummary.model_refit`),
      else the first fit's (`_model_refit.py`). Default: creep saturation and blow-off
      anti-yaw dampers (`nonlinear_options()`), the wheel-rail and damper nonlinearities a
      linear fit of in-service data leaves; `None`: no refit.
    """

    candidates: tuple[str, ...] | None = None
    band: object = None
    false_alarm_rate: float = 0.05
    noise: AbstractNoiseModel = PerChannelNoise()
    covariance: AbstractCovariance | None = None
    remove_bias: bool = True
    run_corrections: bool = True
    nuisance: tuple[str, ...] | None = None
    resolution: float = RESOLUTION
    max_correlation: float = MAX_CORRELATION
    max_steps: int = 30
    horizon_start: float | None = HORIZON_START
    run_misfit: float = RUN_MISFIT
    track_error: float = 0.0
    track_error_draws: int = 16
    model: ModelOptions = dataclasses.field(default_factory=ModelOptions)
    settings: SolveSettings | None = None
    weights: object = None
    jacobian_rtol: float | None = JACOBIAN_RTOL
    jacobian: str = "small-motion"
    refit_model: ModelOptions | None = dataclasses.field(default_factory=nonlinear_options)

    def __post_init__(self):
        set_ = lambda name, value: object.__setattr__(self, name, value)
        set_("candidates", _names(self.candidates))
        set_("nuisance", _names(self.nuisance))
        check_false_alarm_rate(self.false_alarm_rate)
        _check_kind("noise", self.noise, AbstractNoiseModel, NOISE_MODELS)
        if self.covariance is not None:
            _check_kind("covariance", self.covariance, AbstractCovariance, COVARIANCES)
        for name in ("resolution", "max_correlation"):
            check_number(name, getattr(self, name), 0.0, 1.0, open_lo=True)
        check_positive_int("max_steps", self.max_steps)
        if self.horizon_start is not None:
            check_number("horizon_start", self.horizon_start, 0.0, math.inf, "s", open_lo=True)
        check_number("run_misfit", self.run_misfit, 0.0, math.inf, open_lo=True)
        check_number("track_error", self.track_error, 0.0, math.inf, "m")
        check_positive_int("track_error_draws", self.track_error_draws, lo=2)
        if self.jacobian_rtol is not None:
            check_number("jacobian_rtol", self.jacobian_rtol, 0.0, 1.0, open_lo=True, open_hi=True)
        if self.jacobian not in JACOBIANS:
            raise ValueError(f"`jacobian` = {self.jacobian!r} must be one of {JACOBIANS}")
        if not isinstance(self.model, ModelOptions):
            raise TypeError(f"`model` must be a ModelOptions, got {type(self.model).__name__}")
        if self.refit_model is not None and not isinstance(self.refit_model, ModelOptions):
            got = type(self.refit_model).__name__
            raise TypeError(f"`refit_model` must be None or a ModelOptions, got {got}")
        if self.settings is not None and not isinstance(self.settings, SolveSettings):
            got = type(self.settings).__name__
            raise TypeError(f"`settings` must be None or a SolveSettings, got {got}")

    @property
    def covariance_rule(self) -> AbstractCovariance:
        """`covariance`, or its default (the class docstring)."""
        if self.covariance is not None:
            return self.covariance
        return GaussNewtonCovariance() if self.track_error > 0 else SandwichCovariance()

    def fitted_model(self, model_refit: bool) -> ModelOptions:
        """The model a result was fitted with: `refit_model` where its fit was refitted
        (`FitSummary.model_refit`), else `model`."""
        return self.refit_model if model_refit else self.model

    def solve_settings(self) -> SolveSettings:
        """`settings` (default `SolveSettings.for_objective()`) with `throw=False`: a failed
        solve leaves its run out instead of stopping every run of the vmapped program."""
        settings = SolveSettings.for_objective() if self.settings is None else self.settings
        return settings.replace(throw=False)


def _check_kind(name: str, value, kind: type, table: dict) -> None:
    """`TypeError` naming `name` unless `value` is a `kind`; the table's objects in the message."""
    if not isinstance(value, kind):
        objects = ", ".join(f"{type(v).__name__}()" for v in table.values())
        raise TypeError(
            f"`{name}` = {value!r} must be an object such as {objects} (named "
            f"{', '.join(table)} at the command line)"
        )
