"""Physics of the forward model against analytic oracles (reference doc sections 1.4, 4.1, 4.2)."""

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import bogie_jax as bj
from bogie_jax.contact import cone_geometry
from bogie_jax.model import (
    GRAVITY,
    build_model,
    critical_speed,
    eigenvalues,
    mass_matrix,
    model_constants,
    system_matrix,
)
from bogie_jax.simulation import simulate
from bogie_jax.track import perfect_track


def _set(params, **values):
    """Return params with dotted-path fields replaced, e.g. _set(p, **{"primary.ky": 0.0}).

    A per-element field (e.g. `primary.ky`, one value per spring) gets `value` in every element:
    the shapes stay those of the named set, so the compiled programs below are shared."""
    for path, value in values.items():
        getter = lambda p, path=path: eval("p." + path)  # noqa: E731 (test helper)
        old = getter(params)
        params = eqx.tree_at(getter, params, jnp.full(jnp.shape(old), value, dtype=float))
    return params


@pytest.fixture(scope="module")
def linear_fn():
    """(system_matrix, eigenvalues) in one program; the speed is traced (one compilation)."""
    return eqx.filter_jit(
        lambda params, speed: (system_matrix(params, speed), eigenvalues(params, speed))
    )


@pytest.fixture(scope="module")
def eig_fn(linear_fn):
    return lambda params, speed: linear_fn(params, jnp.asarray(speed, dtype=float))[1]


@pytest.fixture(scope="module")
def mass_fn():
    return jax.jit(mass_matrix)


@pytest.fixture(scope="module")
def simulate_fn():
    def run(params, speed, y0, duration):  # speed traced: one compilation per duration
        return simulate(
            params,
            perfect_track(),
            speed=speed,
            duration=duration,
            sample_rate=100.0,
            y0=y0,
            stepsize_controller=dfx.PIDController(rtol=1e-8, atol=1e-11),
        )

    jitted = eqx.filter_jit(run, donate="none")
    return lambda params, speed, y0, duration: jitted(
        params, jnp.asarray(speed, dtype=float), y0, duration
    )


HUNT_DURATION = 6.0  # [s]: the hunting runs; the rest run has the same length (one program)


def _free_wheelsets(params):
    """No lateral/longitudinal primary coupling: the wheelsets are free in lateral and yaw."""
    return _set(
        params, **{"primary.kx": 0.0, "primary.ky": 0.0, "primary.cx": 0.0, "primary.cy": 0.0}
    )


def _lowest_oscillation_hz(eig):
    eig = np.asarray(eig)
    osc = eig[np.abs(eig.imag) > 1e-6]
    return np.min(np.abs(osc.imag)) / (2 * np.pi)


def test_static_equilibrium_is_kept(simulate_fn):
    """Started at q = 0 on a perfect track, the bogie stays there (preloads balance gravity)
    for 6 s (the hunting runs' length: the same compiled program)."""
    traj = simulate_fn(bj.manchester_benchmark(), 50.0, jnp.zeros(20), HUNT_DURATION)
    assert bool(traj.successful)
    assert np.max(np.abs(traj.q)) < 1e-12  # metres / radians: rounding only


def test_mass_matrix_symmetric_positive_definite(mass_fn):
    model = build_model(bj.manchester_benchmark(), speed=50.0, track=perfect_track())
    q = jnp.array([1e-3, -2e-3, 1e-3, 2e-3, -1e-3, 3e-3, 4e-3, -3e-3, 2e-3, -1e-3])
    m = np.asarray(mass_fn(model, q))
    assert np.allclose(m, m.T, rtol=1e-12, atol=0)  # algebraic identity
    assert np.all(np.linalg.eigvalsh(m) > 0)


def test_gravitational_stiffness_matches_energy_method(linear_fn, mass_fn):
    """With creep and primary springs removed, the wheelset's lateral and yaw stiffness from the
    constraint (paper eq. 2) is K_y = W zeta and K_yaw = -W xi (reference doc 1.4, [D check])."""
    p = _set(
        bj.manchester_benchmark(),
        **{f"primary.{k}": 0.0 for k in ("kx", "ky", "kz", "cx", "cy", "cz")},
        **{"contact.creep_factor": 0.0},
    )
    model = build_model(p, speed=50.0, track=perfect_track())
    a = np.asarray(linear_fn(p, jnp.asarray(50.0, dtype=float))[0])
    m = np.asarray(mass_fn(model, jnp.zeros(10)))
    stiffness = -(m @ a[10:, :10])  # dQ/dq = M d(q_ddot)/dq at rest
    c = p.contact
    geo = cone_geometry(c.wheel_radius, c.contact_semi_distance, c.cone_slope, c.rail_head_radius)
    const = model_constants(p)
    load = p.masses.wheelset.mass * GRAVITY + 2 * const.primary_preload
    np.testing.assert_allclose(stiffness[6, 6], load * geo.vertical_lateral_coefficient, rtol=1e-9)
    np.testing.assert_allclose(stiffness[8, 8], -load * geo.vertical_yaw_coefficient, rtol=1e-9)


def test_free_wheelset_kinematic_wavelength(eig_fn):
    """Pure-rolling wavelength with the roll-rate term (reference doc 4.1):
    L = 2 pi sqrt(r0 e0 (1 + r0 sigma / e0) / lambda), within 2 %."""
    p = _free_wheelsets(bj.manchester_benchmark())
    speed = 2.0
    c = p.contact
    geo = cone_geometry(c.wheel_radius, c.contact_semi_distance, c.cone_slope, c.rail_head_radius)
    r0, e0 = float(c.wheel_radius), float(c.contact_semi_distance)
    expected = (
        2
        * np.pi
        * np.sqrt(r0 * e0 * (1 + r0 * float(geo.roll_coefficient) / e0) / float(geo.conicity))
    )
    wavelength = speed / _lowest_oscillation_hz(eig_fn(p, speed))
    assert abs(wavelength / expected - 1) < 0.02


def _rigid_bogie(cone_slope):
    return _set(
        bj.manchester_benchmark(),
        **{"primary.kx": 1e9, "primary.ky": 1e9, "contact.cone_slope": cone_slope},
        **{f"secondary.{k}": 0.0 for k in ("kx", "ky", "cy")},
        **{"yaw_dampers.c": 0.0},
    )


@pytest.mark.parametrize("cone_slope", [0.025, 0.05])
def test_rigid_bogie_kinematic_wavelength(eig_fn, cone_slope):
    """Rigid two-axle bogie (primary stiff, secondary and yaw dampers removed) at 2 m/s.

    Oracle 1, reference doc 4.2: L = 2 pi sqrt((r0 e0 / lambda)(1 + (f22/f11)(a/e0)^2)), within
    3 % at tan(delta0) = 0.025. That formula leaves out the roll-rate terms of the lateral
    creepage (paper eq. 9b, terms (2)-(3): the contact point moves laterally by
    (r0 + e0 tan delta0) d(delta_x)/dt), which lengthen the wave by about 4 % at 0.05.
    Oracle 2, the same pure-rolling derivation with those terms kept (c = 1 + (r0 + e0 t) sigma/e0
    multiplies the lateral creepage and, reciprocally, the lateral generalised force):
    L = 2 pi sqrt((r0 e0 c / lambda)(1 + (f22/f11)(a/e0)^2 c^2)), within 0.5 % at both slopes.
    """
    p = _rigid_bogie(cone_slope)
    speed = 2.0
    const = model_constants(p)
    r0, e0 = float(p.contact.wheel_radius), float(p.contact.contact_semi_distance)
    a = float(p.geometry.semi_wheelbase)
    lam, sigma = float(const.geometry.conicity), float(const.geometry.roll_coefficient)
    ratio = float(const.creep.f22 / const.creep.f11)
    c = 1 + (r0 + e0 * cone_slope) * sigma / e0
    classic = 2 * np.pi * np.sqrt(r0 * e0 / lam * (1 + ratio * (a / e0) ** 2))
    with_roll = 2 * np.pi * np.sqrt(r0 * e0 * c / lam * (1 + ratio * c**2 * (a / e0) ** 2))
    wavelength = speed / _lowest_oscillation_hz(eig_fn(p, speed))
    if cone_slope <= 0.025:
        assert abs(wavelength / classic - 1) < 0.03
    assert abs(wavelength / with_roll - 1) < 0.005


def test_hunting_onset_at_critical_speed(simulate_fn):
    """A 2 mm lateral offset decays at 0.9 x and grows at 1.1 x the linear critical speed."""
    p = _set(bj.manchester_benchmark(), **{"yaw_dampers.c": 0.0})
    crit = eqx.filter_jit(critical_speed)(p)
    assert bool(crit.found)
    v_crit = float(crit.speed)
    y0 = jnp.zeros(20).at[6].set(2e-3).at[7].set(2e-3)
    envelopes = {}
    for factor in (0.9, 1.1):
        traj = simulate_fn(p, factor * v_crit, y0, HUNT_DURATION)
        assert bool(traj.successful)
        y = np.abs(np.asarray(traj.q[:, 6]))
        envelopes[factor] = (y[100:200].max(), y[-100:].max())  # second 1 s vs last 1 s
    early, late = envelopes[0.9]
    assert late < 0.5 * early  # decaying
    early, late = envelopes[1.1]
    assert late > 2.0 * early  # growing
