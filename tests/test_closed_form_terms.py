"""The closed-form terms of the equations of motion against their definitions evaluated by
automatic differentiation: inertia terms against Lagrange's equations applied to the kinetic
energy (paper eq. 6, 7, 11), creep generalised forces against the virtual power of the creep
forces, Q = (dv_c/dp_dot)^T F (paper eq. 8)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import bogie_jax as bj
from bogie_jax.contact import linear_creep_forces, shen_hedrick_elkins
from bogie_jax.model import (
    contact_generalised_forces,
    contact_velocities,
    creepages,
    frame_rotation_terms,
    kinematics as kin,
    model_constants,
    scaled_creep_coefficients,
    wheelset_terms,
)
from bogie_jax.params import ModelOptions


def lagrange_terms(energy, p, pd, extra, extra_rate):
    """M = d^2T/dpd^2 and h = d/dt(dT/dpd)|_{p_ddot=0} - dT/dp of `energy(p, pd, extra)`."""
    momentum = jax.grad(energy, argnums=1)
    mass = jax.jacfwd(momentum, argnums=1)(p, pd, extra)
    _, rate = jax.jvp(momentum, (p, pd, extra), (pd, jnp.zeros_like(pd), extra_rate))
    return mass, rate - jax.grad(energy, argnums=0)(p, pd, extra)


def frame_energy(angles, rates, inertia):
    omega = kin.frame_body_rates_matrix(angles) @ rates
    return 0.5 * jnp.sum(inertia * omega**2)


def wheelset_energy(p, pd, track, params, const, spin):
    """T of paper eq. 7: translation of the centre (y, z(y, psi, w)) and rotation with the spin,
    from the kinematics (z rate and angular velocity by differentiation of the constraints)."""
    w, wd = track
    m = params.masses.wheelset
    inertia = jnp.stack([m.ixx, m.iyy, m.izz])
    _, z_rate = jax.jvp(
        lambda p_, w_: kin.height(p_[0], p_[1], w_, params, const), (p, w), (pd, wd)
    )
    omega = kin.angular_velocity(p[0], p[1], pd[0], pd[1], w, wd, params, const, spin)
    omega_body = kin.rotation(p[0], p[1], w, params, const).T @ omega
    return 0.5 * m.mass * (pd[0] ** 2 + z_rate**2) + 0.5 * jnp.sum(inertia * omega_body**2)


@pytest.fixture(scope="module")
def params():
    p = bj.manchester_benchmark()
    # unequal wheelset inertias, so every gyroscopic term is exercised
    return eqx.tree_at(lambda q: q.masses.wheelset.izz, p, 1.3 * p.masses.wheelset.izz)


def test_frame_rotation_terms_match_lagrange(params):
    rng = np.random.default_rng(0)
    inertia = jnp.stack([params.masses.frame.ixx, params.masses.frame.iyy, params.masses.frame.izz])
    for _ in range(5):
        angles, rates = jnp.asarray(rng.normal(0, 0.3, 3)), jnp.asarray(rng.normal(0, 2.0, 3))
        mass, h = frame_rotation_terms(angles, rates, params)
        ref_m, ref_h = lagrange_terms(
            lambda a, ad, _: frame_energy(a, ad, inertia), angles, rates, (), ()
        )
        np.testing.assert_allclose(mass, ref_m, rtol=1e-12, atol=1e-12 * float(jnp.max(inertia)))
        np.testing.assert_allclose(
            h, ref_h, rtol=1e-10, atol=1e-10 * float(jnp.max(jnp.abs(ref_h)))
        )


def test_wheelset_terms_match_lagrange(params):
    const = model_constants(params)
    spin = 50.0 / params.contact.wheel_radius
    rng = np.random.default_rng(1)
    for _ in range(5):
        p, pd = jnp.asarray(rng.normal(0, [4e-3, 5e-3])), jnp.asarray(rng.normal(0, [0.2, 0.3]))
        w, wd, wdd = (
            jnp.asarray(rng.normal(0, s * np.array([1e-3, 1e-3, 1e-3]))) for s in (1, 50, 2500)
        )
        mass, h = wheelset_terms(p, pd, w, wd, wdd, params, const, spin)
        ref_m, ref_h = lagrange_terms(
            lambda p_, pd_, tr: wheelset_energy(p_, pd_, tr, params, const, spin),
            p,
            pd,
            (w, wd),
            (wd, wdd),
        )
        np.testing.assert_allclose(
            mass, ref_m, rtol=1e-12, atol=1e-12 * float(jnp.max(jnp.abs(ref_m)))
        )
        np.testing.assert_allclose(h, ref_h, rtol=1e-9, atol=1e-10 * float(jnp.max(jnp.abs(ref_h))))


@pytest.mark.parametrize("saturation", [False, True])
def test_creep_generalised_forces_match_virtual_power(params, saturation):
    const = model_constants(params)
    options = ModelOptions(creep_saturation=saturation)
    speed, x = 50.0, params.geometry.semi_wheelbase
    spin = speed / params.contact.wheel_radius
    rng = np.random.default_rng(2)
    for _ in range(4):
        p, pd = jnp.asarray(rng.normal(0, [4e-3, 5e-3])), jnp.asarray(rng.normal(0, [0.05, 0.05]))
        w, wd = jnp.asarray(rng.normal(0, 1e-3, 3)), jnp.asarray(rng.normal(0, 5e-2, 3))
        loads = jnp.asarray(rng.uniform(5e4, 9e4, 2))
        q = contact_generalised_forces(p, pd, w, wd, x, loads, params, const, options, speed)
        # the contact forces, then their virtual power by a pullback of the contact velocities
        velocity_of = lambda v: contact_velocities(p, v, w, wd, x, params, const, speed)
        velocity, pullback = jax.vjp(velocity_of, pd)
        omega = kin.angular_velocity(p[0], p[1], pd[0], pd[1], w, wd, params, const, spin)
        normals = kin.contact_normals(p[0], w, params, const)
        xi = creepages(velocity, omega, normals, speed)
        fx, fy = linear_creep_forces(*xi, scaled_creep_coefficients(loads, const))
        if saturation:
            fx, fy = shen_hedrick_elkins(fx, fy, loads, params.contact.friction)
        forces = fx[:, None] * kin.E_X + fy[:, None] * jnp.cross(normals, kin.E_X)
        ref = pullback(forces)[0]
        np.testing.assert_allclose(q, ref, rtol=1e-10, atol=1e-10 * float(jnp.max(jnp.abs(ref))))
