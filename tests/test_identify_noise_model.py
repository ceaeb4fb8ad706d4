"""`bogie_jax.identify.fit_noise_model`: the monitor's noise model (sensor bias removed, each
channel's noise estimated and the fit reweighted) and covariance rules in a fit, on a linear
problem whose answer numpy gives (no simulation)."""

import jax.numpy as jnp
import numpy as np

from bogie_jax.cost import GaussNewtonCovariance, NominalNoise
from bogie_jax.identify import BoxTransform, LeastSquaresProblem, fit_noise_model


def _channel_problem(seed):
    """A linear model of 3 channels x 400 samples with a bias per channel and noise levels of
    1, 5 and 0.2 times the stated one: its residuals, present mask and truth."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 4.0, 400)[:, None]
    basis = np.stack([np.sin(3 * t + [0.0, 1.0, 2.0]), np.cos(5 * t + [0.5, 0.2, 0.9])])
    truth = np.array([1.5, -0.7])
    level, bias = np.array([1.0, 5.0, 0.2]), np.array([0.3, -2.0, 0.05])
    y = np.einsum("p,ptc->tc", truth, basis) + bias + level * rng.standard_normal((400, 3))

    box = BoxTransform([-10.0, -10.0], [10.0, 10.0])

    def residuals(theta, args):
        p = box.to_physical(theta)
        return jnp.ravel(jnp.einsum("p,ptc->tc", p, jnp.asarray(basis)) - y)

    problem = LeastSquaresProblem(residuals, box)
    return problem, basis, y, truth, level


def test_noise_model_fit_estimates_channel_noise_and_equals_weighted_least_squares():
    """Per channel: the noise level is found (its stated level 1), the fit equals weighted least
    squares with explicit bias columns and the final weights, and the truth lies in the
    intervals; the plain pooled fit would weight the noisy channel as much as the quiet one."""
    problem, basis, y, truth, level = _channel_problem(0)
    ones = np.ones((400, 3), bool)
    model = fit_noise_model(problem, start=[0.0, 0.0], present=ones)
    assert model.status == "successful" and model.reweights >= 1 and model.bias_removed
    np.testing.assert_allclose(model.channel_noise, level, rtol=0.1)
    design = [np.ravel(basis[k] * model.weights) for k in range(2)]
    design += [np.ravel(np.outer(np.ones(400), np.eye(3)[c] * model.weights[c])) for c in range(3)]
    coef = np.linalg.lstsq(np.stack(design, 1), np.ravel(y * model.weights), rcond=None)[0]
    # variable projection: the same optimum, to the LM's stop (relative offset 0.01)
    assert np.all(np.abs(model.estimates - coef[:2]) <= 0.02 * model.std_errors)
    assert np.all((model.ci95[:, 0] <= truth) & (truth <= model.ci95[:, 1])), model.ci95
    gn = fit_noise_model(
        problem, present=ones, noise=NominalNoise(), covariance=GaussNewtonCovariance()
    )
    assert gn.reweights == 0 and gn.covariance_rule == "gauss-newton" and gn.dof == 1200 - 2 - 3
