"""`covariance_from_jacobian` against numpy/scipy, well-conditioned and rank-deficient."""

import jax
import numpy as np
import pytest
import scipy.linalg

from bogie_jax.cost import covariance_from_jacobian


jax.config.update("jax_enable_x64", True)


def _jacobian(seed=0, m=40, n=4):
    return np.random.default_rng(seed).normal(size=(m, n)) * np.array([1.0, 3.0, 0.5, 2.0])[:n]


def test_well_conditioned_matches_numpy():
    jac = _jacobian()
    cov = covariance_from_jacobian(jac, sigma2=2.5)
    ref = 2.5 * np.linalg.inv(jac.T @ jac)
    std = np.sqrt(np.diag(ref))
    np.testing.assert_allclose(cov.covariance, ref, rtol=1e-12)
    np.testing.assert_allclose(cov.std_errors, std, rtol=1e-12)
    np.testing.assert_allclose(cov.correlation, ref / np.outer(std, std), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(cov.eigenvalues, np.linalg.eigvalsh(jac.T @ jac), rtol=1e-12)
    np.testing.assert_allclose(cov.condition_number, np.linalg.cond(jac) ** 2, rtol=1e-10)
    assert int(cov.rank) == 4 and not np.any(cov.null) and cov.null_directions.shape == (4, 0)
    assert np.all(cov.identifiable)


def test_scale_is_the_delta_method():
    jac = _jacobian(1)
    d = np.array([2.0, -0.5, 1e3, 1e-3])
    cov = covariance_from_jacobian(jac, scale=d)
    ref = np.diag(d) @ np.linalg.inv(jac.T @ jac) @ np.diag(d)
    std = np.sqrt(np.diag(ref))
    np.testing.assert_allclose(cov.covariance, ref, rtol=1e-12)
    np.testing.assert_allclose(cov.std_errors, std, rtol=1e-12)
    np.testing.assert_allclose(cov.correlation, ref / np.outer(std, std), rtol=1e-12, atol=1e-14)


def test_rank_deficient_is_reported_not_inverted():
    base = _jacobian(2, n=3)
    # column 3 = column 0 + column 1: the combination p0 + p1 - p3 is not identifiable
    jac = np.column_stack([base, base[:, 0] + base[:, 1]])
    cov = covariance_from_jacobian(jac)
    assert int(cov.rank) == 3 and np.isinf(cov.condition_number)
    null = cov.null_directions
    assert null.shape == (4, 1)
    expected = np.array([1.0, 1.0, 0.0, -1.0]) / np.sqrt(3.0)
    np.testing.assert_allclose(np.abs(null[:, 0] @ expected), 1.0, rtol=1e-10)
    np.testing.assert_allclose(jac @ null, 0.0, atol=1e-10)
    # the loose parameters have infinite errors and NaN correlations; p2 is separable
    assert np.all(np.isinf(np.asarray(cov.std_errors)[[0, 1, 3]]))
    assert np.all(np.isnan(np.asarray(cov.correlation)[[0, 1, 3]]))
    pinv = scipy.linalg.pinvh(jac.T @ jac)
    np.testing.assert_allclose(cov.covariance, pinv, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(cov.std_errors[2], np.sqrt(pinv[2, 2]), rtol=1e-8)
    np.testing.assert_allclose(cov.correlation[2, 2], 1.0, rtol=1e-12)


def test_jit_and_bad_input():
    jac = _jacobian(3)
    jitted = jax.jit(lambda j, s2: covariance_from_jacobian(j, sigma2=s2))(jac, 1.0)
    np.testing.assert_allclose(jitted.covariance, np.linalg.inv(jac.T @ jac), rtol=1e-12)
    with pytest.raises(ValueError, match="2-D"):
        covariance_from_jacobian(np.ones(3))
    with pytest.raises(ValueError, match="rcond"):
        covariance_from_jacobian(jac, rcond=1.5)
    with pytest.raises(ValueError, match="scale"):
        covariance_from_jacobian(jac, scale=np.ones(2))
