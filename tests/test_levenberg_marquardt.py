"""The LM's relative-offset stopping rule (`identify._levenberg_marquardt`) against numpy's lstsq
and scipy's least_squares, on a curve fit whose residuals jitter as an ODE fit's do."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import scipy.optimize

from bogie_jax.identify import (
    BoxTransform,
    HouseholderQR,
    LeastSquaresMethod,
    LeastSquaresProblem,
    LevenbergMarquardt,
    fit,
    free_parameters,
    relative_offset,
)


def test_relative_offset_matches_its_definition_by_lstsq():
    rng = np.random.default_rng(3)
    jac = rng.normal(size=(300, 4)) * np.logspace(0, 4, 4)
    r = rng.normal(size=300) + jac @ rng.normal(size=4) * 1e-5
    d = np.linalg.lstsq(jac, r, rcond=None)[0]  # Gauss-Newton step (sign aside)
    offset2, orth2 = np.sum((jac @ d) ** 2), np.sum((r - jac @ d) ** 2)
    expected = np.sqrt((offset2 / 4) / (orth2 / 296))
    np.testing.assert_allclose(relative_offset(jnp.asarray(jac), jnp.asarray(r)), expected, 1e-8)
    assert relative_offset(jnp.asarray(jac), jnp.asarray(jac @ np.ones(4))) == np.inf


T = np.linspace(0.0, 5.0, 400)
SIGMA = 0.01
Y = 2.0 * np.exp(-0.7 * T) + 0.3 + SIGMA * np.random.default_rng(0).normal(size=T.size)


def _smooth(p):
    return p[0] * jnp.exp(-p[1] * T) + p[2] - Y


def _jittery(p, _):
    """The curve fit's residuals plus a rough term of 1e-4 of the noise that changes with the
    parameters but is not differentiated, as an ODE solver's error does when its adaptive steps
    move (the step-size controller is not differentiated)."""
    rough = jax.lax.stop_gradient(1e-6 * jnp.sin(1e7 * (p[0] + 2.0 * p[1] + 3.0 * p[2]) + 17.0 * T))
    return _smooth(p) + rough


def test_lm_stops_within_a_small_fraction_of_a_standard_error():
    p0 = jnp.array([1.0, 0.3, 0.0])
    qr = HouseholderQR()
    ours = optx.least_squares(
        _jittery, LevenbergMarquardt(1e-10, 1e-10, 1e-2, linear_solver=qr), p0, max_steps=200,
        throw=False,
    )  # fmt: skip
    theirs = optx.least_squares(
        _jittery, optx.LevenbergMarquardt(1e-10, 1e-10, linear_solver=qr), p0, max_steps=200,
        throw=False,
    )  # fmt: skip
    assert ours.result == optx.RESULTS.successful
    steps = int(ours.stats["num_steps"])
    # the Cauchy test alone does not stop this fit (the rough term): it runs on
    assert int(theirs.stats["num_steps"]) > 2 * steps

    # oracle: scipy's least_squares on the smooth residuals, and its standard errors
    ref = scipy.optimize.least_squares(
        lambda p: np.asarray(_smooth(p)), [1.0, 0.3, 0.0], xtol=1e-15, ftol=1e-15, gtol=1e-15
    )
    cov = (2 * ref.cost / (T.size - 3)) * np.linalg.inv(ref.jac.T @ ref.jac)
    delta = np.asarray(ours.value) - ref.x
    # the rule's promise: within offset_tol sqrt(n) joint standard errors (Mahalanobis length),
    # up to the change of the linearisation over that distance
    assert np.sqrt(delta @ np.linalg.solve(cov, delta)) < 2 * 1e-2 * np.sqrt(3)


def test_a_fit_stalled_at_its_objectives_own_error_stops_near_the_optimum():
    """A rough term of 10 % of the noise: the offset's floor lies above `offset_tol`, so near
    the optimum the steps are rejected and only the Cauchy test stops the fit. The stall rule
    (5 rejected steps in a row at an offset below 0.1) stops it successfully in a third of the
    steps or fewer, within 0.1 sqrt(3) joint standard errors of scipy's optimum of the smooth
    residuals (the rule's promise)."""

    def rough(p, _):
        wiggle = 1e-3 * jnp.sin(1e7 * (p[0] + 2.0 * p[1] + 3.0 * p[2]) + 17.0 * T)
        return _smooth(p) + jax.lax.stop_gradient(wiggle)

    def lm(stall_offset):
        solver = LevenbergMarquardt(1e-10, 1e-10, 1e-2, HouseholderQR(), stall_offset=stall_offset)
        p0 = jnp.array([1.0, 0.3, 0.0])
        return optx.least_squares(rough, solver, p0, max_steps=200, throw=False)

    stalled, plain = lm(0.1), lm(0.0)
    assert stalled.result == optx.RESULTS.successful
    steps, plain_steps = int(stalled.stats["num_steps"]), int(plain.stats["num_steps"])
    print(f"steps with the stall rule {steps}, without {plain_steps}")
    assert 3 * steps <= plain_steps

    ref = scipy.optimize.least_squares(
        lambda p: np.asarray(_smooth(p)), [1.0, 0.3, 0.0], xtol=1e-15, ftol=1e-15, gtol=1e-15
    )
    cov = (2 * ref.cost / (T.size - 3)) * np.linalg.inv(ref.jac.T @ ref.jac)
    delta = np.asarray(stalled.value) - ref.x
    assert np.sqrt(delta @ np.linalg.solve(cov, delta)) < 0.1 * np.sqrt(3)


def test_a_parameter_held_on_its_bound_is_left_out_of_the_offset():
    """The decay rate's box ends below its best value: the fit holds it on the bound. The offset
    over the other two parameters stops the fit at their optimum given the bound (scipy's
    bounded least_squares as the oracle), where the offset over all three, which keeps a
    component along the rate's vanishing column, lets it run on."""
    tr = BoxTransform([0.5, 0.05, -1.0], [5.0, 0.5, 1.0], names=("a", "b", "c"))
    problem = LeastSquaresProblem(lambda th, args: _jittery(tr.to_physical(th), args), tr)
    start = [1.0, 0.5 - 1e-10, 0.0]  # the rate already on its bound (u = 1 - 2e-10)

    def lm(bound_tol):
        solver = LevenbergMarquardt(1e-10, 1e-10, 1e-2, HouseholderQR(), bound_tol=bound_tol)
        return fit(problem, start, method=LeastSquaresMethod(solver), max_steps=300, throw=False)

    held, all_columns = lm(1e-6), lm(0.0)
    assert held.success and np.asarray(held.on_bound).tolist() == [False, True, False]
    assert int(held.num_steps) < int(all_columns.num_steps)

    ref = scipy.optimize.least_squares(
        lambda p: np.asarray(_smooth(p)), [1.0, 0.3, 0.0], bounds=(tr.lower, tr.upper),
        xtol=1e-15, ftol=1e-15, gtol=1e-15,
    )  # fmt: skip
    assert ref.active_mask.tolist() == [0, 1, 0]
    free = ref.jac[:, [0, 2]]
    cov = (2 * ref.cost / (T.size - 2)) * np.linalg.inv(free.T @ free)
    delta = np.asarray(held.estimates)[[0, 2]] - ref.x[[0, 2]]
    assert np.sqrt(delta @ np.linalg.solve(cov, delta)) < 2 * 1e-2 * np.sqrt(2)


def test_only_boxed_parameters_can_be_held_on_a_bound():
    """A log-scale parameter (bounds 0 and inf, as `select_parameters` gives) is always free;
    a boxed one is held within `bound_tol` box widths of either bound."""

    class _Transform(eqx.Module):
        lower: jax.Array
        upper: jax.Array

        def to_physical(self, theta):
            return theta  # physical = theta, enough for the test

    transform = _Transform(jnp.array([0.0, 0.0, 0.0, 1.0]), jnp.array([jnp.inf, 1.0, 1.0, 3.0]))
    problem = LeastSquaresProblem(lambda th, args: th, transform)
    y = jnp.array([1e-9, 1e-9, 0.5, 3.0 - 1e-7])
    free = free_parameters(y, problem, 1e-6)
    assert np.asarray(free).tolist() == [True, False, True, False]
    assert np.asarray(free_parameters(y, None, 1e-6)).all()
