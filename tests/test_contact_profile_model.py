"""The equations of motion on a profile contact table (S1002 on UIC60 1:40), against oracles.

- the JAX interpolation against scipy's cubic spline of the same smoothed columns, C2 across the
  knots, finite with finite derivatives everywhere (also across the contact-point jumps and
  beyond the table);
- the vector field against the numpy twin reading the same table
  (`tests/reference/bogie_twin.py` with `tests/reference/twin_table.py`);
- a free decay: scipy Radau on the twin against diffrax on the JAX model.
"""

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.integrate
from scipy.interpolate import CubicSpline
from scipy.ndimage import gaussian_filter1d

from bogie_jax.contact import named_contact_table, profile_geometry
from bogie_jax.model import build_model, static_equilibrium, vector_field
from bogie_jax.params import manchester_benchmark
from bogie_jax.track import perfect_track


try:
    from reference.bogie_twin import BogieTwin, perfect_track_inputs
except ImportError:  # tests/ imported as a package
    from tests.reference.bogie_twin import BogieTwin, perfect_track_inputs


SPEED = 50.0  # [m/s]
SMOOTHING = 3e-4  # [m], the default of `profile_geometry`
_vector_field = jax.jit(vector_field)


@pytest.fixture(scope="module")
def params():
    return manchester_benchmark(contact="s1002-uic60")


@pytest.fixture(scope="module")
def pair(params):
    model = build_model(params, speed=SPEED, track=perfect_track())
    return model, BogieTwin(params, SPEED, perfect_track_inputs)


def test_interpolation_matches_scipy_and_is_c2():
    table = named_contact_table("s1002-uic60")
    geometry = profile_geometry(table, smoothing=SMOOTHING)
    step = table.lateral[1] - table.lateral[0]
    roll = CubicSpline(
        table.lateral, gaussian_filter1d(table.roll, SMOOTHING / step, mode="nearest")
    )
    radius = CubicSpline(
        table.lateral,
        gaussian_filter1d(table.rolling_radius[:, 0], SMOOTHING / step, mode="nearest"),
    )
    y = np.random.default_rng(0).uniform(-0.012, 0.012, 200)
    value, slope, curvature = (np.asarray(a) for a in geometry.evaluate(jnp.asarray(y)))
    for k, spline in ((6, roll), (0, radius)):
        for nu, got in enumerate((value, slope, curvature)):
            # the same cubic pieces: equal to rounding (second derivatives reach 1e3-1e4)
            np.testing.assert_allclose(got[k], spline(y, nu), rtol=1e-9, atol=1e-12)
    knots = table.lateral[1:-1]  # second derivative continuous: left and right limits agree
    eps = 1e-12
    below = np.asarray(geometry.evaluate(jnp.asarray(knots - eps))[2])
    above = np.asarray(geometry.evaluate(jnp.asarray(knots + eps))[2])
    scale = np.max(np.abs(below), axis=1, keepdims=True)
    assert np.max(np.abs(below - above) / scale) < 1e-6
    far = np.asarray(geometry.evaluate(jnp.asarray([-0.05, 0.05]))[0])
    assert np.all(np.isfinite(far))


def test_derivatives_finite_across_jumps_and_beyond_the_table(pair):
    """No NaN in the interpolation's derivatives (forward and reverse mode) or in the vector
    field at the centre, at the contact-point jumps (near 0, 4.7 and 6.2 mm) and beyond the
    table; the full Jacobian of the vector field is checked by the heavy test below."""
    model, _ = pair
    geometry = model.constants.geometry
    points = jnp.asarray([0.0, 5e-5, 4.7e-3, 6.2e-3, 0.02, -0.05])
    for f in (jax.jacfwd, jax.jacrev):
        d = f(lambda y: geometry.evaluate(y)[0])(points)
        assert np.all(np.isfinite(np.asarray(d)))
    for offset in np.asarray(points):
        y = np.zeros(20)
        y[6:8] = offset
        y[16:18] = 0.01
        assert np.all(np.isfinite(np.asarray(_vector_field(0.0, jnp.asarray(y), model))))


@pytest.mark.heavy
def test_vector_field_jacobian_finite_at_the_jumps(pair):
    model, _ = pair
    jacobian = jax.jit(jax.jacfwd(vector_field, argnums=1))
    for offset in (0.0, 5e-5, 4.7e-3, 6.2e-3, 0.02):
        y = np.zeros(20)
        y[6:8] = offset
        y[16:18] = 0.01
        assert np.all(np.isfinite(np.asarray(jacobian(0.0, jnp.asarray(y), model))))


def test_rhs_matches_twin_on_the_profile_table(pair):
    """|a_jax - a_twin| / |a_twin| <= 1e-9 (as the cone model's twin test), at random states
    with wheelset offsets up to 8 mm (tread, flange root and flange contact)."""
    model, twin = pair
    rng = np.random.default_rng(3)
    worst = 0.0
    for _ in range(12):
        y = np.concatenate([1e-3 * rng.standard_normal(10), 1e-2 * rng.standard_normal(10)])
        y[6:8] = rng.uniform(-8e-3, 8e-3, 2)
        f_jax = np.asarray(_vector_field(0.0, jnp.asarray(y), model))
        f_twin = twin.rhs(0.0, y)
        worst = max(worst, np.linalg.norm(f_jax[10:] - f_twin[10:]) / np.linalg.norm(f_twin[10:]))
    assert worst <= 1e-9, worst


def test_static_equilibrium_is_centred(params):
    q0 = np.asarray(static_equilibrium(params))
    assert np.all(np.isfinite(q0))
    assert np.max(np.abs(q0[6:])) < 1e-12  # symmetric bogie on symmetric profiles


@pytest.mark.heavy
def test_free_decay_radau_on_twin_matches_diffrax(pair):
    """0.3 s at 50 m/s from a 3 mm offset of both wheelsets (through the contact-point jump at
    the centre): scipy Radau (rtol 1e-10, atol 1e-12) on the twin vs diffrax Dopri8 (rtol 1e-11,
    atol 1e-13) on the JAX model; max abs difference per coordinate / max abs of the twin's,
    over lateral and yaw of the wheelsets and the frame: <= 1e-6."""
    model, twin = pair
    y0 = np.zeros(20)
    y0[6:8] = 3e-3
    ts = np.linspace(0.0, 0.3, 61)
    sol = scipy.integrate.solve_ivp(
        twin.rhs, (0.0, ts[-1]), y0, method="Radau", rtol=1e-10, atol=1e-12, t_eval=ts
    )
    assert sol.success, sol.message
    y_jax = diffrax.diffeqsolve(
        diffrax.ODETerm(vector_field),
        diffrax.Dopri8(),
        t0=0.0,
        t1=ts[-1],
        dt0=1e-4,
        y0=jnp.asarray(y0),
        args=model,
        stepsize_controller=diffrax.PIDController(rtol=1e-11, atol=1e-13),
        saveat=diffrax.SaveAt(ts=jnp.asarray(ts)),
        max_steps=100_000,
    ).ys
    y_twin, y_jax = sol.y.T, np.asarray(y_jax)
    for cols in ([1], [5], [6, 7], [8, 9]):  # frame lateral, frame yaw, wheelset lateral, yaw
        diff = np.abs(y_jax[:, cols] - y_twin[:, cols]).max()
        assert diff / np.abs(y_twin[:, cols]).max() <= 1e-6, (cols, diff)


def test_wear_blends_the_new_and_worn_tables():
    """`wear.level` blends the tables linearly: level 0 is the new pair, 1 the worn wheel's; the
    derivative with respect to the level is worn - new (forward mode through the constants), and
    the vector field at a half-worn wheel is finite."""
    from bogie_jax.contact import equivalent_conicity
    from bogie_jax.model import model_constants
    from bogie_jax.params import set_parameters

    worn_params = manchester_benchmark(contact="s1002-uic60", wear=1.0)
    new = profile_geometry(named_contact_table("s1002-uic60"))
    worn = profile_geometry(named_contact_table("worn-uic60"))
    at_0 = model_constants(set_parameters(worn_params, {"wear.level": 0.0})).geometry
    at_1 = model_constants(worn_params).geometry
    np.testing.assert_array_equal(np.asarray(at_0.coefficients), np.asarray(new.coefficients))
    np.testing.assert_allclose(at_1.coefficients, worn.coefficients, rtol=1e-12)  # rounding

    def coefficients(level):
        params = set_parameters(worn_params, {"wear.level": level})
        return model_constants(params).geometry.coefficients

    _, tangent = jax.jvp(coefficients, (0.4,), (1.0,))
    np.testing.assert_allclose(tangent, worn.coefficients - new.coefficients, rtol=1e-12)
    # the equivalent conicity is linear in Delta r, so it blends with the same weights
    table_new, table_worn = named_contact_table("s1002-uic60"), named_contact_table("worn-uic60")
    a = np.array([2e-3, 4e-3])
    dr = 0.7 * table_new.rolling_radius_difference + 0.3 * table_worn.rolling_radius_difference
    blended = equivalent_conicity(table_new.lateral, dr, a)
    expected = 0.7 * equivalent_conicity(
        table_new.lateral, table_new.rolling_radius_difference, a
    ) + 0.3 * equivalent_conicity(table_worn.lateral, table_worn.rolling_radius_difference, a)
    np.testing.assert_allclose(blended, expected, rtol=1e-12)
    model = build_model(
        set_parameters(worn_params, {"wear.level": 0.5}), speed=SPEED, track=perfect_track()
    )
    y = np.zeros(20)
    y[6:8] = 4e-3
    assert np.all(np.isfinite(np.asarray(_vector_field(0.0, jnp.asarray(y), model))))


def test_conicity_factor_scales_the_rolling_radius_difference():
    """`wear.conicity_factor` k scales Delta r about the centred contact: the scaled geometry's
    Delta r and its first two derivatives are k times scipy's splines of the smoothed table's
    (and so its equivalent conicity, a linear functional of Delta r), the other six quantities
    stay bit for bit, k = 1 is the blend itself bit for bit, and d/dk (forward mode through the
    constants) is the rolling radii's deviation from their centred value."""
    from bogie_jax.model import model_constants
    from bogie_jax.params import set_parameters

    params = manchester_benchmark(contact="s1002-uic60", wear=0.3)
    blend = model_constants(params).geometry
    table_new, table_worn = named_contact_table("s1002-uic60"), named_contact_table("worn-uic60")
    new, worn = profile_geometry(table_new), profile_geometry(table_worn)
    expected_blend = 0.7 * np.asarray(new.coefficients) + 0.3 * np.asarray(worn.coefficients)
    np.testing.assert_allclose(blend.coefficients, expected_blend, rtol=1e-12)

    def geometry(k):
        return model_constants(set_parameters(params, {"wear.conicity_factor": k})).geometry

    np.testing.assert_array_equal(np.asarray(geometry(1.0).coefficients), blend.coefficients)
    k = 0.6
    scaled = geometry(k)
    step = table_new.lateral[1] - table_new.lateral[0]
    dr = 0.7 * table_new.rolling_radius_difference + 0.3 * table_worn.rolling_radius_difference
    spline = CubicSpline(table_new.lateral, gaussian_filter1d(dr, SMOOTHING / step, mode="nearest"))
    y = np.random.default_rng(1).uniform(-0.011, 0.011, 100)
    for nu, got in enumerate(np.asarray(a) for a in scaled.evaluate(jnp.asarray(y))):
        np.testing.assert_allclose(got[0] - got[1], k * spline(y, nu), rtol=1e-9, atol=1e-12)
    unscaled = blend.coefficients[..., 2:]
    np.testing.assert_array_equal(np.asarray(scaled.coefficients[..., 2:]), unscaled)
    radii = np.asarray(blend.evaluate(jnp.asarray(y))[0][:2])
    centred = np.asarray(blend.evaluate(0.0)[0][:2])
    along = np.asarray(
        jax.jvp(lambda k: geometry(k).evaluate(jnp.asarray(y))[0][:2], (k,), (1.0,))[1]
    )
    np.testing.assert_allclose(along, radii - centred[:, None], rtol=1e-9, atol=1e-15)


def test_leaving_the_table_is_a_solve_status_not_a_nan(pair):
    """A wheelset thrown beyond the 12 mm table: with the event condition the solve stops with
    `event_occurred` and finite states; the cone never triggers it."""
    from bogie_jax.model import beyond_contact_table

    model, _ = pair
    y0 = np.zeros(20)
    y0[6:8] = 10e-3
    y0[16:18] = 1.5  # 1.5 m/s outwards: enough to climb the flange past the 12 mm table
    solution = diffrax.diffeqsolve(
        diffrax.ODETerm(vector_field),
        diffrax.Tsit5(),
        t0=0.0,
        t1=0.5,
        dt0=1e-4,
        y0=jnp.asarray(y0),
        args=model,
        stepsize_controller=diffrax.PIDController(rtol=1e-6, atol=1e-8),
        event=diffrax.Event(beyond_contact_table),
        throw=False,
    )
    assert solution.result == diffrax.RESULTS.event_occurred
    assert float(solution.ts[-1]) < 0.05
    assert np.all(np.isfinite(np.asarray(solution.ys)))
    cone = build_model(manchester_benchmark(), speed=SPEED, track=perfect_track())
    assert not bool(beyond_contact_table(0.0, jnp.asarray(y0), cone))


def test_simulate_reports_leaving_the_table_as_its_status(params):
    """`simulate` on the profile model stops where a wheelset leaves the table: the run's status
    is `event_occurred` (not successful), the samples after the stop hold inf and none is NaN;
    a run that stays inside the table is successful and finite."""
    from bogie_jax import simulate

    y0 = np.zeros(20)
    y0[6:8] = 10e-3
    y0[16:18] = 1.5  # 1.5 m/s outwards: past the 12 mm table within a few milliseconds
    kwargs = dict(speed=SPEED, duration=0.2, sample_rate=200.0)
    thrown = simulate(params, perfect_track(), y0=y0, **kwargs)
    assert thrown.result == diffrax.RESULTS.event_occurred and not bool(thrown.successful)
    for samples in (thrown.q, thrown.qd, thrown.qdd):
        assert not np.isnan(np.asarray(samples)).any()
    assert 0 < int(np.isfinite(np.asarray(thrown.q)).all(axis=1).sum()) < len(thrown.ts)
    calm = simulate(params, perfect_track(), **kwargs)
    assert bool(calm.successful) and np.isfinite(np.asarray(calm.qdd)).all()
