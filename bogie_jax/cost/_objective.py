"""The least-squares objective of paper eq. 12, the one definition every later tool uses.

    r(theta) = W^(1/2) (y_model(theta) - y_meas)    over all channels and samples,
    J(theta) = 1/2 |r(theta)|^2,

with W = diag(w_c) per channel (default w_c = 1 / noise_std_c^2, the inverse noise variance) and
missing (NaN) samples excluded. The time integral of eq. 12 becomes a sum over the samples (a
constant factor 1/f_s dropped). theta holds the selected parameters in unconstrained coordinates
(`ParameterSelection`); unselected parameters keep their values in the base `params`.
"""

import dataclasses
import math

import diffrax as dfx
import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from ..measure import sensor_readings
from ..model import build_model
from ..params import BogieParams, ModelOptions
from ..simulation import SolveSettings, Trajectory, simulate
from ..small_motion import SmallMotionSteps, small_motion_response
from ..track import TrackIrregularity
from ._run_corrections import CorrectedObjective, RunCorrections, check_corrections
from ._selection import ParameterSelection


def _as_float(x):
    """A float array (a tracer or JAX array stays as it is): a traced leaf, never static."""
    return x if isinstance(x, jnp.ndarray) or hasattr(x, "aval") else np.asarray(x, dtype=float)


class ResidualModel(eqx.Module):
    """Weighted residuals r(p) (paper eq. 12) as a function of a full parameter tree p.

    Holds the measured data (`data` (n_times, n_channels) with missing samples set to 0 and
    `mask` True where present), `sqrt_weights` (n_channels,) = W^(1/2) [1/channel unit], the run
    (`track`, `speed` [m/s], `duration` [s] from the first to the last sample, `sample_rate`
    [Hz], `start_position` [m]: track position of the first sample, `lead_in` [m]: distance
    simulated before it, `y0`: a fixed initial state at the start of the lead-in, or `None` for
    the static equilibrium of the parameters `p` being evaluated, solved inside the traced
    function), `stop_after` [s] (`simulate`'s: the samples after it are not simulated and
    their residuals mean nothing; `None`: all are), the `sensors` and the `SolveSettings`
    passed to `simulate` (default `SolveSettings.for_objective()`), and `small_motion`: `None`
    (the equations of motion, `simulate`) or the `SmallMotionSteps` of the small-motion model
    (`bogie_jax.small_motion`, set by `with_small_motion`). `start_position` and
    `lead_in` are arrays (traced): every window of the same sample count shares one
    compilation. Build it through `make_objective`.
    """

    params: BogieParams
    track: TrackIrregularity
    speed: Float[Array, ""]
    sensors: tuple
    data: Float[Array, "n c"]
    mask: Bool[Array, "n c"]
    sqrt_weights: Float[Array, " c"]
    duration: float = eqx.field(static=True)
    sample_rate: float = eqx.field(static=True)
    options: ModelOptions = ModelOptions()
    settings: SolveSettings = SolveSettings.for_objective()
    y0: Float[Array, " 20"] | None = None
    start_position: Float[Array, ""] = eqx.field(default=0.0, converter=_as_float)
    lead_in: Float[Array, ""] = eqx.field(default=0.0, converter=_as_float)
    stop_after: Float[Array, ""] | None = None
    small_motion: SmallMotionSteps | None = eqx.field(static=True, default=None)

    # Read-only views of `settings` (backward compatibility).
    solver = property(lambda self: self.settings.solver)
    stepsize_controller = property(lambda self: self.settings.stepsize_controller)
    adjoint = property(lambda self: self.settings.adjoint)
    max_steps = property(lambda self: self.settings.max_steps)
    dt0 = property(lambda self: self.settings.dt0)
    throw = property(lambda self: self.settings.throw)

    @property
    def n_residuals(self) -> int:
        return self.data.size

    @property
    def n_runs(self) -> int:
        """One run (`RunCorrections` of one entry apply to it)."""
        return 1

    def with_corrections(self, corrections: RunCorrections) -> "ResidualModel":
        """This run at `start_position + position_offset` [m] and `speed *
        exp(log_speed_factor)` [m/s] (`RunCorrections` of one run, leaves of shape () or
        (1,)); sample spacing, duration and `lead_in` [m] unchanged. Traceable."""
        if not isinstance(corrections, RunCorrections) or corrections.n_runs != 1:
            check_corrections(corrections, 1)  # raises, naming the problem
        offset = jnp.reshape(corrections.position_offset, ())
        factor = jnp.exp(jnp.reshape(corrections.log_speed_factor, ()))
        return dataclasses.replace(
            self, start_position=self.start_position + offset, speed=self.speed * factor
        )

    def with_small_motion(self, substeps: int = 8) -> "ResidualModel":
        """This run simulated by the small-motion model (`bogie_jax.small_motion`) with
        `substeps` hold steps per sample and the lead-in's steps at that step length: the
        residuals of the linearised equations of motion, whose derivatives approximate the
        full model's (docs/model.md), from this run's `y0`. Needs concrete `lead_in` and
        `speed`."""
        lead_time = float(self.lead_in) / float(self.speed)
        lead_in_steps = math.ceil(lead_time * self.sample_rate * substeps - 1e-9)
        steps = SmallMotionSteps(substeps, lead_in_steps)
        return dataclasses.replace(self, small_motion=steps)

    def simulate(self, params: BogieParams) -> Trajectory:
        """The simulated run at parameters `params` (by the small-motion model where
        `small_motion` is set: every sample, whatever `stop_after`)."""
        if self.small_motion is not None:
            return small_motion_response(
                params, self.track, self.speed, self.start_position, self.lead_in,
                duration=self.duration, sample_rate=self.sample_rate, options=self.options,
                steps=self.small_motion, y0=self.y0,
            )  # fmt: skip
        return simulate(
            params,
            self.track,
            speed=self.speed,
            duration=self.duration,
            sample_rate=self.sample_rate,
            start_position=self.start_position,
            lead_in=self.lead_in,
            y0=self.y0,
            options=self.options,
            settings=self.settings,
            stop_after=self.stop_after,
        )

    def _predict(self, params):
        run = self.simulate(params)
        model = build_model(params, speed=self.speed, track=self.track, options=self.options)
        # q_ddot of the run (one evaluation of the equations of motion per sample); the samples
        # a failed solve did not reach are zeroed (their residuals are +inf in `__call__`)
        clean = lambda x: jnp.where(jnp.isfinite(x), x, 0.0)
        readings = sensor_readings(
            self.sensors, model, run.ts, clean(run.q), clean(run.qd), clean(run.qdd)
        )
        return readings, run.successful

    def predict(self, params: BogieParams) -> Float[Array, "n c"]:
        """Model channels y_model (n_times, n_channels) at `params` (sensor bias included)."""
        return self._predict(params)[0]

    def __call__(self, params: BogieParams) -> Float[Array, " m"]:
        """Residuals (n_times * n_channels,), sample-major; exactly 0 at missing samples and
        +inf everywhere if the solve failed (with `throw=False`)."""
        y, ok = self._predict(params)
        r = jnp.where(self.mask, (y - self.data) * self.sqrt_weights, 0.0)
        return jnp.where(ok, r, jnp.inf).reshape(-1)


class Objective(eqx.Module):
    """J(theta) = 1/2 |r(theta)|^2 over the selected parameters theta (paper eq. 12).

    `residuals(theta, args)` has the optimistix signature (`args` is ignored), so
    `optx.least_squares(objective.residuals, solver, theta0)` works. Pure JAX: compile it with the
    objective as an argument, `eqx.filter_jit(lambda obj, th: obj.cost(th))(objective, theta)`
    (`jax.jit(objective.cost)` fails: a module holding arrays is not hashable; closing over the
    objective in `jax.jit` works but lets XLA fold the parameters into constants, which rounds
    differently); `jax.vmap` (e.g. over theta) and every AD transform the solver's `adjoint`
    supports work. Build it with `make_objective`.

    - `selection`: the `ParameterSelection` (names, units, bounds, transforms);
    - `residual_model`: the `ResidualModel` (data, weights, run, sensors, solver settings).
    """

    selection: ParameterSelection
    residual_model: ResidualModel

    @property
    def params(self) -> BogieParams:
        """The base parameters (unselected parameters keep these values)."""
        return self.residual_model.params

    @property
    def n_params(self) -> int:
        return self.selection.n_params

    @property
    def n_residuals(self) -> int:
        return self.residual_model.n_residuals

    @property
    def n_observations(self) -> int:
        """Number of measured (not missing) samples: the residuals that can be non-zero."""
        return int(jnp.sum(self.residual_model.mask))

    def physical_params(self, theta) -> BogieParams:
        """The full parameter tree at `theta`."""
        return self.selection.apply(self.params, theta)

    def residuals(self, theta, args=None) -> Float[Array, " m"]:
        """r(theta) (n_times * n_channels,): W^(1/2) (y_model - y_meas), sample-major.

        +inf everywhere where `theta` maps to a non-finite physical value (NaN, or +-inf on a
        log scale), without simulating it: an adaptive solve with NaN parameters rejects every
        step until `max_steps` (16384 steps against about 1100 in the 6-parameter
        identification benchmark), and under `vmap` every member of the batch would wait for it
        (e.g. a multistart member that an optimiser left at a NaN point while the others go
        on). An infinite `theta` of a bounded parameter is its bound, and is simulated."""
        del args
        finite = jnp.all(jnp.isfinite(self.selection.to_physical(theta)))
        safe = jnp.where(finite, theta, jnp.zeros_like(theta))
        r = self.residual_model(self.physical_params(safe))
        return jnp.where(finite, r, jnp.inf)

    def cost(self, theta, args=None) -> Float[Array, ""]:
        """J(theta) = 1/2 |r(theta)|^2 (dimensionless: residuals are in noise standard deviations
        with the default weights)."""
        r = self.residuals(theta, args)
        return 0.5 * jnp.sum(r**2)

    def predict(self, theta) -> Float[Array, "n c"]:
        """Model channels (n_times, n_channels) at `theta`."""
        return self.residual_model.predict(self.physical_params(theta))

    def simulate(self, theta) -> Trajectory:
        """The simulated run at `theta`."""
        return self.residual_model.simulate(self.physical_params(theta))

    @property
    def settings(self) -> SolveSettings:
        """The `SolveSettings` of the simulation."""
        return self.residual_model.settings

    def with_settings(self, settings: SolveSettings) -> "Objective":
        """A copy simulating with `settings` (works under `jit`: no validation re-run)."""
        if not isinstance(settings, SolveSettings):
            raise TypeError(f"`settings` must be a SolveSettings, got {type(settings).__name__}")
        model = dataclasses.replace(self.residual_model, settings=settings)
        return Objective(self.selection, model)

    def replace(self, **solve_options) -> "Objective":
        """A copy with some `SolveSettings` fields changed (`solver`, `stepsize_controller`,
        `adjoint`, `max_steps`, `dt0`, `throw`), e.g. `objective.replace(max_steps=4096)`."""
        return self.with_settings(self.settings.replace(**solve_options))

    def with_adjoint(self, adjoint: dfx.AbstractAdjoint) -> "Objective":
        """A copy that differentiates the solve with `adjoint`."""
        return self.with_settings(eqx.tree_at(lambda s: s.adjoint, self.settings, adjoint))

    def forward_mode(self) -> "Objective":
        """This objective differentiated in forward mode (`SolveSettings.forward_mode`), as
        residual Jacobians need; the library switches by itself where it needs it."""
        return self.with_settings(self.settings.forward_mode())

    def with_run_corrections(self) -> CorrectedObjective:
        """The objective over x = [theta (n), position_offset (R) [m], log_speed_factor (R)]:
        each run's position on its track record and its speed fitted as nuisance parameters
        (`bogie_jax.cost.CorrectedObjective`); `residuals` here is unchanged."""
        return CorrectedObjective(self)
