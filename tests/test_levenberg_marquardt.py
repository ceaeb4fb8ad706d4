"""The one Levenberg-Marquardt (`bogie_jax.identify.levenberg_marquardt_batch`): its
relative-offset and stall rules against numpy's lstsq and scipy's least_squares on a curve fit
whose residuals jitter as an ODE fit's do, the bound rule through `fit`, and a batch whose
members keep their own damping, status and failures."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import scipy.optimize

from bogie_jax.identify import (
    BoxTransform,
    LeastSquaresProblem,
    LevenbergMarquardt,
    fit,
    free_parameters,
    levenberg_marquardt_batch,
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
    # over the free columns only: the offset of the system without the held column
    free = np.array([True, False, True, True])
    np.testing.assert_allclose(
        relative_offset(jac, r, free), relative_offset(jac[:, free], r), rtol=1e-12
    )


T = np.linspace(0.0, 5.0, 400)
SIGMA = 0.01
Y = 2.0 * np.exp(-0.7 * T) + 0.3 + SIGMA * np.random.default_rng(0).normal(size=T.size)
P0 = np.array([1.0, 0.3, 0.0])


def _smooth(p):
    return p[0] * np.exp(-p[1] * T) + p[2] - Y


def _rough(amplitude):
    """`evaluate` of the curve fit plus a rough term of `amplitude` that changes with the
    parameters but is not in the Jacobian, as an ODE solver's error does when its adaptive steps
    move (the step-size controller is not differentiated)."""

    def evaluate(points, members):
        del members
        p = points[0]
        e = np.exp(-p[1] * T)
        wiggle = amplitude * np.sin(1e7 * (p[0] + 2.0 * p[1] + 3.0 * p[2]) + 17.0 * T)
        jac = np.stack([e, -p[0] * T * e, np.ones_like(T)], axis=1)
        return (_smooth(p) + wiggle)[None], jac[None], None

    return evaluate


def _scipy_optimum():
    ref = scipy.optimize.least_squares(_smooth, P0, xtol=1e-15, ftol=1e-15, gtol=1e-15)
    cov = (2 * ref.cost / (T.size - 3)) * np.linalg.inv(ref.jac.T @ ref.jac)
    return ref.x, cov


def _standard_errors_away(p, ref, cov) -> float:
    """The Mahalanobis length of p - ref: joint standard errors."""
    delta = np.asarray(p) - ref
    return float(np.sqrt(delta @ np.linalg.solve(cov, delta)))


def test_lm_stops_within_a_small_fraction_of_a_standard_error():
    """A rough term of 1e-4 of the noise: the relative offset stops the fit in fewer steps than
    the numerical rules alone, within 2 x 0.01 sqrt(3) joint standard errors of scipy's optimum
    of the smooth residuals (the rule's promise, up to the change of the linearisation)."""
    evaluate = _rough(1e-6)
    ours = levenberg_marquardt_batch(evaluate, [P0], LevenbergMarquardt(), max_steps=200)[0]
    plain = LevenbergMarquardt(offset_tol=0.0, stall_offset=0.0)
    numerical = levenberg_marquardt_batch(evaluate, [P0], plain, max_steps=200)[0]
    assert ours.status == numerical.status == "converged"
    assert ours.steps < numerical.steps
    ref, cov = _scipy_optimum()
    assert _standard_errors_away(ours.phi, ref, cov) < 2 * 1e-2 * np.sqrt(3)


def test_a_fit_stalled_at_its_objectives_own_error_stops_near_the_optimum():
    """A rough term of 10 % of the noise: the offset's floor lies above `offset_tol`, so near
    the optimum the steps are rejected. The stall rule (5 rejected steps in a row at an offset
    below 0.1) stops the fit, successfully, in fewer steps than the numerical rules, within
    0.1 sqrt(3) joint standard errors of scipy's optimum of the smooth residuals (the rule's
    promise)."""
    evaluate = _rough(1e-3)
    stalled = levenberg_marquardt_batch(evaluate, [P0], LevenbergMarquardt(), max_steps=200)[0]
    plain = LevenbergMarquardt(stall_offset=0.0)
    numerical = levenberg_marquardt_batch(evaluate, [P0], plain, max_steps=200)[0]
    print(f"steps with the stall rule {stalled.steps}, without {numerical.steps}")
    assert stalled.status == "converged"
    assert stalled.steps < numerical.steps
    ref, cov = _scipy_optimum()
    assert _standard_errors_away(stalled.phi, ref, cov) < 0.1 * np.sqrt(3)


def test_a_batch_keeps_each_fits_damping_status_and_failure():
    """Three starts, two lanes: a start whose residuals are not finite fails, a trial point
    whose residuals are not finite is a rejected step, and every fit ends where it ends alone."""
    smooth = _rough(0.0)

    def evaluate(points, members):
        r, jac, _ = zip(*(smooth(p[None], None) for p in points))
        r = np.concatenate(r)
        bad = (points[:, 2] < -3.0) | (points[:, 1] > 2.0)  # a "failed simulation" region
        return np.where(bad[:, None], np.nan, r), np.concatenate(jac), None

    starts = np.array([P0, [1.0, 0.3, -5.0], [3.0, 1.9, 1.0]])
    method = LevenbergMarquardt()
    batch = levenberg_marquardt_batch(evaluate, starts, method, max_steps=100, width=2)
    alone = [levenberg_marquardt_batch(evaluate, [s], method, max_steps=100)[0] for s in starts]
    assert [f.status for f in batch] == ["converged", "failed", "converged"]
    assert batch[1].steps == 0 and batch[1].evaluations == 1
    ref, _ = _scipy_optimum()
    for ours, single in zip(batch, alone):
        assert ours.steps == single.steps and ours.status == single.status
        np.testing.assert_array_equal(ours.phi, single.phi)
    np.testing.assert_allclose(batch[2].phi, ref, rtol=1e-4)


def _decay_problem(transform):
    def residuals(theta, args):
        p = transform.to_physical(theta)
        wiggle = 1e-6 * jnp.sin(1e7 * (p[0] + 2.0 * p[1] + 3.0 * p[2]) + 17.0 * T)
        return p[0] * jnp.exp(-p[1] * T) + p[2] - Y + jax.lax.stop_gradient(wiggle)

    return LeastSquaresProblem(residuals, transform)


def test_a_parameter_held_on_its_bound_is_left_out_of_the_offset():
    """The decay rate's box ends below its best value and the fit starts on that bound. Held
    there (left out of the step and the offset), the rate stays, and the other two reach their
    optimum given the bound (scipy's bounded least_squares as the oracle) in fewer steps than
    with every column stepped, where the rate's vanishing column takes huge scaled steps that,
    cut to `max_step`, shrink the others' to nothing."""
    tr = BoxTransform([0.5, 0.05, -1.0], [5.0, 0.5, 1.0], names=("a", "b", "c"))
    problem = _decay_problem(tr)
    start = [1.0, 0.5 - 1e-10, 0.0]  # the rate already on its bound (u = 1 - 2e-10)

    def lm(bound_tol):
        method = LevenbergMarquardt(bound_tol=bound_tol)
        return fit(problem, start, method=method, max_steps=300, throw=False)

    held, all_columns = lm(1e-6), lm(0.0)
    assert held.success and np.asarray(held.on_bound).tolist() == [False, True, False]
    assert int(held.num_steps) < int(all_columns.num_steps)

    ref = scipy.optimize.least_squares(
        _smooth, [1.0, 0.3, 0.0], bounds=(tr.lower, tr.upper), xtol=1e-15, ftol=1e-15,
        gtol=1e-15,
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


def test_bad_settings_name_the_field():
    for kwargs, name in (
        (dict(offset_tol=-1.0), "offset_tol"),
        (dict(stall_steps=0), "stall_steps"),
        (dict(max_step=0.0), "max_step"),
        (dict(bound_tol=0.7), "bound_tol"),
    ):
        try:
            LevenbergMarquardt(**kwargs)
        except ValueError as e:
            assert f"`{name}`" in str(e), e
        else:
            raise AssertionError(f"{kwargs} accepted")
