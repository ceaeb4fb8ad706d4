"""The objective (paper eq. 12): parameter selection and transforms, residuals, weights and
missing data, input errors, jit and vmap over theta."""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from bogie_jax.cost import make_objective, select_parameters
from bogie_jax.gradients import compiled_residuals as _residuals, gradient
from bogie_jax.measure import Measurement, MeasurementError


try:
    from fixtures_cost import four_sensors, nominal, objective, problem, short_track, theta0  # noqa: F401
except ImportError:  # tests/ imported as a package
    from tests.fixtures_cost import four_sensors, nominal, objective, problem, short_track, theta0  # noqa: F401


# ------------------------------------------------------------------------------- selection
def test_selection_round_trip_bounds_and_apply(nominal):
    sel = select_parameters(
        nominal,
        ["primary.kz", "primary.ky", "yaw_dampers.c"],
        bounds={"primary.ky": "spec", "yaw_dampers.c": (1e5, 1e6)},
    )
    assert sel.log_scale == (True, False, False)
    assert sel.units == ("N/m", "N/m", "N s/m")
    np.testing.assert_allclose(sel.to_physical(jnp.zeros(3)), sel.nominal, rtol=1e-15)
    theta = jnp.array([0.3, -1.7, 2.2])
    np.testing.assert_allclose(sel.to_theta(sel.to_physical(theta)), theta, rtol=1e-12)
    np.testing.assert_allclose(
        sel.to_physical(jnp.array([0.3, 0.0, 0.0]))[0], 1.22e6 * np.exp(0.3), rtol=1e-15
    )
    extreme = sel.to_physical(jnp.array([0.0, 40.0, -40.0]))  # logistic stays inside its box
    assert 2e6 < float(extreme[1]) <= 1e7 and 1e5 <= float(extreme[2]) < 4e5
    grads = jax.jacfwd(sel.to_physical)(jnp.array([0.0, 40.0, -40.0]))
    assert np.all(np.isfinite(grads))
    p = sel.apply(nominal, theta)
    # a tied name sets every element (four axleboxes, two sides) to its one value
    np.testing.assert_allclose(
        [p.primary.kz, p.primary.ky], np.repeat(sel.to_physical(theta)[:2, None], 4, 1), rtol=1e-15
    )
    np.testing.assert_allclose(p.yaw_dampers.c, np.repeat(sel.to_physical(theta)[2], 2), rtol=1e-15)
    np.testing.assert_array_equal(p.primary.kx, nominal.primary.kx)  # unselected unchanged
    batch = jax.vmap(lambda th: sel.apply(nominal, th).primary.kz)(jnp.stack([theta, -theta]))
    np.testing.assert_allclose(batch, 1.22e6 * np.exp([[0.3] * 4, [-0.3] * 4]), rtol=1e-14)
    assert sel.describe(jnp.zeros(3))["primary.kz"] == (1.22e6, "N/m")


@pytest.mark.parametrize(
    "names, bounds, match",
    [
        ([], None, "`names` is empty"),
        (
            ["primary.kzz"],
            None,
            r"unknown parameter 'primary.kzz' in `names` \(did you mean primary.kz",
        ),
        (["primary.kz", "primary.kz"], None, "repeated: primary.kz"),
        (
            ["yaw_dampers.c"],
            {"yaw_dampers.c": (1e4, 2e5)},
            r"starting value `yaw_dampers.c` = 400000 N s/m is outside its bounds "
            r"\(10000, 200000\)",
        ),
        (
            ["contact.poisson_ratio"],
            "spec",
            r"`contact.poisson_ratio` = 0.3 - is outside its bounds \(0.25, 0.3\)",
        ),
        (["primary.kz"], {"primary.ky": "spec"}, "not selected: primary.ky"),
        (["primary.kz"], {"primary.kz": (2e6, 1e6)}, "must satisfy lo < hi"),
        (["primary.kz"], {"primary.kz": (-1.0, 2e6)}, r"inside the valid range \[0, 1e\+10\]"),
        (["primary.kz"], "all", "`bounds` must be None, 'spec' or a mapping"),
    ],
)
def test_bad_selections_are_rejected(nominal, names, bounds, match):
    with pytest.raises(ValueError, match=match):
        select_parameters(nominal, names, bounds=bounds)


def test_element_selection_reads_and_sets_one_element(nominal):
    """An element name (`primary.1L.kz`) has its own theta; tied names still set all elements;
    `values` reads back what `apply` wrote; works under vmap."""
    names = ["primary.1L.kz", "yaw_dampers.right.c", "secondary.cy"]
    sel = select_parameters(nominal, names, bounds={"yaw_dampers.right.c": "spec"})
    assert sel.units == ("N/m", "N s/m", "N s/m") and sel.log_scale == (True, False, True)
    np.testing.assert_allclose(sel.nominal, [1.22e6, 400e3, 32e3], rtol=1e-15)
    theta = jnp.array([0.2, -0.5, 0.1])
    p = sel.apply(nominal, theta)
    v = np.asarray(sel.to_physical(theta))
    np.testing.assert_allclose(p.primary.kz, [v[0], 1.22e6, 1.22e6, 1.22e6], rtol=1e-15)
    np.testing.assert_allclose(p.yaw_dampers.c, [400e3, v[1]], rtol=1e-15)
    np.testing.assert_allclose(p.secondary.cy, [v[2], v[2]], rtol=1e-15)
    np.testing.assert_allclose(sel.values(p), v, rtol=1e-15)
    batch = jax.vmap(lambda th: sel.apply(nominal, th).yaw_dampers.c)(jnp.stack([theta, 0 * theta]))
    np.testing.assert_allclose(batch, [[400e3, v[1]], [400e3, 400e3]], rtol=1e-14)
    # two elements of one field: each its own theta
    sel2 = select_parameters(nominal, ["yaw_dampers.left.c", "yaw_dampers.right.c"])
    p2 = sel2.apply(nominal, jnp.array([np.log(0.5), 0.0]))
    np.testing.assert_allclose(p2.yaw_dampers.c, [200e3, 400e3], rtol=1e-14)
    # a tied name on an asymmetric base has no single nominal value
    with pytest.raises(
        ValueError,
        match=r"`yaw_dampers.c` has no single value: its elements "
        r"differ \(yaw_dampers.left.c = 200000, yaw_dampers.right.c = 400000",
    ):
        select_parameters(p2, ["yaw_dampers.c"])
    np.testing.assert_allclose(
        select_parameters(p2, ["yaw_dampers.left.c"]).nominal, [200e3], rtol=1e-15
    )


@pytest.mark.parametrize(
    "names, match",
    [
        (
            ["primary.3L.kz"],
            r"unknown element '3L' in parameter 'primary.3L.kz' in `names`: the "
            r"elements of `primary` are 1L, 1R, 2L, 2R",
        ),
        (
            ["yaw_dampers.middle.c"],
            r"unknown element 'middle' in parameter "
            r"'yaw_dampers.middle.c' in `names`: the elements of `yaw_dampers` are left, right",
        ),
        (
            ["primary.kz", "primary.1L.kz"],
            r"`names` mixes the tied group `primary.kz` \(all its "
            r"elements, one value\) with its member\(s\) `primary.1L.kz`",
        ),
        (
            ["secondary.right.cy", "yaw_dampers.c", "secondary.cy", "secondary.left.cy"],
            r"mixes the tied group `secondary.cy` .* `secondary.right.cy`, `secondary.left.cy`",
        ),
        (["primary.1L.kz", "primary.1L.kz"], "repeated: primary.1L.kz"),
    ],
)
def test_bad_element_selections_are_rejected(nominal, names, match):
    with pytest.raises(ValueError, match=match):
        select_parameters(nominal, names)


def test_log_scale_needs_a_positive_nominal(nominal):
    zero = eqx.tree_at(lambda p: p.masses.carbody_mass, nominal, 0.0)
    with pytest.raises(ValueError, match="cannot be log-scaled"):
        select_parameters(zero, ["masses.carbody_mass"])


# ------------------------------------------------------------------------------- objective
def test_residuals_vanish_at_the_truth(objective, theta0):
    # `_residuals` is `eqx.filter_jit(lambda obj, th: obj.residuals(th))`: the objective is an
    # argument (a closure would let XLA fold the parameters into constants and round
    # differently); the same compiled function serves finite differences below
    r0 = np.asarray(_residuals(objective, jnp.zeros(3)))
    assert r0.shape == (objective.n_residuals,) == (51 * 4,)
    assert np.max(np.abs(r0)) < 1e-6  # noise-free data from the same solve (measured 5e-10)
    r = np.asarray(_residuals(objective, theta0))
    assert np.max(np.abs(r)) > 1.0


def test_missing_samples_and_weights(objective, theta0, four_sensors, nominal, short_track):
    rm = objective.residual_model
    r = np.asarray(gradient(objective, theta0, method="fd-forward").residuals)  # shares compilation
    data = np.asarray(rm.data).copy()
    data[5:9, 1] = np.nan
    data[20, :] = np.nan
    m = Measurement(
        times=np.arange(51) / 200.0,
        data=data,
        channels=[s.name for s in four_sensors],
        units=[s.unit for s in four_sensors],
        speed=50.0,
    )
    weights = {"frame_yaw_rate": 4.0 / float(four_sensors[2].noise_std) ** 2}
    obj = make_objective(
        m,
        nominal,
        short_track,
        objective.selection.names,
        sensors=four_sensors,
        weights=weights,
        bounds={"primary.ky": "spec"},
        options=rm.options,
        stepsize_controller=rm.stepsize_controller,
        max_steps=rm.max_steps,
        dt0=rm.dt0,
    )
    assert obj.n_observations == 51 * 4 - 8
    g = gradient(obj, theta0, method="fd-forward")  # same structure: no new compilation
    r_missing = np.asarray(g.residuals).reshape(51, 4)
    expected = r.reshape(51, 4).copy()
    expected[5:9, 1] = 0.0
    expected[20, :] = 0.0
    expected[:, 2] *= 2.0  # weight x4 -> residual x2
    np.testing.assert_allclose(r_missing, expected, rtol=1e-12, atol=0)
    assert np.all(np.isfinite(np.asarray(g.grad)))
    default_w = np.asarray(objective.residual_model.sqrt_weights) ** 2
    np.testing.assert_allclose(default_w, [1 / float(s.noise_std) ** 2 for s in four_sensors])


def test_vmap_over_theta_equals_a_loop_and_cost_is_half_the_square(objective, theta0):
    # Objective.cost under vmap against 1/2 |r|^2 of the residuals evaluated one by one.
    thetas = jnp.stack([theta0, 0.5 * theta0, -theta0])
    batched = eqx.filter_jit(lambda obj, th: jax.vmap(lambda t: obj.cost(t))(th))(objective, thetas)
    # one by one through the compiled residuals of the tests above (one solve each)
    looped = [0.5 * np.sum(np.asarray(_residuals(objective, th)) ** 2) for th in thetas]
    np.testing.assert_allclose(batched, looped, rtol=1e-10)  # same solves, different batching


def test_non_finite_parameters_give_infinite_residuals_without_simulating_them(objective, theta0):
    # An adaptive solve at NaN parameters rejects every step until `max_steps`; with
    # `throw=True` it would raise. The objective answers +inf without solving at such a point.
    # theta = +inf of the boxed primary.ky (index 2) is its upper bound: a valid point.
    import diffrax as dfx

    adaptive = objective.replace(
        stepsize_controller=dfx.PIDController(rtol=1e-6, atol=1e-9), max_steps=2048, throw=True
    )
    thetas = jnp.stack(
        [
            theta0,
            theta0.at[2].set(jnp.inf),  # the bound of a boxed parameter: simulated
            theta0.at[1].set(jnp.nan),
            theta0.at[0].set(jnp.inf),  # log scale: infinite stiffness
        ]
    )
    r = eqx.filter_jit(lambda obj, th: jax.vmap(obj.residuals)(th))(adaptive, thetas)
    assert np.all(np.isfinite(r[:2])) and np.any(r[0] != 0) and np.any(r[1] != r[0])
    assert np.all(np.isposinf(r[2:]))


def test_make_objective_input_errors(objective, four_sensors, nominal, short_track):
    rm = objective.residual_model
    names, units = [s.name for s in four_sensors], [s.unit for s in four_sensors]
    base = dict(
        times=np.arange(51) / 200.0,
        data=np.asarray(rm.data),
        channels=names,
        units=units,
        speed=50.0,
    )
    build = lambda m, **kw: make_objective(
        m, nominal, short_track, ["primary.kz"], sensors=four_sensors, **kw
    )
    # times need not start at 0 (only the spacing counts; a window's position is its
    # `start_position`): a shifted record gives the same residual model
    shifted = build(Measurement(**{**base, "times": 0.1 + np.arange(51) / 200.0}))
    assert shifted.residual_model.duration == pytest.approx(0.25, rel=1e-12)
    with pytest.raises(MeasurementError, match="unknown channel 'extra'"):
        build(
            Measurement(
                **{
                    **base,
                    "data": np.zeros((51, 5)),
                    "channels": names + ["extra"],
                    "units": units + ["m"],
                }
            )
        )
    with pytest.raises(MeasurementError, match="every sample of the measurement is missing"):
        build(Measurement(**{**base, "data": np.full((51, 4), np.nan)}))
    with pytest.raises(ValueError, match=r"`weights` must have shape \(4,\)"):
        build(Measurement(**base), weights=np.ones(3))
    with pytest.raises(ValueError, match="`weights` must be finite and > 0; channel 'frame_1L_y'"):
        build(Measurement(**base), weights={"frame_1L_y": -1.0})
    with pytest.raises(MeasurementError, match="no sensor layout"):
        make_objective(Measurement(**base), nominal, short_track, ["primary.kz"])
    with pytest.raises(ValueError, match="cannot replace"):
        objective.replace(params=nominal)


def test_replace_keeps_data_and_changes_solver_settings(objective):
    import diffrax as dfx

    other = objective.with_adjoint(dfx.ForwardMode())
    assert isinstance(other.residual_model.adjoint, dfx.ForwardMode)
    assert other.selection is objective.selection
    assert dataclasses.replace(objective.residual_model).n_residuals == objective.n_residuals
