"""The speed ramp-down (`bogie_jax.hunting`) against the eigenvalues of the linearised model.

Oracles: on the linear model a ramp's motion grows per second by exp(max Re(lambda)) of the
linearised equations, so it must die at the linear critical speed; with saturated creep on the
S1002/UIC60 table the bifurcation is supercritical (docs/contact.md), and a supercritical Hopf
cycle shrinks to nothing at the linear critical speed (Hopf's theorem), so the ramp must lose it
there as well.
"""

import jax.numpy as jnp
import numpy as np
import pytest

import bogie_jax as bj
from bogie_jax.hunting import ramp_down
from bogie_jax.model import critical_speed, stability_sweep
from bogie_jax.params import ModelOptions, set_parameters


def _without_yaw_dampers(**contact):
    return set_parameters(bj.manchester_benchmark(**contact), {"yaw_dampers.c": 0.0})


@pytest.fixture(scope="module")
def linear_ramp():
    params = _without_yaw_dampers()
    speeds = np.arange(108.0, 98.0, -1.0)
    ramp = ramp_down(
        params,
        speeds,
        dwell=6.0,
        settle=0.0,
        kick=1e-4,
        min_amplitude=1e-9,
        decay_tolerance=0.0,
        options=ModelOptions(),
    )
    return params, ramp


def test_linear_ramp_dies_at_the_linear_critical_speed(linear_ramp):
    params, ramp = linear_ramp
    lower, upper = ramp.dies_between()
    v_c = float(critical_speed(params, v_min=90.0, v_max=120.0).speed)  # 103.39 m/s
    assert lower < v_c < upper
    assert upper - lower == pytest.approx(1.0)
    assert bool(jnp.all(ramp.successful))


def test_linear_ramp_growth_is_the_largest_eigenvalue(linear_ramp):
    params, ramp = linear_ramp
    speeds = np.asarray(ramp.speeds)[[0, -1]]
    sigma = np.asarray(stability_sweep(params, speeds).max_real_part)
    expected = np.exp(sigma * 1.0)  # amplitude ratio over one second
    np.testing.assert_allclose(np.asarray(ramp.growth)[[0, -1]], expected, rtol=0.03)


@pytest.mark.parametrize(
    "argument, value, words",
    [
        ("speeds", [40.0, 50.0], "strictly descending"),
        ("speeds", [200.0, 100.0], "`speeds`"),
        ("dwell", 1.0, "`dwell`"),
        ("settle", -1.0, "`settle`"),
        ("kick", 0.05, "`kick`"),
        ("decay_tolerance", 0.5, "`decay_tolerance`"),
    ],
)
def test_bad_input_is_named(argument, value, words):
    arguments = {"speeds": [50.0, 40.0], argument: value}
    with pytest.raises(ValueError, match=words):
        ramp_down(bj.manchester_benchmark(), **arguments)


@pytest.mark.heavy
def test_profile_cycle_dies_at_the_linear_critical_speed_supercritical():
    params = _without_yaw_dampers(contact="s1002-uic60")
    v_c = float(critical_speed(params, v_min=30.0, v_max=70.0).speed)  # 47.1 m/s
    ramp = ramp_down(params, np.arange(52.0, 42.0, -0.5), dwell=10.0)
    lower, upper = ramp.dies_between()
    assert abs(0.5 * (lower + upper) - v_c) < 1.0
    assert float(ramp.amplitude[0]) > 0.2e-3  # hunting at 52 m/s (a cycle of 0.7 mm)


@pytest.mark.heavy
def test_a_run_leaving_the_contact_table_ends_the_ramp():
    params = _without_yaw_dampers(contact="s1002-uic60")
    ramp = ramp_down(params, [50.0, 45.0], dwell=2.0, kick=0.018)  # beyond the +-12 mm table
    assert not bool(jnp.any(ramp.successful))
    assert np.isnan(ramp.dies_between()[0])
