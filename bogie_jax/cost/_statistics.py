"""The noise model and the covariance rule of a fit (`monitor` and `bogie_jax.identify`): strategy
objects, chosen by value.

A **noise model** says how the rows are weighted and which residual variance sigma^2 scales the
Gauss-Newton covariance; s2 = 2 S / (m - n - b) is the variance of the fit's weighted residuals
(S = 1/2 |r|^2, m residuals, n fitted coordinates, b bias parameters):

- `PerChannelNoise` (the default): every run-channel's noise variance is estimated from the
  fit's residuals and the fit repeated with those weights (`channel_weights`); sigma^2 = s2
  of the reweighted fit;
- with the sensors' stated `noise_std` as weights: `NominalNoise` (sigma^2 = 1, an exactly known
  variance), `EstimatedNoise` (s2) and `MaxNoise` (the larger of both).

A **covariance rule** turns the fit's residuals and Jacobian into the estimates' covariance:
`GaussNewtonCovariance`, sigma^2 (J^T J)^+ (`bogie_jax.cost.covariance_from_jacobian`), or
`SandwichCovariance`, Newey-West with the Bartlett kernel (`bogie_jax.cost.sandwich_covariance`;
Newey & West, Econometrica 55 (1987) 703), right when the misfit is autocorrelated in time or
differs between channels, never below the Gauss-Newton standard errors with the noise model's
sigma^2. Its bandwidth [samples] is given, or Andrews' AR(1) plug-in rule on the prewhitened
scores (`bogie_jax.cost.long_run_covariance`; Andrews, Econometrica 59 (1991) 817).

Strings name them only at the command line, through `NOISE_MODELS` and `COVARIANCES`.
"""

import abc
import math
from typing import ClassVar

import equinox as eqx

from ._covariance import (
    Covariance,
    covariance_from_jacobian,
    long_run_covariance,
    sandwich_covariance,
    score_series,
)
from ._noise import RunChannels


class AbstractNoiseModel(eqx.Module):
    """How a fit weights its rows and which sigma^2 its covariance uses (module docstring):
    `sigma2(s2)` from the fit's residual variance s2."""

    name: ClassVar[str]
    reweights: ClassVar[bool] = False  # estimate each run-channel's noise and refit

    @abc.abstractmethod
    def sigma2(self, s2: float) -> float:
        raise NotImplementedError

    def residual_dof(self, dof: int) -> float:
        """Degrees of freedom of sigma^2 (`inf`: known exactly, or no residual estimates it)."""
        return dof if dof > 0 else math.inf


class PerChannelNoise(AbstractNoiseModel):
    """Each run-channel's noise estimated and the fit reweighted; sigma^2 = s2."""

    name: ClassVar[str] = "per-channel"
    reweights: ClassVar[bool] = True

    def sigma2(self, s2):
        return s2


class NominalNoise(AbstractNoiseModel):
    """The sensors' stated noise: sigma^2 = 1, known exactly."""

    name: ClassVar[str] = "nominal"

    def sigma2(self, s2):
        return 1.0

    def residual_dof(self, dof):
        return math.inf


class EstimatedNoise(AbstractNoiseModel):
    """The sensors' stated noise as weights, sigma^2 = s2."""

    name: ClassVar[str] = "estimated"

    def sigma2(self, s2):
        return s2


class MaxNoise(AbstractNoiseModel):
    """The sensors' stated noise as weights, sigma^2 = max(1, s2)."""

    name: ClassVar[str] = "max"

    def sigma2(self, s2):
        return max(1.0, s2)


class AbstractCovariance(eqx.Module):
    """A covariance rule (module docstring). `estimate(jac, r, runs, n_nuisance, sigma2,
    scale)` returns the covariance of the coordinates of `jac`'s columns scaled to reported
    values by `scale` (dp/dv), the Gauss-Newton one with `sigma2`, and the bandwidth used (NaN
    for Gauss-Newton); `n_nuisance`: further parameters (bias, profiled nuisance) in the degrees
    of freedom; `runs`: the rows' `RunChannels` layout (its active runs are used)."""

    name: ClassVar[str]

    @abc.abstractmethod
    def estimate(
        self, jac, r, runs: RunChannels, n_nuisance: int, sigma2: float, scale
    ) -> tuple[Covariance, Covariance, float]:
        raise NotImplementedError


class GaussNewtonCovariance(AbstractCovariance):
    """sigma^2 (J^T J)^+."""

    name: ClassVar[str] = "gauss-newton"

    def estimate(self, jac, r, runs, n_nuisance, sigma2, scale):
        gn = covariance_from_jacobian(jac, sigma2=sigma2, scale=scale)
        return gn, gn, float("nan")


class SandwichCovariance(AbstractCovariance):
    """Newey-West with the Bartlett kernel, floored at Gauss-Newton; `bandwidth` [samples]
    (>= 1) or `None` for Andrews' rule."""

    name: ClassVar[str] = "sandwich"
    bandwidth: float | None = None

    def __check_init__(self):
        if self.bandwidth is not None and not float(self.bandwidth) >= 1:
            raise ValueError(f"`bandwidth` = {self.bandwidth!r} must be None or >= 1 (samples)")

    def estimate(self, jac, r, runs, n_nuisance, sigma2, scale):
        gn = covariance_from_jacobian(jac, sigma2=sigma2, scale=scale)
        slices = [sl for k, sl in enumerate(runs.slices) if runs.active[k]]
        bandwidth = self.bandwidth
        if bandwidth is None:
            bandwidth = long_run_covariance(score_series(jac, r, slices, runs.n_channels))[1]
        cov = sandwich_covariance(
            jac, r, runs=slices, n_channels=runs.n_channels, bandwidth=bandwidth,
            n_nuisance=n_nuisance, floor_sigma2=sigma2, scale=scale,
        )  # fmt: skip
        return cov, gn, float(bandwidth)


NOISE_MODELS: dict[str, AbstractNoiseModel] = {
    m.name: m for m in (PerChannelNoise(), MaxNoise(), NominalNoise(), EstimatedNoise())
}
COVARIANCES: dict[str, AbstractCovariance] = {
    c.name: c for c in (SandwichCovariance(), GaussNewtonCovariance())
}
