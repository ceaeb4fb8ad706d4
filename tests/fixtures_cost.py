"""Session fixtures shared by test_measure, test_cost and test_gradients.

One short run (0.25 s at 200 Hz, 50 m/s, ERRI-low track) measured by four channels of the
default layout, with creep saturation on (so the start at static equilibrium, where every
creepage is zero, exercises the NaN-safe creep law). Tsit5 with a fixed step of 0.25 ms: every AD
method then differentiates the same discrete map (the scalar-product test is exact to rounding),
and the gradient is within ~1e-8 of the tight adaptive reference (Tsit5's error ~ h^5: 4e-10
measured at 0.1 ms). The track starts 5 m behind the trailing wheelset: a wheelset running onto
the end of a sampled track sees a jump in the slope of the input, which would cut a fixed-step
solver to first order. Every compiled function is
compiled once per session: the objective's structure never changes between tests, only its array
leaves (data, mask, weights, track, tolerances).
"""

import diffrax as dfx
import jax.numpy as jnp
import jax.random as jr
import pytest

import bogie_jax as bj
from bogie_jax.cost import synthetic_objective
from bogie_jax.measure import default_sensor_layout
from bogie_jax.params import ModelOptions
from bogie_jax.track import ERRIB176Spectrum, synthesise_track


SPEED, DURATION, RATE = 50.0, 0.25, 200.0  # [m/s], [s], [Hz]
NAMES = ("primary.kz", "yaw_dampers.c", "primary.ky")  # primary.ky boxed, the others log scale
CHANNELS = ("frame_1L_y", "frame_1L_z", "frame_yaw_rate", "axlebox_1L_y")
OPTIONS = ModelOptions(creep_saturation=True)
DT = 2.5e-4  # [s] fixed step (h |lambda|max ~ 0.1: accuracy, not stability, sets it)


@pytest.fixture(scope="session")
def nominal():
    return bj.manchester_benchmark()


@pytest.fixture(scope="session")
def short_track():
    return synthesise_track(
        ERRIB176Spectrum.low(), key=jr.PRNGKey(0), length=35.0, fade_length=2.0, start=-5.0
    )


@pytest.fixture(scope="session")
def four_sensors(nominal):
    return tuple(s for s in default_sensor_layout(nominal) if s.name in CHANNELS)


@pytest.fixture(scope="session")
def problem(nominal, short_track, four_sensors):
    """(objective, theta0): noise-free data at the nominal parameters, theta0 = +10 %."""
    return synthetic_objective(
        nominal,
        short_track,
        NAMES,
        speed=SPEED,
        duration=DURATION,
        sample_rate=RATE,
        sensors=four_sensors,
        key=None,
        offset=0.1,
        options=OPTIONS,
        bounds={"primary.ky": "spec"},
        stepsize_controller=dfx.ConstantStepSize(),
        dt0=DT,
        max_steps=4096,
    )


@pytest.fixture(scope="session")
def objective(problem):
    return problem[0]


@pytest.fixture(scope="session")
def theta0(problem):
    return jnp.asarray(problem[1])
