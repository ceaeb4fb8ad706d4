"""Identification core on analytic least-squares problems with known answers.

Problems are module-level so that compiled solves are shared between tests (runtime budget).
"""

import types

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import optimistix as optx
import pytest
import scipy.stats

from bogie_jax.identify import (
    BoxTransform,
    LeastSquaresMethod,
    LeastSquaresProblem,
    SimulatedAnnealing,
    anneal_path,
    anneal_start,
    anneal_steps,
    anneal_theta,
    as_method,
    default_chunk,
    fit,
    fit_hybrid,
    fit_multistart,
    local_methods,
    queue_lanes,
    simulated_annealing,
    supports_queue,
    t_quantile,
)


# --- problems ----------------------------------------------------------------------------

T = jnp.linspace(0.0, 5.0, 101)

OSC_TRUE = np.array([2.0, 0.3, 4.0])  # amplitude [m], damping ratio [-], natural freq. [rad/s]
OSC_TR = BoxTransform([0.5, 0.05, 2.0], [5.0, 0.9, 8.0], names=("A", "zeta", "omega"))


def _oscillator(p):
    a, zeta, omega = p[0], p[1], p[2]
    return a * jnp.exp(-zeta * omega * T) * jnp.cos(omega * jnp.sqrt(1.0 - zeta**2) * T)


OSC = LeastSquaresProblem(
    lambda th, data: _oscillator(OSC_TR.to_physical(th)) - data, OSC_TR, _oscillator(OSC_TRUE)
)

DECAY_TRUE = np.array([3.0, 0.7, 0.5])  # amplitude, rate [1/s], offset


def _decay(p):
    return p[0] * jnp.exp(-p[1] * T) + p[2]


DECAY_TR = BoxTransform([0.1, 0.05, -2.0], [10.0, 5.0, 2.0])
DECAY = LeastSquaresProblem(
    lambda th, data: _decay(DECAY_TR.to_physical(th)) - data, DECAY_TR, _decay(DECAY_TRUE)
)

ROSEN_TR = BoxTransform([-2.0, -2.0], [3.0, 3.0])
ROSEN = LeastSquaresProblem(
    lambda th, args: (lambda p: jnp.stack([1.0 - p[0], 10.0 * (p[1] - p[0] ** 2)]))(
        ROSEN_TR.to_physical(th)
    ),
    ROSEN_TR,
)

# Two minima in x: global at (1, 0.5) with cost 0, local near (-0.98, 0.5) with cost ~0.08.
# Residuals are NaN for x < -1.5 (a "failed simulation" region).
TWO_TR = BoxTransform([-2.0, -1.0], [2.0, 2.0], names=("x", "y"))


def _two_minima(th, args):
    x, y = TWO_TR.to_physical(th)
    r = jnp.stack([x**2 - 1.0, 0.2 * (x - 1.0), y - 0.5])
    return jnp.where(x < -1.5, jnp.nan, r)


TWO = LeastSquaresProblem(_two_minima, TWO_TR)

# the optimum to rounding (no relative-offset stop): the tests that compare ends and statistics
# with exact references or between batch layouts on these few-residual problems; the LM's
# statistical stop is tested in test_levenberg_marquardt.py
EXACT_LM = local_methods(offset_tol=0.0, stall_offset=0.0)["lm"]


def _rel_err(estimate, truth):
    return np.max(np.abs(np.asarray(estimate) / truth - 1.0))


# --- local fits --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "method", ["lm", "gauss-newton", "dogleg", "bfgs", "nelder-mead", "pattern"]
)
def test_local_methods_recover_truth(method):
    res = fit(DECAY, [2.5, 0.9, 0.3], method=method, max_steps=4000)
    # noise-free data: truth to 1e-6 relative (house rule for synthetic identification)
    assert _rel_err(res.estimates, DECAY_TRUE) < 1e-6, res.estimates
    assert res.success and int(res.num_fn_evals) > 0 and res.wall_time > 0
    assert not np.any(res.on_bound)


def test_oscillator_and_rosenbrock():
    osc = fit(OSC, [1.8, 0.35, 3.8])
    assert _rel_err(osc.estimates, OSC_TRUE) < 1e-6
    assert osc.names == ("A", "zeta", "omega")
    assert osc.std_errors.shape == (3,) and osc.correlation.shape == (3, 3)
    ros = fit(ROSEN, [-1.2, 1.0], max_steps=1000)
    assert _rel_err(ros.estimates, np.array([1.0, 1.0])) < 1e-6


def test_ci_matches_numpy_lstsq():
    """Linear model: estimates, standard errors and CIs against numpy lstsq + scipy t."""
    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 1.0, 40)
    a = np.stack([np.ones_like(t), t, t**2], axis=1)
    y = a @ np.array([1.0, -2.0, 0.5]) + 0.05 * rng.standard_normal(t.size)
    tr = BoxTransform([-10.0, -10.0, -10.0], [10.0, 10.0, 10.0])
    a_j, y_j = jnp.asarray(a), jnp.asarray(y)
    prob = LeastSquaresProblem(lambda th, args: a_j @ tr.to_physical(th) - y_j, tr)
    res = fit(prob, [0.0, 0.0, 0.0], method=EXACT_LM)
    coef, rss, *_ = np.linalg.lstsq(a, y, rcond=None)
    dof = t.size - 3
    cov = rss[0] / dof * np.linalg.inv(a.T @ a)
    se = np.sqrt(np.diag(cov))
    np.testing.assert_allclose(res.estimates, coef, rtol=1e-8, atol=1e-10)  # solver tolerance
    np.testing.assert_allclose(res.covariance, cov, rtol=1e-6)  # exact chain rule at optimum
    np.testing.assert_allclose(res.correlation, cov / np.outer(se, se), rtol=1e-6, atol=1e-12)
    half = scipy.stats.t.ppf(0.975, dof) * se
    np.testing.assert_allclose(res.ci95, np.stack([coef - half, coef + half], 1), rtol=1e-6)
    assert res.dof == dof


def test_t_quantile():
    dofs = np.array([1.0, 3.0, 10.0, 200.0])
    got = [t_quantile(0.975, d) for d in dofs]  # the one t quantile (monitor's verdicts too)
    np.testing.assert_allclose(got, scipy.stats.t.ppf(0.975, dofs), rtol=1e-10)


def test_bad_input_errors():
    with pytest.raises(ValueError, match="strictly inside the bounds"):
        fit(DECAY, [20.0, 0.9, 0.3])
    with pytest.raises(ValueError, match="unknown `method`"):
        fit(DECAY, method="newton-raphson")
    empty = LeastSquaresProblem(lambda th, args: th, BoxTransform(np.zeros(0), np.ones(0)))
    with pytest.raises(ValueError, match="empty parameter selection"):
        fit(empty)
    with pytest.raises(ValueError, match="empty parameter selection"):
        fit_multistart(empty, key=jr.PRNGKey(0))
    with pytest.raises(TypeError, match="`method`"):
        fit(DECAY, method=3)


def test_bound_flag():
    # truth outside the box: the estimate is pinned to (never beyond) the upper bound of rate
    tr = BoxTransform([0.1, 0.05, -2.0], [10.0, 0.5, 2.0])
    prob = LeastSquaresProblem(
        lambda th, data: _decay(tr.to_physical(th)) - data, tr, _decay(DECAY_TRUE)
    )
    res = fit(prob, [2.5, 0.3, 0.3], throw=False, bound_tol=1e-3)
    assert np.all(res.estimates <= tr.upper) and np.all(res.estimates >= tr.lower)
    assert bool(res.on_bound[1])


# --- multistart --------------------------------------------------------------------------


def test_multistart_two_minima_clusters_and_failures():
    # the lock-step batch in chunks (the queue, the default, is compared with it below)
    res = fit_multistart(
        TWO, key=jr.PRNGKey(1), n_starts=24, chunk_size=8, lanes=None, method=EXACT_LM
    )
    starts_x = res.starts[:, 0]
    # starts in the NaN region fail, are reported, and do not kill the batch
    assert np.any(starts_x < -1.5) and np.all(res.failed[starts_x < -1.5])
    assert np.sum(~res.failed) >= 12
    assert len(res.records()) == 24 and res.records()[0]["status"]
    # both minima are found, global first, with counts adding up to the successful starts
    assert len(res.clusters) == 2
    np.testing.assert_allclose(res.clusters[0].estimates, [1.0, 0.5], rtol=1e-6)
    assert res.clusters[1].estimates[0] < -0.9 and res.clusters[1].cost > 0.05
    assert sum(c.count for c in res.clusters) == np.sum(~res.failed)
    np.testing.assert_allclose(res.best.estimates, [1.0, 0.5], rtol=1e-6)
    # the same batch on one device (conftest exposes 4 host devices): same answers
    single = fit_multistart(
        TWO,
        key=jr.PRNGKey(1),
        n_starts=24,
        chunk_size=8,
        lanes=None,
        devices=jax.devices()[:1],
        method=EXACT_LM,
    )
    np.testing.assert_array_equal(single.failed, res.failed)
    np.testing.assert_allclose(
        single.ends[~res.failed], res.ends[~res.failed], rtol=1e-12, atol=1e-14
    )


def test_multistart_equals_loop_of_fits():
    res = fit_multistart(OSC, key=jr.PRNGKey(2), n_starts=6, design="sobol", throw=False)
    for i in range(6):
        single = fit(OSC, res.starts[i], throw=False)
        np.testing.assert_allclose(res.ends[i], single.estimates, rtol=1e-9, atol=1e-12)
        assert int(res.num_steps[i]) == int(single.num_steps)
    assert np.any(_rel_err(res.best.estimates, OSC_TRUE) < 1e-6)


@pytest.mark.parametrize("max_steps", [5, 100])
def test_queued_multistart_equals_lock_step_batch(max_steps):
    """The queue (lanes refilled as fits end) takes the steps every start takes at once: same
    ends, step counts, statuses and costs as every start at once, including starts that fail
    (NaN region) or run out of steps."""
    kw = dict(key=jr.PRNGKey(1), n_starts=24, max_steps=max_steps, throw=False, method=EXACT_LM)
    queued = fit_multistart(TWO, lanes=3, **kw)
    lock_step = fit_multistart(TWO, lanes=None, **kw)
    np.testing.assert_array_equal(queued.status, lock_step.status)
    np.testing.assert_array_equal(queued.num_steps, lock_step.num_steps)
    np.testing.assert_array_equal(queued.failed, lock_step.failed)
    ok = ~queued.failed
    np.testing.assert_allclose(queued.ends[ok], lock_step.ends[ok], rtol=1e-12, atol=1e-14)
    finite = np.isfinite(lock_step.costs)
    np.testing.assert_array_equal(np.isfinite(queued.costs), finite)
    np.testing.assert_allclose(
        queued.costs[finite], lock_step.costs[finite], rtol=1e-10, atol=1e-15
    )
    names = set(queued.status)  # optimistix.RESULTS member names
    assert "nonfinite" in names and "successful" in names
    if max_steps == 5:
        assert "nonlinear_max_steps_reached" in names


def test_only_the_levenberg_marquardt_runs_as_a_queue():
    """The Levenberg-Marquardt runs on the host over a compiled evaluation, so its fits queue;
    the compiled methods (optimistix's, an optimistix LM passed as a solver too) run lock-step."""
    assert supports_queue(as_method("lm"))
    assert not any(supports_queue(as_method(m)) for m in ("gauss-newton", "dogleg", "bfgs"))
    assert not supports_queue(LeastSquaresMethod(optx.LevenbergMarquardt(1e-8, 1e-8)))


def test_auto_lanes_one_fit_per_cpu_device_many_per_accelerator():
    """`lanes="auto"`: one fit in flight per CPU device (stepped without `vmap`), about 32
    residual tangents per step, ceil(32 / (n + 1)) fits, on an accelerator."""
    cpu = jax.devices("cpu")
    assert queue_lanes("auto", 3, cpu) == 1 and queue_lanes("auto", 10, cpu[:1]) == 1
    gpu = [types.SimpleNamespace(platform="gpu")]
    assert queue_lanes("auto", 3, gpu) == 8 and queue_lanes("auto", 10, gpu) == 3
    assert queue_lanes("auto", 40, gpu) == 1
    assert queue_lanes("auto", 3, [*cpu, *gpu]) == 8  # any accelerator among the devices
    assert queue_lanes(5, 3) == 5 and queue_lanes(None, 3) is None
    with pytest.raises(ValueError, match="`lanes` must be"):
        queue_lanes(0, 3)


def test_default_chunk_saves_every_two_fits_per_cpu_device_and_fills_an_accelerator():
    """A chunk holds two fits per CPU device (each steps one at a time) and every lane of an
    accelerator (its parallelism), at least two per device."""
    cpu = jax.devices("cpu")
    gpu = [types.SimpleNamespace(platform="gpu")]
    assert default_chunk("auto", 3, cpu) == 2 * len(cpu)
    assert default_chunk("auto", 3, gpu) == 8 and default_chunk("auto", 10, gpu) == 3
    assert default_chunk("auto", 40, gpu * 2) == 4  # one lane each, still two per device
    assert default_chunk(5, 3, cpu[:1]) == 5 and default_chunk(None, 3, gpu) == 8


# --- annealing and hybrid ----------------------------------------------------------------


def test_annealing_and_hybrid_reach_global_minimum():
    schedule = SimulatedAnnealing(n_iter=3000)
    sa = simulated_annealing(TWO, [-0.9, 0.0], key=jr.PRNGKey(3), schedule=schedule)
    # annealing alone: inside the global basin, not to solver precision
    assert abs(float(sa.estimates[0]) - 1.0) < 0.05 and int(sa.num_fn_evals) == 3001
    hyb = fit_hybrid(TWO, key=jr.PRNGKey(4), n_chains=4, schedule=schedule)
    np.testing.assert_allclose(hyb.best.estimates, [1.0, 0.5], rtol=1e-6)
    assert int(hyb.best.num_fn_evals) > 4 * 3001


class _BoxAndLog(eqx.Module):
    """Two parameters in the box [0.5, 1.5], a third on log scale (`upper` = inf), as a
    `ParameterSelection` mixes them."""

    lower: jax.Array = eqx.field(default_factory=lambda: jnp.array([0.5, 0.5, 0.0]))
    upper: jax.Array = eqx.field(default_factory=lambda: jnp.array([1.5, 1.5, jnp.inf]))

    def to_physical(self, theta):
        box = 0.5 + jax.nn.sigmoid(theta)
        return jnp.where(jnp.arange(3) < 2, box, jnp.exp(theta))

    def to_theta(self, p):
        u = jnp.clip(p - 0.5, 1e-300, 1.0)
        return jnp.where(jnp.arange(3) < 2, jnp.log(u) - jnp.log1p(-u), jnp.log(p))


MIXED_TR = _BoxAndLog()
MIXED_TRUE = np.array([1.1, 0.9, 1.2])
# Correlated, unequally scaled linear residuals in the physical values: one minimum, at the truth.
MIXED_A = np.array([[1.0, 0.2, 0.0], [0.0, 1.0, 0.5], [0.3, 0.0, 1.0]]) * [[1e3], [3e2], [3e3]]
MIXED = LeastSquaresProblem(
    lambda th, args: MIXED_A @ (MIXED_TR.to_physical(th) - MIXED_TRUE), MIXED_TR
)


def test_annealing_converges_in_the_box_instead_of_drifting_to_the_bounds():
    """A hot chain must not wander onto the flat ends of the logistic map (where, once cold, it
    could not come back): long chains end at the single minimum, known exactly."""
    schedule = SimulatedAnnealing(n_iter=20000, step_size=0.5, min_step=1e-6)
    chains = jax.jit(jax.vmap(lambda k: anneal_theta(MIXED, jnp.zeros(3), k, schedule)[0]))(
        jr.split(jr.PRNGKey(11), 4)
    )
    found = np.asarray(jax.vmap(MIXED_TR.to_physical)(chains))
    assert np.all(np.isfinite(np.asarray(chains)))
    np.testing.assert_allclose(found, np.broadcast_to(MIXED_TRUE, found.shape), rtol=1e-3)


def test_annealing_in_pieces_is_the_chain_in_one_piece():
    """A long chain run (and saved) piece by piece takes the same proposals as in one piece (up
    to rounding: the pieces and the whole compile separately, and a proposal maps through the
    physical values and back)."""
    schedule = SimulatedAnnealing(n_iter=300)
    theta0, key = jnp.array([-0.5, 0.0]), jr.PRNGKey(5)
    best, f_best, rate, _, path = eqx.filter_jit(anneal_path)(TWO, theta0, key, schedule)
    step = eqx.filter_jit(lambda st: anneal_steps(TWO, st, key, schedule, 100))
    state, paths = anneal_start(TWO, theta0, schedule), []
    for _ in range(3):
        state, p = step(state)
        paths.append(p)
    np.testing.assert_allclose(np.concatenate(paths), path, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(state.best, best, rtol=1e-10)
    np.testing.assert_allclose(float(state.best_cost), float(f_best), rtol=1e-9)
    assert int(state.k) == 300 and float(state.accepted) / 300 == float(rate)
    with pytest.raises(ValueError, match="length"):
        anneal_steps(TWO, state, key, schedule, 301)


def test_annealing_path_is_the_running_best():
    schedule = SimulatedAnnealing(n_iter=300)
    best, f_best, _, nfev, path = eqx.filter_jit(anneal_path)(
        TWO, jnp.array([-0.5, 0.0]), jr.PRNGKey(5), schedule
    )
    costs = np.asarray(jax.vmap(TWO.cost)(path))
    assert path.shape == (300, 2) and int(nfev) == 301
    np.testing.assert_array_equal(path[-1], best)
    np.testing.assert_allclose(costs[-1], f_best)
    assert np.all(np.diff(costs) <= 0.0) and costs[-1] < costs[0]
    # keeping the path does not change the chain: `anneal_theta` ends at the same point
    np.testing.assert_array_equal(
        anneal_theta(TWO, jnp.array([-0.5, 0.0]), jr.PRNGKey(5), schedule)[0], best
    )


# --- noise and the Objective adapter -----------------------------------------------------


def test_noisy_truth_inside_ci_in_most_trials():
    rng = np.random.default_rng(7)
    inside = []
    for _ in range(5):
        clean = _decay(DECAY_TRUE)
        noisy = clean + 0.02 * np.abs(clean).mean() * rng.standard_normal(clean.shape)
        # max_steps as in test_local_methods_recover_truth: its compiled fit (the LM stops at
        # convergence, well before either limit; a fit that did not converge would raise)
        noisy_problem = eqx.tree_at(lambda p: p.args, DECAY, jnp.asarray(noisy))
        res = fit(noisy_problem, [2.5, 0.9, 0.3], max_steps=4000)
        assert int(res.num_steps) < 256
        inside.append((res.ci95[:, 0] <= DECAY_TRUE) & (DECAY_TRUE <= res.ci95[:, 1]))
    # 15 nominal-95% intervals; P(fewer than 12 inside) < 0.5% for a calibrated interval
    assert np.sum(inside) >= 12, np.array(inside)


class _FakeObjective(eqx.Module):
    """Stands in for bogie_jax.cost.Objective: `residuals(theta, args=None)` + `selection`."""

    selection: BoxTransform
    data: jax.Array

    def residuals(self, theta, args=None):
        return _decay(self.selection.to_physical(theta)) - self.data


def test_objective_adapter():
    res = fit(_FakeObjective(DECAY_TR, _decay(DECAY_TRUE)), [2.5, 0.9, 0.3])
    assert _rel_err(res.estimates, DECAY_TRUE) < 1e-6
