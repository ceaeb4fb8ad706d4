"""Per-run nuisance corrections of where a run lies on its track record and how fast it ran,
fitted together with the suspension parameters.

A track record is positioned along the track to about 0.5 m, and a run's speed is known to
about 1 %: fitted with the nominal values, the suspension estimates absorb the mismatch (biased
estimates, false alarms). Run k is therefore simulated with

    start_position_k' = start_position_k + position_offset_k         [m]
    speed_k'          = speed_k * exp(log_speed_factor_k)           [m/s]

(zero corrections: the run as recorded). The samples stay where they were measured (k / f_s
after the first sample) and so does the lead-in distance [m] before the first sample, so the
bogie starts `lead_in` metres before the corrected first position, at the corrected speed. A
record whose irregularity at s is the true one at s + d (`TrackIrregularity` with `s0`
lowered by d, as `bogie_jax.cli.demo.recorded_track` builds it) is matched by
`position_offset` = -d; data recorded at speed v_true with the speed given as v by
`log_speed_factor` = log(v_true / v).

`CorrectedObjective` is the objective over the stacked vector

    x = [theta (n), position_offset (R) [m], log_speed_factor (R) [-]],

the shared parameters of an `Objective` (n) and the corrections of its R runs (R = 1 for a
single-run objective), with `residuals(x, args)` for `residual_jacobian` and the least-squares
solvers. Get it from `Objective.with_run_corrections()`.
"""

import dataclasses
from typing import TYPE_CHECKING

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float


if TYPE_CHECKING:
    from ._objective import Objective


def _as_float_array(x):
    return jnp.asarray(x, dtype=float)


class RunCorrections(eqx.Module):
    """Per-run corrections of position and speed (module docstring); zero = no correction.

    - `position_offset` (R,) [m]: added to each run's `start_position` (the track position of
      its first sample);
    - `log_speed_factor` (R,) [-]: each run's speed is multiplied by `exp(log_speed_factor)`
      (`speed_factor`); log scale, so every real value is a positive speed.

    Both are arrays (traced): every value shares one compiled program.
    """

    position_offset: Float[Array, " r"] = eqx.field(converter=_as_float_array)
    log_speed_factor: Float[Array, " r"] = eqx.field(converter=_as_float_array)

    def __check_init__(self):
        a, b = jnp.shape(self.position_offset), jnp.shape(self.log_speed_factor)
        if a != b or len(a) > 1:
            raise ValueError(
                "`position_offset` and `log_speed_factor` must have one shape (n_runs,); got "
                f"{a} and {b}"
            )

    @classmethod
    def zeros(cls, n_runs: int) -> "RunCorrections":
        """No correction for `n_runs` runs."""
        return cls(jnp.zeros(n_runs), jnp.zeros(n_runs))

    @property
    def n_runs(self) -> int:
        return int(jnp.size(self.position_offset))

    @property
    def speed_factor(self) -> Float[Array, " r"]:
        """exp(log_speed_factor) (R,) [-]: corrected speed / recorded speed."""
        return jnp.exp(self.log_speed_factor)

    def __add__(self, other: "RunCorrections") -> "RunCorrections":
        """Both corrections applied one after the other (offsets and log factors add)."""
        return RunCorrections(
            self.position_offset + other.position_offset,
            self.log_speed_factor + other.log_speed_factor,
        )


def check_corrections(corrections, n_runs: int) -> RunCorrections:
    """`corrections` as `RunCorrections` of `n_runs` runs (shapes are static: checked at trace
    time). **Raises:** `TypeError` / `ValueError` naming the argument."""
    if not isinstance(corrections, RunCorrections):
        raise TypeError(f"`corrections` must be a RunCorrections, got {type(corrections).__name__}")
    if corrections.n_runs != n_runs:
        raise ValueError(
            f"`corrections` holds {corrections.n_runs} runs for a residual model of {n_runs}"
        )
    return corrections


class CorrectedObjective(eqx.Module):
    """J(x) = 1/2 |r(x)|^2 over x = [theta (n), position_offset (R) [m], log_speed_factor (R)
    [-]] (module docstring): `objective`'s residuals with each run k simulated at
    start_position_k + position_offset_k and speed_k * exp(log_speed_factor_k).

    `residuals(x, args)` has the optimistix signature; `residual_jacobian(corrected, x)` gives
    J (m, n + 2R), whose columns `theta_slice`, `offset_slice`, `log_speed_slice` are the
    derivatives by theta, by the offsets [1/m] and by the log speed factors. At
    x = `join(theta)` (zero corrections) the residuals are `objective.residuals(theta)`.
    Compile it with the objective as an argument (`eqx.filter_jit`), as an `Objective`:
    evaluated eagerly, `simulate`'s window checks see the corrected start position (a negative
    one raises), under `jit` they see tracers and check nothing.

    - `objective`: the `Objective` (single run, or joint over runs: `make_joint_objective`).
    """

    objective: "Objective"

    # ---------------------------------------------------------------- sizes and layout of x
    @property
    def n_theta(self) -> int:
        """n: the shared (suspension) parameters."""
        return self.objective.n_params

    @property
    def n_runs(self) -> int:
        """R: the runs (1 for a single-run objective)."""
        return self.objective.residual_model.n_runs

    @property
    def n_params(self) -> int:
        """n + 2R: the length of x."""
        return self.n_theta + 2 * self.n_runs

    @property
    def theta_slice(self) -> slice:
        return slice(0, self.n_theta)

    @property
    def offset_slice(self) -> slice:
        """Entries (and Jacobian columns) of the position offsets [m]."""
        return slice(self.n_theta, self.n_theta + self.n_runs)

    @property
    def log_speed_slice(self) -> slice:
        """Entries (and Jacobian columns) of the log speed factors [-]."""
        return slice(self.n_theta + self.n_runs, self.n_params)

    @property
    def names(self) -> tuple[str, ...]:
        """Names of the entries of x: the selection's, `position_offset[k]`,
        `log_speed_factor[k]`."""
        runs = range(self.n_runs)
        return (
            *self.objective.selection.names,
            *(f"position_offset[{k}]" for k in runs),
            *(f"log_speed_factor[{k}]" for k in runs),
        )

    @property
    def units(self) -> tuple[str, ...]:
        """Units of the physical values of x's entries (theta's parameters; m; -)."""
        return (*self.objective.selection.units, *("m",) * self.n_runs, *("-",) * self.n_runs)

    def split(self, x) -> tuple[Float[Array, " n"], RunCorrections]:
        """`(theta (n,), RunCorrections)` of a vector x (n + 2R,)."""
        x = jnp.asarray(x)
        if x.shape != (self.n_params,):
            raise ValueError(
                f"`x` must have shape ({self.n_params},) = n + 2R with n = {self.n_theta} "
                f"parameters and R = {self.n_runs} runs, got {x.shape}"
            )
        corrections = RunCorrections(x[self.offset_slice], x[self.log_speed_slice])
        return x[self.theta_slice], corrections

    def join(self, theta, corrections: RunCorrections | None = None) -> Float[Array, " p"]:
        """x (n + 2R,) of `theta` (n,) and `corrections` (default: none)."""
        theta = jnp.asarray(theta, dtype=float)
        if theta.shape != (self.n_theta,):
            raise ValueError(f"`theta` must have shape ({self.n_theta},), got {theta.shape}")
        if corrections is None:
            corrections = RunCorrections.zeros(self.n_runs)
        check_corrections(corrections, self.n_runs)
        return jnp.concatenate([theta, corrections.position_offset, corrections.log_speed_factor])

    def profile_jacobian(self, jac) -> Float[Array, "m n"]:
        """The theta columns of `jac` (m, n + 2R) with the corrections profiled out:
        J_eff = (I - P_c) J_theta, P_c the orthogonal projector onto the correction columns
        J_c (least squares; zero columns, e.g. of inactive runs, drop out). Then
        J_eff^T J_eff = I_tt - I_tc I_cc^+ I_ct (the Schur complement of the Fisher information
        J^T J), whose inverse is the theta block of (J^T J)^-1: the information on theta
        with the corrections unknown, for identifiability checks on theta alone."""
        jac = jnp.asarray(jac)
        if jac.ndim != 2 or jac.shape[1] != self.n_params:
            raise ValueError(
                f"`jac` must have shape (m, {self.n_params}) (columns of x), got {jac.shape}"
            )
        j_theta, j_c = jac[:, self.theta_slice], jac[:, self.n_theta :]
        coef = jnp.linalg.lstsq(j_c, j_theta)[0]
        return j_theta - j_c @ coef

    # ---------------------------------------------------------------- evaluation
    def corrected(self, corrections: RunCorrections):
        """The `Objective` over theta with `corrections` applied to its runs."""
        model = self.objective.residual_model.with_corrections(corrections)
        return dataclasses.replace(self.objective, residual_model=model)

    def residuals(self, x, args=None) -> Float[Array, " m"]:
        """r(x) (m,): the objective's residuals of the corrected runs; +inf everywhere for
        non-finite corrections (not simulated) or theta (see `Objective.residuals`)."""
        del args
        theta, corrections = self.split(x)
        c = jnp.concatenate([corrections.position_offset, corrections.log_speed_factor])
        finite = jnp.all(jnp.isfinite(c))
        safe = _zero_unless(finite, corrections)
        r = self.corrected(safe).residuals(theta)
        return jnp.where(finite, r, jnp.inf)

    def cost(self, x, args=None) -> Float[Array, ""]:
        """J(x) = 1/2 |r(x)|^2."""
        return 0.5 * jnp.sum(self.residuals(x, args) ** 2)

    def predict(self, x):
        """Model channels at x: (n_times, n_channels), or a tuple per run for a joint model."""
        theta, corrections = self.split(x)
        return self.corrected(corrections).predict(theta)

    def simulate(self, x):
        """The simulated run(s) at x (corrected start positions and speeds)."""
        theta, corrections = self.split(x)
        return self.corrected(corrections).simulate(theta)

    # ---------------------------------------------------------------- the wrapped objective
    @property
    def selection(self):
        return self.objective.selection

    @property
    def residual_model(self):
        """The uncorrected residual model (`run_slices`, `active`, ... of a joint model)."""
        return self.objective.residual_model

    @property
    def params(self):
        return self.objective.params

    @property
    def settings(self):
        return self.objective.settings

    @property
    def n_residuals(self) -> int:
        return self.objective.n_residuals

    @property
    def n_observations(self) -> int:
        return self.objective.n_observations

    def physical_params(self, x):
        """The full parameter tree at x (the corrections do not enter it)."""
        return self.objective.physical_params(self.split(x)[0])

    def with_settings(self, settings) -> "CorrectedObjective":
        return CorrectedObjective(self.objective.with_settings(settings))

    def replace(self, **solve_options) -> "CorrectedObjective":
        return CorrectedObjective(self.objective.replace(**solve_options))

    def forward_mode(self) -> "CorrectedObjective":
        """Differentiated in forward mode (what `residual_jacobian` switches to)."""
        return CorrectedObjective(self.objective.forward_mode())


def _zero_unless(finite, corrections: RunCorrections) -> RunCorrections:
    """`corrections` where `finite`, else zero corrections (double-where for safe tangents)."""
    zero = lambda a: jnp.where(finite, a, jnp.zeros_like(a))
    return RunCorrections(zero(corrections.position_offset), zero(corrections.log_speed_factor))
