"""The LAPACK-free least-squares solver of the Gauss-Newton / LM steps against numpy's lstsq."""

import jax
import jax.numpy as jnp
import lineax as lx
import numpy as np
import optimistix as optx
import pytest

from bogie_jax.identify import HouseholderQR


@pytest.mark.parametrize("shape", [(7, 3), (200, 6), (40, 40)])
def test_householder_qr_matches_numpy_lstsq(shape):
    rng = np.random.default_rng(sum(shape))
    # columns of very different scales, as sensitivities to physical parameters are
    a = rng.normal(size=shape) * np.logspace(0, 5, shape[1])
    b = rng.normal(size=shape[0])
    x = lx.linear_solve(
        lx.MatrixLinearOperator(jnp.asarray(a)), jnp.asarray(b), HouseholderQR()
    ).value
    ref = np.linalg.lstsq(a, b, rcond=None)[0]
    np.testing.assert_allclose(x, ref, rtol=1e-9, atol=0)


def test_solver_in_lineax_and_under_vmap_has_no_lapack_call():
    rng = np.random.default_rng(1)
    a = jnp.asarray(rng.normal(size=(8, 30, 4)))
    b = jnp.asarray(rng.normal(size=(8, 30)))

    def solve(a_, b_):
        op = lx.MatrixLinearOperator(a_)
        return lx.linear_solve(op, b_, HouseholderQR()).value

    x = jax.vmap(solve)(a, b)
    for i in range(8):
        np.testing.assert_allclose(x[i], np.linalg.lstsq(a[i], b[i], rcond=None)[0], rtol=1e-10)
    hlo = jax.jit(jax.vmap(solve)).lower(a, b).as_text()
    assert "lapack" not in hlo.lower()  # (lineax's error callback is the only custom call)


def test_rank_deficient_system_is_reported_not_returned():
    a = jnp.asarray(np.c_[np.ones(5), np.ones(5)])
    sol = lx.linear_solve(lx.MatrixLinearOperator(a), jnp.ones(5), HouseholderQR(), throw=False)
    assert sol.result != lx.RESULTS.successful


def test_levenberg_marquardt_with_householder_fits_a_curve():
    t = jnp.linspace(0, 1, 50)
    y = 2.0 * jnp.exp(-1.3 * t) + 0.5

    def residuals(p, _):
        return p[0] * jnp.exp(-p[1] * t) + p[2] - y

    solver = optx.LevenbergMarquardt(1e-10, 1e-10, linear_solver=HouseholderQR())
    sol = optx.least_squares(residuals, solver, jnp.array([1.0, 0.5, 0.0]), max_steps=100)
    np.testing.assert_allclose(sol.value, [2.0, 1.3, 0.5], rtol=1e-8)
