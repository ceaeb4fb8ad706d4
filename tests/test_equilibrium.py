"""Static equilibrium (`bogie_jax.model.static_equilibrium`): the rest state on a perfect track.

Checked against an independent solve of the numpy twin's accelerations (`scipy.optimize.root`
on `tests/reference/bogie_twin.py`), for the symmetric named sets (zeros) and an asymmetric
bogie (left anti-yaw damper at 0, primary 1L vertical spring +30 %, secondary left lateral
damper at 50 %); its derivative (implicit function theorem, forward and reverse mode) against
central differences; its failure results (step limit, non-finite parameters) per bogie under
`vmap`; a simulation started there (the default initial state of `simulate`) stays there; and
the test that lets an objective skip the solve (`rests_at_zero`, `fixed_rest_state`) against
the twin's rest states.
"""

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pytest
import scipy.optimize

import bogie_jax as bj
from bogie_jax.model import (
    equilibrium_residual,
    rests_at_zero,
    static_equilibrium,
    static_equilibrium_solve,
)
from bogie_jax.params import PARAMETER_SETS, set_parameters
from bogie_jax.simulation import simulate
from bogie_jax.track import perfect_track


try:
    from reference.bogie_twin import BogieTwin
except ImportError:  # tests/ imported as a package
    from tests.reference.bogie_twin import BogieTwin


def _asymmetric(params):
    return set_parameters(
        params,
        {
            "yaw_dampers.left.c": 0.0,
            "primary.1L.kz": 1.3 * float(params.primary.kz[0]),
            "secondary.left.cy": 0.5 * float(params.secondary.cy[0]),
        },
    )


@pytest.fixture(scope="module")
def solve():
    return eqx.filter_jit(static_equilibrium_solve)


@pytest.fixture(scope="module")
def residual():
    return eqx.filter_jit(equilibrium_residual)


@pytest.fixture(scope="module")
def asymmetric():
    return _asymmetric(bj.manchester_benchmark())


@pytest.fixture(scope="module")
def q0(solve, asymmetric):
    return np.asarray(solve(asymmetric).value)


def _twin_equilibrium(params):
    """Independent solve: scipy's hybrid Powell method on the twin's accelerations at zero
    velocity on a perfect track."""
    twin = BogieTwin(params, 50.0)
    sol = scipy.optimize.root(
        lambda q: twin.qddot(0.0, q, np.zeros(10)), np.zeros(10), method="hybr", tol=1e-14
    )
    assert sol.success, sol.message
    return sol.x, twin


@pytest.mark.parametrize("name", sorted(PARAMETER_SETS))
def test_symmetric_sets_rest_at_zero(solve, name):
    """A symmetric bogie's springs carry their design loads at q = 0: q0 = 0 to 1e-12."""
    sol = solve(PARAMETER_SETS[name]())
    assert np.abs(np.asarray(sol.value)).max() <= 1e-12


def test_asymmetric_rest_state_matches_the_twin(asymmetric, q0, residual):
    """The asymmetric bogie settles with heave, roll and pitch; the JAX residual is below
    1e-10 (m/s^2, rad/s^2) and q0 agrees with scipy's root of the twin's accelerations to
    1e-8 of its largest entry; the wheel loads shift (twin's normal loads at q0)."""
    res = np.abs(np.asarray(residual(asymmetric, jnp.asarray(q0)))).max()
    assert res < 1e-10, res
    q_twin, twin = _twin_equilibrium(asymmetric)
    error = np.abs(q0 - q_twin).max() / np.abs(q_twin).max()
    print(f"equilibrium residual {res:.2e}, JAX vs twin {error:.2e} relative; q0 = {q0}")
    assert error <= 1e-8, (q0, q_twin)
    assert np.abs(twin.qddot(0.0, q0, np.zeros(10))).max() < 1e-8
    assert np.all(np.abs(q0[2:5]) > 1e-5), q0  # heave [m], roll and pitch [rad]
    loads = [c["normal_load"] for c in twin.creep_details(0.0, np.concatenate([q0, np.zeros(10)]))]
    nominal = [
        c["normal_load"]
        for c in BogieTwin(bj.manchester_benchmark(), 50.0).creep_details(0.0, np.zeros(20))
    ]
    assert np.abs(np.asarray(loads) / nominal - 1).max() > 1e-2, loads


def test_rest_state_jacobian_is_non_singular(residual, asymmetric, q0):
    """All 10 coordinates are held at rest: da/dq at q0 (central differences of the compiled
    residual, step 1e-7 m or rad) is well conditioned (the wheelsets are held by the primary
    springs, the gravitational stiffness and creep)."""
    h = 1e-7
    cols = [
        (
            np.asarray(residual(asymmetric, jnp.asarray(q0 + h * e)))
            - np.asarray(residual(asymmetric, jnp.asarray(q0 - h * e)))
        )
        / (2 * h)
        for e in np.eye(10)
    ]
    sv = np.linalg.svd(np.stack(cols, axis=1), compute_uv=False)
    print("singular values of da/dq at q0:", sv)
    assert sv.min() > 1e-4 * sv.max(), sv


def test_rest_state_derivative_matches_central_differences(solve, asymmetric):
    """dq0/dk for k = primary 1L vertical stiffness by the implicit function theorem, forward
    (jvp) and reverse (vjp) mode through `static_equilibrium`, against central differences
    (step 1e-4 k): 1e-6 relative to the largest entry."""
    k = float(asymmetric.primary.kz[0])

    @eqx.filter_jit
    def derivatives(params, kz):
        def q_of(kz_):
            return static_equilibrium(set_parameters(params, {"primary.1L.kz": kz_}))

        return jax.jvp(q_of, (kz,), (jnp.ones_like(kz),))[1], jax.jacrev(q_of)(kz)

    fwd, rev = derivatives(asymmetric, jnp.asarray(k))
    h = 1e-4 * k
    q = [solve(set_parameters(asymmetric, {"primary.1L.kz": kz})).value for kz in (k + h, k - h)]
    fd = (np.asarray(q[0]) - np.asarray(q[1])) / (2 * h)
    scale = np.abs(fd).max()
    assert scale > 0
    np.testing.assert_allclose(np.asarray(fwd), fd, rtol=0, atol=1e-6 * scale)
    np.testing.assert_allclose(np.asarray(rev), fd, rtol=0, atol=1e-6 * scale)


def test_failures_are_reported(solve, asymmetric):
    """Under `vmap` with `throw=False` (as in the fits' batches), each bogie gets its own
    result: the asymmetric one with `max_steps=2` (it needs 4) ends `max_steps_reached` after
    2 steps, a NaN spring stiffness `nonlinear_divergence` after 1, the symmetric one
    `successful` after 1 (q = 0 is its root); with `throw=True` the NaN bogie raises."""
    nominal = bj.manchester_benchmark()
    broken = set_parameters(nominal, {"primary.1L.kz": float("nan")})
    batch = jax.tree.map(lambda *x: jnp.stack(x), asymmetric, broken, nominal)
    sol = eqx.filter_jit(jax.vmap(lambda p: static_equilibrium_solve(p, max_steps=2, throw=False)))(
        batch
    )
    expected = (
        optx.RESULTS.max_steps_reached,
        optx.RESULTS.nonlinear_divergence,
        optx.RESULTS.successful,
    )
    for i, result in enumerate(expected):
        assert bool(np.asarray(sol.result == result)[i]), (i, result)
    np.testing.assert_array_equal(np.asarray(sol.stats["num_steps"]), [2, 1, 1])
    assert np.abs(np.asarray(sol.value[2])).max() <= 1e-12
    with pytest.raises(Exception, match="diverged"):
        jax.block_until_ready(solve(broken).value)


def test_simulation_from_rest_stays_at_rest(asymmetric, q0):
    """`simulate`'s default initial state is (q0, 0): 1 s on a perfect track at 50 m/s stays
    within 1e-9 of q0 (m, rad)."""
    run = jax.jit(
        lambda p: (
            simulate(
                p,
                perfect_track(),
                speed=50.0,
                duration=1.0,
                sample_rate=100.0,
                stepsize_controller=dfx.PIDController(rtol=1e-8, atol=1e-11),
            ).q
        )
    )(asymmetric)
    drift = np.abs(np.asarray(run) - q0).max()
    print(f"drift from rest over 1 s: {drift:.2e}")
    assert drift < 1e-9, drift


def test_rests_at_zero_agrees_with_the_twin(asymmetric):
    """`rests_at_zero` (q = 0 passes the Newton test, so an objective may skip the solve): true
    for the symmetric named sets, whose twin accelerations at q = 0 are below 1e-10, false for
    the asymmetric bogie, whose twin rest state lies 1e-5 or more from zero, and for a set with
    a NaN stiffness."""
    sets = [PARAMETER_SETS[name]() for name in sorted(PARAMETER_SETS)]
    for params in sets:
        assert np.abs(BogieTwin(params, 50.0).qddot(0.0, np.zeros(10), np.zeros(10))).max() < 1e-10
    assert rests_at_zero(sets)
    q_twin, _ = _twin_equilibrium(asymmetric)
    assert np.abs(q_twin).max() > 1e-5
    assert not rests_at_zero([asymmetric])
    assert not rests_at_zero([*sets, asymmetric])  # any set off zero counts
    broken = set_parameters(sets[0], {"primary.1L.kz": np.nan})
    assert not rests_at_zero([*sets, broken])  # a non-finite acceleration never passes


@pytest.mark.parametrize(
    "names, fixed",
    [
        (("primary.kz", "primary.cz", "yaw_dampers.c"), True),  # the default identification
        (("yaw_dampers.left.c", "primary.1L.cz", "secondary.right.cy"), True),  # dampers
        (("primary.1L.ky", "secondary.kz"), True),  # no preload change at q = 0
        (("yaw_dampers.left.c", "primary.1L.kz"), False),  # one spring carries more
        (("secondary.left.kz",), False),
    ],
)
def test_fixed_rest_state_only_where_no_selected_parameter_moves_it(names, fixed):
    """`fixed_rest_state` holds an objective's start at zero only where the selected
    parameters cannot move the rest state. Oracle: the twin's accelerations at q = 0 and zero
    velocity at three theta away from the probes (up to e^3 = 20x the nominal): below 1e-10
    at all three where the start is held (q = 0 is the rest state there), 1e-3 m/s^2 or more
    at one of them at least where it is not."""
    from bogie_jax.cost import fixed_rest_state, select_parameters

    nominal = bj.manchester_benchmark()
    selection = select_parameters(nominal, names)
    start = fixed_rest_state(nominal, selection, bj.ModelOptions())
    assert (start is not None) == fixed
    thetas = np.random.default_rng(7).uniform(-3.0, 3.0, (3, len(names)))
    at_zero = lambda p: BogieTwin(p, 50.0).qddot(0.0, np.zeros(10), np.zeros(10))
    largest = max(np.abs(at_zero(selection.apply(nominal, th))).max() for th in thetas)
    print(names, "largest |a(q = 0)| of the twin:", largest)
    if fixed:
        np.testing.assert_array_equal(start, np.zeros(20))
        assert largest < 1e-10
    else:
        assert largest > 1e-3


def test_synthetic_data_start_where_the_objective_starts():
    """Where the objective holds its start at zero, `synthetic_objective` simulates its data
    from zero too, without the equilibrium solve: the same data as a simulation from the
    truth's static equilibrium (the Newton solve, `synthetic_measurement`'s default, which
    stops within 1e-12 of zero: see above), to 1e-6 of each sensor's noise level."""
    from bogie_jax.cost import synthetic_objective
    from bogie_jax.measure import default_sensor_layout, synthetic_measurement

    params = bj.manchester_benchmark()
    wheelbase = 2 * float(params.geometry.semi_wheelbase)
    reference = bj.TrackReference.for_run(
        "erri-high", seed=3, speed=50.0, duration=0.1, wheelbase=wheelbase
    )
    track = reference.build()
    run = dict(speed=50.0, duration=0.1, sample_rate=100.0)
    solve = dict(stepsize_controller=dfx.ConstantStepSize(), dt0=1e-3)
    names = ("primary.kz", "primary.cz", "yaw_dampers.c")
    objective, _ = synthetic_objective(params, track, names, **run, **solve)
    assert objective.residual_model.y0 is not None  # the start is held at zero
    from_rest = synthetic_measurement(params, track, **run, **solve).data
    noise = np.array([float(s.noise_std) for s in default_sensor_layout(params)])
    moved = np.abs(from_rest).max(axis=0) / noise
    assert moved.max() > 1.0  # the track moves the bogie by more than the noise
    difference = np.abs(np.asarray(objective.residual_model.data) - from_rest).max(axis=0)
    print("largest difference / noise level:", (difference / noise).max())
    assert np.all(difference < 1e-6 * noise)
    # and the data are those of a run started exactly at zero, not from the Newton solve (whose
    # start lies about 4e-18 m away, so its data differ in the last digits): this part fails if
    # the data program solves for the equilibrium again
    from_zero = synthetic_measurement(params, track, **run, **solve, y0=np.zeros(20)).data
    assert not np.array_equal(from_rest, from_zero)
    np.testing.assert_array_equal(np.asarray(objective.residual_model.data), from_zero)


def test_each_scenario_truth_rests_at_zero_where_its_data_start_there():
    """`scenario_problem` starts its data at zero where the scenario's offset parameters cannot
    move the rest state (`fixed_rest_state` on them): the twin's accelerations of every such
    truth at q = 0 are below 1e-10 (m/s^2, rad/s^2), and at least the default scenario is one."""
    from bogie_jax.cost import fixed_rest_state, select_parameters
    from bogie_jax.identify import SCENARIOS
    from bogie_jax.params import get_parameter

    nominal = bj.manchester_benchmark()
    held = []
    for name, scenario in SCENARIOS.items():
        offset = select_parameters(nominal, tuple(scenario.offsets))
        if fixed_rest_state(nominal, offset, bj.ModelOptions()) is not None:
            truth = set_parameters(
                nominal,
                {n: f * float(get_parameter(nominal, n)) for n, f in scenario.offsets.items()},
            )
            at_zero = BogieTwin(truth, 50.0).qddot(0.0, np.zeros(10), np.zeros(10))
            assert np.abs(at_zero).max() < 1e-10, name
            held.append(name)
    print("data start at zero:", held)
    assert "default" in held
