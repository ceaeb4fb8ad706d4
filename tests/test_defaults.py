"""Issue 16, items 3-5: one `SolveSettings`, defaults that work together (`fit` of a default
objective, no adjoint switch by the caller), no runtime value in a static field, status as
`optimistix.RESULTS`, JAX's own / a bounded cache. Cheap: short runs, one or two parameters."""

import dataclasses

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pytest

from bogie_jax.cost import get_parameter, make_objective, residual_jacobian
from bogie_jax.identify import (
    BoxTransform,
    LeastSquaresProblem,
    SimulatedAnnealing,
    batched_fits,
    clear_runner_cache,
    fit,
    simulated_annealing,
    status_names,
)
from bogie_jax.measure import synthetic_measurement
from bogie_jax.sensitivity import fisher_information
from bogie_jax.simulation import SolveSettings, simulate
from bogie_jax.track import TrackReference, perfect_track


try:
    from blank_data import blank_measurement
    from fixtures_cost import four_sensors, nominal, short_track  # noqa: F401
except ImportError:  # tests/ imported as a package
    from tests.blank_data import blank_measurement
    from tests.fixtures_cost import four_sensors, nominal, short_track  # noqa: F401


jax.config.update("jax_enable_x64", True)

T = jnp.linspace(0.0, 2.0, 41)
DECAY_TR = BoxTransform([0.1, 0.05], [10.0, 5.0], names=("a", "rate"))


def _decay(p):
    return p[0] * jnp.exp(-p[1] * T)


def _decay_residuals(theta, data):
    return _decay(DECAY_TR.to_physical(theta)) - data


def _decay_problem(a=3.0, rate=0.7):
    return LeastSquaresProblem(_decay_residuals, DECAY_TR, _decay(jnp.array([a, rate])))


# ---------------------------------------------------------------------------- SolveSettings
def test_solve_settings_defaults_validation_and_replace():
    s = SolveSettings()
    assert isinstance(s.solver, dfx.Tsit5) and (s.max_steps, s.dt0, s.throw) == (
        100_000,
        1e-3,
        True,
    )
    assert s.adjoint == dfx.RecursiveCheckpointAdjoint(checkpoints=100_000)  # what jax.grad needs
    assert float(s.stepsize_controller.rtol) == 1e-6 and float(s.stepsize_controller.atol) == 1e-9
    obj = SolveSettings.for_objective()
    assert (obj.max_steps, obj.throw) == (16_384, False)
    # a full-checkpoint adjoint follows max_steps; an explicit adjoint stays
    assert obj.replace(max_steps=512).adjoint.checkpoints == 512
    direct = obj.replace(adjoint=dfx.DirectAdjoint()).replace(max_steps=512)
    assert isinstance(direct.adjoint, dfx.DirectAdjoint)
    assert isinstance(obj.forward_mode().adjoint, dfx.ForwardMode)
    assert direct.forward_mode() is direct  # DirectAdjoint already does forward mode
    with pytest.raises(ValueError, match=r"unknown solve options \['rtol'\]"):
        obj.replace(rtol=1e-3)
    with pytest.raises(ValueError, match=r"`max_steps` must be an integer in \[1, "):
        SolveSettings(max_steps=0)
    with pytest.raises(ValueError, match="`dt0` = -0.1 s must be finite and > 0"):
        SolveSettings(dt0=-0.1)
    with pytest.raises(TypeError, match="`solver` must be a diffrax solver"):
        SolveSettings(solver="tsit5")


def test_tolerances_are_traced_and_static_fields_are_compile_time_only():
    a = SolveSettings(stepsize_controller=dfx.PIDController(rtol=1e-6, atol=1e-9))
    b = SolveSettings(stepsize_controller=dfx.PIDController(rtol=1e-8, atol=1e-11))
    static = lambda s: eqx.partition(s, eqx.is_array)[1]
    assert eqx.tree_equal(static(a), static(b))  # one compilation for both tolerances
    assert not eqx.tree_equal(static(a), static(a.replace(max_steps=10)))


def test_simulate_takes_settings_or_single_options(nominal):
    kw = dict(speed=30.0, duration=0.02, sample_rate=200.0)
    settings = SolveSettings(stepsize_controller=dfx.ConstantStepSize(), dt0=1e-3, max_steps=64)
    track = perfect_track()
    y0 = jnp.zeros(20).at[0].set(1e-3)
    one = simulate(nominal, track, y0=y0, settings=settings, **kw)
    two = simulate(
        nominal, track, y0=y0, stepsize_controller=dfx.ConstantStepSize(), max_steps=64, **kw
    )
    np.testing.assert_array_equal(one.q, two.q)
    assert bool(one.successful) and int(one.num_steps) == 20
    with pytest.raises(ValueError, match="unknown solve options"):
        simulate(nominal, track, settings=settings, rtol=1e-3, **kw)
    with pytest.raises(TypeError, match="`settings` must be a SolveSettings"):
        simulate(nominal, track, settings={"max_steps": 3}, **kw)


# -------------------------------------------------------------- defaults work together
@pytest.fixture(scope="module")
def measured(nominal, short_track, four_sensors):
    """0.1 s at 200 Hz, four channels with noise, the truth's primary.kz 10 % above nominal.
    (Noise-free data would leave LM at the solver's accuracy floor, where it ends `singular`.)"""
    truth = eqx.tree_at(lambda p: p.primary.kz, nominal, 1.1 * nominal.primary.kz)
    reference = TrackReference(spectrum="erri-low", seed=0, length=35.0)
    m = synthetic_measurement(
        truth,
        short_track,
        speed=50.0,
        duration=0.1,
        sample_rate=200.0,
        sensors=four_sensors,
        track_reference=reference,
        key=jax.random.PRNGKey(1),
    )
    return m, truth


@pytest.mark.heavy  # an LM fit on the adaptive default solver: about 30 s; README, "Tests"
def test_fit_of_an_objective_made_with_default_arguments_converges(measured, nominal, short_track):
    measurement, truth = measured
    assert measurement.track == TrackReference(spectrum="erri-low", seed=0, length=35.0)
    objective = make_objective(measurement, nominal, short_track, ["primary.kz"])
    adjoint = objective.settings.adjoint  # reverse mode, one checkpoint per step: jax.grad
    assert adjoint == dfx.RecursiveCheckpointAdjoint(checkpoints=objective.settings.max_steps)
    result = fit(objective)  # default LM: switches to forward mode itself
    assert result.success and result.status == optx.RESULTS.successful
    error = abs(float(result.estimates[0]) - float(get_parameter(truth, "primary.kz")))
    assert result.rank == 1 and 0 < float(result.std_errors[0]) < 0.01 * float(
        get_parameter(truth, "primary.kz")
    )
    assert error < 3 * float(result.std_errors[0])  # measured: 1.2 standard errors
    assert isinstance(objective.settings.adjoint, dfx.RecursiveCheckpointAdjoint)  # untouched


@pytest.fixture(scope="module")
def recorded(four_sensors):
    """A measurement's layout and metadata without a simulation: 0.1 s at 200 Hz of zeros on
    the four channels (what `measured` gives, less its data values, which no check here reads;
    simulating them cost a 26 s compile)."""
    return blank_measurement(four_sensors, n=21, rate=200.0, speed=50.0, track_length=35.0)


def test_track_metadata_does_not_reach_the_objective(recorded, nominal, short_track):
    measurement = recorded
    other = dataclasses.replace(
        measurement, track=TrackReference(spectrum="fra-3", seed=4, length=80.0), note="other"
    )
    a = make_objective(measurement, nominal, short_track, ["primary.kz"])
    b = make_objective(other, nominal, short_track, ["primary.kz"])
    static = lambda o: eqx.partition(o, eqx.is_array)[1]
    assert eqx.tree_equal(static(a), static(b))
    traces = []

    @eqx.filter_jit
    def weighted(objective):
        traces.append(1)
        return jnp.sum(objective.residual_model.data * objective.residual_model.sqrt_weights)

    weighted(a), weighted(b)
    assert len(traces) == 1


# --------------------------------------------------------- one Jacobian, one covariance
def test_fit_and_fisher_information_share_jacobian_and_covariance():
    problem = _decay_problem()
    res = fit(problem, [2.0, 1.0])
    r, jac = residual_jacobian(problem, res.theta, problem.args)
    np.testing.assert_allclose(
        jac, jax.jacfwd(lambda t: problem.residuals(t, problem.args))(res.theta), rtol=1e-12
    )
    fim = fisher_information(problem, res.theta)
    # same Jacobian in physical units: the FIM is J_p^T J_p; the fit's covariance is s^2 F^-1
    d = jax.jvp(DECAY_TR.to_physical, (res.theta,), (jnp.ones(2),))[1]
    jp = jac / d
    np.testing.assert_allclose(fim.fim, jp.T @ jp, rtol=1e-10)
    s2 = float(res.noise_variance)
    np.testing.assert_allclose(res.covariance, s2 * np.asarray(fim.covariance), rtol=1e-8, atol=0)
    assert int(fim.uncertainty.rank) == 2 == res.rank


def test_rank_deficient_fit_reports_the_unidentifiable_combination():
    # r depends on a * b only: the direction (ln a, -ln b) is not identifiable
    tr = BoxTransform([0.5, 0.5], [4.0, 4.0], names=("a", "b"))
    x = jnp.linspace(0.0, 1.0, 11)
    y = 2.0 * x + 0.01 * jnp.sin(7 * x)
    problem = LeastSquaresProblem(lambda th, d: jnp.prod(tr.to_physical(th)) * x - d, tr, y)
    res = fit(problem, [1.0, 2.5], throw=False)
    assert res.rank == 1 and res.null_directions.shape == (2, 1)
    assert np.all(np.isinf(res.std_errors)) and np.all(np.isnan(res.correlation))
    assert np.isinf(float(res.uncertainty.condition_number))


# ------------------------------------------------- static fields, RESULTS, caches
def test_results_carry_runtime_values_as_leaves():
    problem = _decay_problem()
    one, two = fit(problem, [2.0, 1.0]), fit(problem, [4.0, 0.3])
    assert jax.tree.structure(one) == jax.tree.structure(two)  # wall_time etc. are leaves
    assert float(one.wall_time) > 0 and one.status == optx.RESULTS.successful
    assert one.status_name == "successful"
    chain = lambda s: simulated_annealing(problem, [2.0, 1.0], key=jax.random.PRNGKey(s),
                                          schedule=SimulatedAnnealing(n_iter=20))  # fmt: skip
    assert jax.tree.structure(chain(0)) == jax.tree.structure(chain(1))
    fims = [fisher_information(problem, jnp.array(t)) for t in ([0.1, 0.2], [1.0, -1.0])]
    assert jax.tree.structure(fims[0]) == jax.tree.structure(fims[1])
    stalled = fit(problem, [2.0, 1.0], max_steps=1, throw=False)
    assert stalled.status == optx.RESULTS.nonlinear_max_steps_reached and not stalled.success
    assert str(status_names(stalled.status)) == "nonlinear_max_steps_reached"


def test_batched_fits_reuses_runners_by_structure_in_a_bounded_cache():
    clear_runner_cache()
    a, b = _decay_problem(), _decay_problem(a=2.0)  # same structure, other data
    assert batched_fits(a, max_steps=10) is batched_fits(b, max_steps=10)
    assert batched_fits(a, max_steps=11) is not batched_fits(a, max_steps=10)
    first = batched_fits(a, max_steps=1)
    for k in range(2, 12):
        batched_fits(a, max_steps=k)
    assert batched_fits(a, max_steps=1) is not first  # evicted: the cache is bounded
    clear_runner_cache()
