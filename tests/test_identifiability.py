"""Fisher information, collinearity indices and profile likelihood (bogie_jax.sensitivity).

Analytic checks on a linear least-squares problem r = (X p - y) / sigma, then one short real
objective (0.5 s at 50 m/s, three suspension parameters).
"""

import math

import diffrax as dfx
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

import bogie_jax as bj
from bogie_jax.cost import synthetic_objective
from bogie_jax.identify import BoxTransform, LeastSquaresProblem
from bogie_jax.measure import default_sensor_layout
from bogie_jax.sensitivity import (
    PROFILE_THRESHOLD,
    collinearity_indices,
    fisher_from_jacobian,
    fisher_information,
    profile_interval,
    profile_likelihood,
)
from bogie_jax.track import ERRIB176Spectrum, synthesise_track


SIGMA = 0.3
TRUE = np.array([2.0, 3.0, 1.5])
NAMES = ("a", "b", "c")


def linear_problem(x, y, lower, upper, names=NAMES):
    transform = BoxTransform(lower, upper, names=names, nominal=np.full(x.shape[1], 1.0))
    xj, yj = jnp.asarray(x), jnp.asarray(y)
    residuals = lambda theta, args: (xj @ transform.to_physical(theta) - yj) / SIGMA
    return LeastSquaresProblem(residuals, transform)


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(0)
    x = np.column_stack([np.ones(40), np.linspace(0, 1, 40), rng.normal(size=40)])
    y = x @ TRUE + SIGMA * rng.normal(size=40)
    p_hat = np.linalg.lstsq(x, y, rcond=None)[0]
    return x, y, p_hat


def test_fim_covariance_correlation_equal_numpy(data):
    x, y, p_hat = data
    problem = linear_problem(x, y, [-10.0] * 3, [10.0] * 3)
    fim = fisher_information(problem, physical=p_hat)
    ref_fim = x.T @ x / SIGMA**2
    ref_cov = np.linalg.inv(ref_fim)
    ref_std = np.sqrt(np.diag(ref_cov))
    np.testing.assert_allclose(fim.values, p_hat, rtol=1e-12)
    np.testing.assert_allclose(fim.fim, ref_fim, rtol=1e-9)
    np.testing.assert_allclose(fim.covariance, ref_cov, rtol=1e-8)
    np.testing.assert_allclose(fim.std_errors, ref_std, rtol=1e-8)
    np.testing.assert_allclose(
        fim.correlation, ref_cov / np.outer(ref_std, ref_std), rtol=1e-8, atol=1e-12
    )
    rel = np.diag(p_hat) @ ref_fim @ np.diag(p_hat)
    np.testing.assert_allclose(fim.fim_relative, rel, rtol=1e-9)
    np.testing.assert_allclose(fim.eigenvalues, np.linalg.eigvalsh(rel), rtol=1e-9)
    # eigenvectors: F_rel v = lambda v
    np.testing.assert_allclose(
        rel @ fim.eigenvectors, fim.eigenvectors * fim.eigenvalues, rtol=1e-8, atol=1e-8
    )
    assert np.isfinite(fim.condition_number)
    assert fim.names == NAMES


def test_collinearity_index_matches_brun_definition(data):
    x = data[0]
    ci = collinearity_indices(x, NAMES, max_size=3)
    assert ci.subsets == (("a", "b"), ("a", "c"), ("b", "c"), ("a", "b", "c"))
    s = x / np.linalg.norm(x, axis=0)
    expect = [
        1 / math.sqrt(np.linalg.eigvalsh(s[:, list(k)].T @ s[:, list(k)])[0])
        for k in ((0, 1), (0, 2), (1, 2), (0, 1, 2))
    ]
    np.testing.assert_allclose(ci.index, expect, rtol=1e-10)
    # column scaling cancels
    np.testing.assert_allclose(
        collinearity_indices(x * [1e3, 1e-3, 7.0], NAMES).index, expect, rtol=1e-8
    )


def test_duplicated_columns_are_collinear_and_named(data):
    x = data[0]
    xd = np.column_stack([x[:, 0], x[:, 1], 2.0 * x[:, 1]])  # c duplicates b (scaled)
    fim = fisher_from_jacobian(xd / SIGMA, np.array([1.0, 1.0, 0.5]), NAMES)
    gamma = dict(zip(fim.collinearity.subsets, np.asarray(fim.collinearity.index)))
    assert gamma[("b", "c")] > 1e6  # infinite in exact arithmetic
    assert np.isfinite(gamma[("a", "b")]) and gamma[("a", "b")] < 10
    assert fim.collinearity.worst(2, 1)[0][0] == ("b", "c")
    assert fim.eigenvalues[0] < 1e-9 * fim.eigenvalues[-1]
    assert math.isinf(fim.condition_number)
    worst = fim.inseparable[0]
    assert set(worst.dominant) == {"b", "c"}
    assert math.isinf(worst.relative_std)
    assert "ln b" in worst.description and "ln c" in worst.description
    assert any("b" in line and "c" in line for line in fim.summary())
    assert (
        np.isinf(fim.std_errors[1])
        and np.isinf(fim.std_errors[2])
        and np.isfinite(fim.std_errors[0])
    )


def test_profile_interval_of_linear_gaussian_problem_is_analytic(data):
    x, y, p_hat = data
    lower, upper = p_hat - 1.0, p_hat + 1.0
    problem = linear_problem(x, y, lower - 1.0, upper + 1.0)
    prof = profile_likelihood(problem, p_hat, n_points=21, lower=lower, upper=upper)
    std = np.sqrt(np.diag(np.linalg.inv(x.T @ x))) * SIGMA
    half = math.sqrt(2 * PROFILE_THRESHOLD) * std  # = 1.96 sigma
    np.testing.assert_allclose(half / std, 1.959964, rtol=1e-6)
    assert prof.status == ("identifiable",) * 3
    assert not np.any(prof.failed)
    np.testing.assert_allclose(prof.interval[:, 0], p_hat - half, rtol=0, atol=1e-6)
    np.testing.assert_allclose(prof.interval[:, 1], p_hat + half, rtol=0, atol=1e-6)
    # profile = analytic quadratic (v - p_hat)^2 / (2 var), the others re-fitted
    dq = (prof.values - p_hat[:, None]) ** 2 / (2 * std[:, None] ** 2)
    np.testing.assert_allclose(prof.delta_cost, dq, rtol=1e-6, atol=1e-7)


def test_flat_and_one_sided_profiles_are_flagged():
    v = np.linspace(0.0, 1.0, 11)
    assert profile_interval(v, 0.1 * v)[2] == "flat"
    lo, hi, status = profile_interval(v, 10 * v**2)
    assert status == "one-sided" and math.isnan(lo) and 0 < hi < 1
    assert profile_interval(v, 10 + v)[2] == "unresolved"  # no point below the threshold
    lo, hi, status = profile_interval(v, 10 * (v - 0.5) ** 2)
    assert status == "identifiable"
    np.testing.assert_allclose(
        [lo, hi], 0.5 + np.array([-1, 1]) * math.sqrt(PROFILE_THRESHOLD / 10), atol=1e-12
    )


def test_profile_bad_input_raises_before_fitting(data):
    x, y, p_hat = data
    problem = linear_problem(x, y, [-10.0] * 3, [10.0] * 3)
    with pytest.raises(ValueError, match="unknown parameter `d`"):
        profile_likelihood(problem, p_hat, params=("d",))
    with pytest.raises(ValueError, match="lower < upper"):
        profile_likelihood(problem, p_hat, lower=[1.0, -1, -1], upper=[1.0, 1, 1])
    with pytest.raises(ValueError, match="n_points"):
        profile_likelihood(problem, p_hat, n_points=2)


# --- a short real objective ------------------------------------------------------------------


@pytest.fixture(scope="module")
def real_objective():
    params = bj.manchester_benchmark()
    track = synthesise_track(
        ERRIB176Spectrum.low(), key=jr.PRNGKey(0), length=60.0, fade_length=2.0, start=-5.0
    )
    sensors = tuple(
        s
        for s in default_sensor_layout(params)
        if s.name in ("frame_1L_y", "frame_1L_z", "frame_yaw_rate")
    )
    objective, _ = synthetic_objective(
        params,
        track,
        ("primary.kz", "primary.ky", "yaw_dampers.c"),
        speed=50.0,
        duration=0.5,
        sample_rate=100.0,
        sensors=sensors,
        key=None,
        bounds="spec",
        stepsize_controller=dfx.ConstantStepSize(),
        dt0=5e-4,
        max_steps=2048,
    )
    return objective


@pytest.mark.heavy  # 1.5 min of compile for a smoke check; README, "Tests"
def test_real_objective_fim_is_finite(real_objective):
    fim = fisher_information(real_objective)
    assert fim.names == ("primary.kz", "primary.ky", "yaw_dampers.c")
    assert np.all(np.isfinite(fim.eigenvalues)) and np.all(fim.eigenvalues >= 0)
    assert fim.eigenvalues[-1] > 0
    assert np.all(np.isfinite(np.asarray(fim.collinearity.index)))
    np.testing.assert_allclose(fim.values, real_objective.selection.nominal, rtol=1e-12)
    assert fim.units == real_objective.selection.units


# --- figures (bogie_jax.plot), on analytic results -------------------------------------------


def test_plots_return_axes_and_figures(data, getkey):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bogie_jax import plot as plots
    from bogie_jax.sensitivity import screening_grid, screening_sweeps, sobol_analysis

    x, y, p_hat = data
    problem = linear_problem(x, y, p_hat - 2.0, p_hat + 2.0)
    fn = lambda p: problem.cost(problem.transform.to_theta(p))
    lo, hi = p_hat - 1.0, p_hat + 1.0
    sobol = sobol_analysis(fn, lo, hi, n=16, key=getkey(), names=NAMES, n_resamples=20)
    assert plots.plot_sobol_indices(sobol).get_xticklabels()[0].get_text() == "a"
    grid = screening_grid(fn, p_hat, lo, hi, params=("a", "b"), n_points=4, names=NAMES)
    fig = plots.plot_cost_surface(grid)
    assert len(fig.axes) == 3  # contour, colour bar, surface
    sweeps = screening_sweeps(fn, p_hat, lo, hi, n_points=3, params=("c", "a"), names=NAMES)
    ax = plots.plot_sweeps(sweeps, all_names=NAMES)
    np.testing.assert_allclose(ax.lines[0].get_xdata(), np.asarray(sweeps.values[0]) / p_hat[2])
    prof = profile_likelihood(problem, p_hat, params=("b",), n_points=5, lower=lo, upper=hi)
    assert prof.indices == (1,)
    assert len(plots.plot_profiles(prof).axes) == 1
    _, ax = plt.subplots()
    assert plots.plot_fim_eigenvalues(fisher_information(problem, physical=p_hat), ax=ax) is ax
    plt.close("all")
