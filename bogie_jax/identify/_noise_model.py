"""A fit with the monitor's noise model and covariance rules: one statistics path for both.

The sensors' stated noise levels and a bias-free record are what the plain fit assumes
(`fit_statistics`: s^2 (J^T J)^+ with one pooled s^2). Real records break both, and the
intervals then do not hold. `fit_noise_model` fits as `monitor` does:

1. a constant sensor bias per channel is eliminated by variable projection (each channel's
   residuals centred over its present samples: `bogie_jax.cost.RunChannels`);
2. each channel's noise variance is estimated from the fit's residuals (degrees of freedom
   corrected by the leverage: `bogie_jax.cost.channel_variances`) and the fit repeated with
   the rows weighted by 1 / sqrt of it (`bogie_jax.cost.channel_weights`), up to `REWEIGHTS`
   times until no weight changes by more than `SETTLED` (for a noise model that reweights);
3. the covariance by the covariance rule (`bogie_jax.cost.SandwichCovariance` by default:
   Newey-West, right where the misfit is autocorrelated in time or differs between channels,
   never below Gauss-Newton) with the noise model's sigma^2, mapped to physical units by the
   transform's derivative (delta method); the 95 % intervals with Student's t of m - n - b
   degrees of freedom (b: the bias parameters).

Each fit is identify's Levenberg-Marquardt (`LevenbergMarquardt`, `_lm_fits.fit_one`); the
weights are an array of the residual function, so every refit runs the same compiled
residual-Jacobian program.
"""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..cost import (
    AbstractCovariance,
    AbstractNoiseModel,
    PerChannelNoise,
    RunChannels,
    SandwichCovariance,
    channel_variances,
    channel_weights,
)
from ._levenberg_marquardt import LevenbergMarquardt
from ._lm_fits import STATUS, fit_one
from ._local import as_method
from ._problem import LeastSquaresProblem, as_problem, param_names, start_theta
from ._student_t import t_quantile


REWEIGHTS = 3  # at most this many refits with per-channel weights
SETTLED = 0.1  # the weights have settled when none changes by more than this fraction


class ChannelResiduals(eqx.Module):
    """`residuals(theta, args)` as (n_times, n_channels) rows times the channel `weights`, each
    channel's mean over its `present` samples removed where `remove_bias` (missing samples
    stay zero)."""

    residuals: object
    weights: jax.Array
    present: jax.Array
    remove_bias: bool = eqx.field(static=True)

    def __call__(self, theta, args):
        r = jnp.reshape(self.residuals(theta, args), self.present.shape) * self.weights
        if self.remove_bias:
            count = jnp.maximum(jnp.sum(self.present, axis=0), 1)
            r = r - jnp.sum(jnp.where(self.present, r, 0.0), axis=0) / count
        return jnp.ravel(jnp.where(self.present, r, 0.0))


@dataclasses.dataclass(frozen=True)
class NoiseModelFit:
    """`fit_noise_model`'s result: parameter `names`, `estimates`, `std_errors`, `ci95` (n, 2)
    and `covariance` in physical units; `theta`; the last fit's `status` and the `steps` of all
    fits; the residual variance `noise_variance` (2 S / (m - n - b)) and the noise model's
    `sigma2`, the degrees of freedom `dof`; `channel_noise`: each channel's noise at the estimate
    as a multiple of its stated `noise_std`; `weights` of the channels; `reweights` (refits);
    the `noise` model's and `covariance` rule's names, its `bandwidth` [samples], and
    `bias_removed`."""

    names: tuple[str, ...]
    estimates: np.ndarray
    std_errors: np.ndarray
    ci95: np.ndarray
    covariance: np.ndarray
    theta: np.ndarray
    status: str
    steps: int
    noise_variance: float
    sigma2: float
    dof: int
    channel_noise: np.ndarray
    weights: np.ndarray
    reweights: int
    noise: str
    covariance_rule: str
    bandwidth: float
    bias_removed: bool


def _present(objective, present) -> np.ndarray:
    """(n_times, n_channels) present samples: `present`, or the objective's mask."""
    if present is None:
        present = getattr(getattr(objective, "residual_model", None), "mask", None)
    if present is None or np.ndim(present) != 2:
        raise ValueError(
            "`present` must be given as (n_times, n_channels) for an objective that is not one "
            "run's `bogie_jax.cost.make_objective` (its residual model's mask gives it)"
        )
    return np.asarray(present, dtype=bool)


def fit_noise_model(
    objective,
    start=None,
    *,
    noise: AbstractNoiseModel = PerChannelNoise(),
    covariance: AbstractCovariance = SandwichCovariance(),
    remove_bias: bool = True,
    method="lm",
    max_steps: int = 256,
    present=None,
) -> NoiseModelFit:
    """Fit `objective` (one run's, `bogie_jax.cost.make_objective`, or a `LeastSquaresProblem`
    with its sample-major residuals' `present` (n_times, n_channels) mask) from `start`
    (physical units, default nominal) with the noise model and covariance rule of the module
    docstring; `method`: `"lm"` or a `LevenbergMarquardt`.

    **Raises:** `ValueError` for another method."""
    base = as_problem(objective)
    theta = start_theta(base.transform, start)
    present = _present(objective, present)
    runs = RunChannels.of([slice(0, present.size)], present.shape[1], present.reshape(-1))
    lm = as_method(method)
    if not isinstance(lm, LevenbergMarquardt):
        raise ValueError(f'`method` = {method!r} must be "lm" or a LevenbergMarquardt')
    w = np.ones(present.shape[1])
    fits, reference, s2 = [], None, None
    for k in range(REWEIGHTS + 1):
        weighted = ChannelResiduals(
            base.residuals, jnp.asarray(w), jnp.asarray(present), remove_bias
        )
        problem = LeastSquaresProblem(weighted, base.transform, base.args)
        lm_fit = fit_one(problem, np.asarray(theta), lm, max_steps)
        theta, r, jac = lm_fit.phi, lm_fit.r, lm_fit.jac
        fits.append((theta, STATUS[lm_fit.status], lm_fit.steps, r, jac))
        s2 = channel_variances(r, jac, runs, remove_bias=remove_bias, weights=w[None, :])
        if reference is None:
            dof = runs.n_present - (runs.n_bias if remove_bias else 0) - theta.size
            reference = float(r @ r) / dof if dof > 0 else 1.0
        new = channel_weights(s2, reference=reference)[0]
        if not noise.reweights or k == REWEIGHTS or np.nanmax(np.abs(new / w - 1.0)) <= SETTLED:
            break
        w = new
    return _statistics(base, fits, runs, s2, w, (noise, covariance, remove_bias))


def _statistics(base, fits, runs, s2, w, model) -> NoiseModelFit:
    """The estimates' statistics at the last fit (module docstring, step 3)."""
    noise, rule, remove_bias = model
    theta, result, _, r, jac = fits[-1]
    n_bias = runs.n_bias if remove_bias else 0
    dof = runs.n_present - theta.size - n_bias
    s2_all = float(r @ r) / dof if dof > 0 else float("nan")
    sigma2 = noise.sigma2(s2_all)
    ones = (jnp.ones(theta.size),)
    estimates, d = jax.jvp(base.transform.to_physical, (jnp.asarray(theta),), ones)
    cov, _, bandwidth = rule.estimate(jac, r, runs, n_bias, sigma2, np.asarray(d))
    se = np.asarray(cov.std_errors)
    half = t_quantile(0.975, noise.residual_dof(dof)) * se
    estimates = np.asarray(estimates)
    return NoiseModelFit(
        names=param_names(base.transform, theta.size), estimates=estimates, std_errors=se,
        ci95=np.stack([estimates - half, estimates + half], axis=-1),
        covariance=np.asarray(cov.covariance), theta=theta, status=result,
        steps=sum(f[2] for f in fits), noise_variance=s2_all, sigma2=float(sigma2),
        dof=int(dof), channel_noise=np.sqrt(s2[0]), weights=w, reweights=len(fits) - 1,
        noise=noise.name, covariance_rule=rule.name, bandwidth=bandwidth,
        bias_removed=bool(remove_bias),
    )  # fmt: skip
