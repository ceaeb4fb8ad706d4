# long: the contact package's oracles (geometry, Hertz tables, Kalker tables, creep
# saturation) kept in one file.
"""Tests of `bogie_jax.contact` against independent oracles.

Oracles: the printed tables of the physics reference doc (sections 1.2, 2.2, 2.4, 3.2), scipy's
elliptic integrals and an independent scipy (brentq) Hertz solver written here, closed forms
(circular contact), and finite differences (`jax.test_util.check_grads`).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads
from scipy import optimize, special

from bogie_jax import contact


# Everything runs jitted: it tests jit-compatibility and keeps compile time (op-by-op dispatch
# compiles every primitive separately) small.
CreepCoefficients = contact.CreepCoefficients
cone_geometry = jax.jit(contact.cone_geometry)
cone_on_rail_curvatures = jax.jit(contact.cone_on_rail_curvatures)
creep_coefficients = jax.jit(contact.creep_coefficients)
ellipe = jax.jit(contact.ellipe)
ellipk = jax.jit(contact.ellipk)
hertz_axis_ratio = jax.jit(contact.hertz_axis_ratio)
hertz_contact = jax.jit(contact.hertz_contact)
kalker_coefficients = jax.jit(contact.kalker_coefficients)
linear_creep_forces = jax.jit(contact.linear_creep_forces)
shear_modulus = jax.jit(contact.shear_modulus)
shen_hedrick_elkins = jax.jit(contact.shen_hedrick_elkins)


# ---------------------------------------------------------------------------------------------
# Geometry (reference doc 1.2)

# tan(delta0), lambda, sigma, eps (track plane), zeta [1/m], xi [m]; e0 = 0.75, r0 = 0.46, R_r = 0.3
GEOMETRY_TABLE = [
    (0.025, 0.0256, 0.0254, 0.0254, 0.0686, 0.0185),
    (0.05, 0.0526, 0.0516, 0.0517, 0.1413, 0.0364),
    (0.10, 0.1108, 0.1065, 0.1076, 0.3010, 0.0704),
    (0.15, 0.1750, 0.1652, 0.1689, 0.4830, 0.1022),
    (0.20, 0.2458, 0.2280, 0.2371, 0.6925, 0.1316),
    (0.30, 0.4099, 0.3676, 0.4007, 1.2203, 0.1836),
    (0.40, 0.6088, 0.5300, 0.6148, 1.9544, 0.2264),
]


@pytest.mark.parametrize("row", GEOMETRY_TABLE)
def test_cone_geometry_table(row):
    slope, *expected = row
    geo = cone_geometry(0.46, 0.75, slope, 0.3)
    got = [
        geo.conicity,
        geo.roll_coefficient,
        geo.contact_angle_coefficient,
        geo.vertical_lateral_coefficient,
        geo.vertical_yaw_coefficient,
    ]
    # Printed to 4 decimals: agree to half a unit in the last digit.
    np.testing.assert_allclose(got, expected, rtol=0, atol=0.5e-4 + 1e-12)
    assert np.isclose(geo.cone_angle, np.arctan(slope), rtol=1e-14)


def test_cone_geometry_knife_edge_batched():
    # R_r = 0: lambda = e0 t / (e0 - r0 t) (reference doc 1.2, knife-edge note).
    slopes = jnp.array([0.025, 0.1, 0.4])
    geo = cone_geometry(0.46, 0.75, slopes, 0.0)
    np.testing.assert_allclose(geo.conicity, 0.75 * slopes / (0.75 - 0.46 * slopes), rtol=1e-14)


# ---------------------------------------------------------------------------------------------
# Elliptic integrals

ELLIPTIC_M = np.concatenate(
    [-np.logspace(4, -8, 25), [0.0], np.linspace(1e-6, 0.999, 25), 1.0 - np.logspace(-4, -10, 4)]
)


def test_elliptic_integrals_match_scipy():
    np.testing.assert_allclose(ellipk(ELLIPTIC_M), special.ellipk(ELLIPTIC_M), rtol=1e-12)
    np.testing.assert_allclose(ellipe(ELLIPTIC_M), special.ellipe(ELLIPTIC_M), rtol=1e-12)
    assert ellipk(0) == pytest.approx(np.pi / 2, rel=1e-15)


def test_elliptic_integral_derivatives():
    # dK/dm = (E - (1-m) K) / (2 m (1-m)), dE/dm = (E - K) / (2m); limits pi/8, -pi/8 at m = 0.
    m = np.array([-20.0, -1.0, -1e-3, 1e-3, 0.3, 0.9, 0.999])
    k, e = special.ellipk(m), special.ellipe(m)
    both = jax.jit(jax.vmap(lambda x: (jax.grad(ellipk)(x), jax.grad(ellipe)(x))))
    dk, de = both(np.append(m, 0.0))
    np.testing.assert_allclose(dk[:-1], (e - (1 - m) * k) / (2 * m * (1 - m)), rtol=1e-9)
    np.testing.assert_allclose(de[:-1], (e - k) / (2 * m), rtol=1e-9)
    assert dk[-1] == pytest.approx(np.pi / 8, rel=1e-14)
    assert de[-1] == pytest.approx(-np.pi / 8, rel=1e-14)


# ---------------------------------------------------------------------------------------------
# Hertz (reference doc 3.1, 3.2)

# theta [deg], m, n, b/a
MN_TABLE = [
    (10, 6.6115, 0.3110, 0.0470),
    (20, 3.8160, 0.4121, 0.1080),
    (30, 2.7306, 0.4931, 0.1806),
    (40, 2.1357, 0.5673, 0.2656),
    (50, 1.7541, 0.6407, 0.3652),
    (60, 1.4858, 0.7171, 0.4826),
    (70, 1.2851, 0.7999, 0.6225),
    (80, 1.1278, 0.8927, 0.7915),
    (85, 1.0609, 0.9442, 0.8900),
    (90, 1.0000, 1.0000, 1.0000),
]


def _hertz_factor(force, curv_a, curv_b, young, nu):
    """Classical `K = [(3/2) N (1 - nu^2) / (E (A + B))]^(1/3)` [m] (reference doc 3.1)."""
    return (1.5 * force * (1 - nu**2) / (young * (curv_a + curv_b))) ** (1 / 3)


@pytest.mark.parametrize("row", MN_TABLE)
def test_hertz_mn_table(row):
    theta, m_ref, n_ref, ratio_ref = row
    cos_t = np.cos(np.radians(theta))
    curv_a, curv_b = 1.0, (1 + cos_t) / (1 - cos_t)  # cos(theta) = |B - A| / (A + B), B >= A
    force, young, nu = 1e4, 2e11, 0.3
    patch = hertz_contact(force, curv_a, curv_b, young, nu)
    factor = _hertz_factor(force, curv_a, curv_b, young, nu)
    np.testing.assert_allclose(patch.a / factor, m_ref, rtol=0.01)
    np.testing.assert_allclose(patch.b / factor, n_ref, rtol=0.01)
    np.testing.assert_allclose(patch.b / patch.a, ratio_ref, rtol=0.01)


def _scipy_hertz(force, curv_a, curv_b, young, nu):
    """Independent oracle: eccentricity by brentq, semi-axes by the classical m, n form."""
    ratio = max(curv_a, curv_b) / min(curv_a, curv_b)

    def residual(e2):
        k, e = special.ellipk(e2), special.ellipe(e2)
        return (e / (1 - e2) - k) / (k - e) - ratio

    e2 = optimize.brentq(residual, 1e-9, 1 - 1e-14, xtol=1e-16, rtol=1e-15, maxiter=500)
    m_coef = (2 * special.ellipe(e2) / (np.pi * (1 - e2))) ** (1 / 3)
    factor = _hertz_factor(force, curv_a, curv_b, young, nu)
    major, minor = m_coef * factor, m_coef * np.sqrt(1 - e2) * factor
    # The major semi-axis lies along the direction of the smaller curvature.
    return (major, minor) if curv_b >= curv_a else (minor, major)


@pytest.mark.parametrize(
    "force, curv_a, curv_b, young, nu",
    [
        (80e3, 1.0856, 1.6667, 210e9, 0.3),
        (1.0, 1.0, 30.0, 1.0, 0.0),
        (5e4, 1.0, 1.1, 2e11, 0.25),
        (5e4, 1.1, 1.0, 2e11, 0.25),
        (2e3, 10.0, 1.0, 7e10, 0.33),
        (2e5, 5.0, 0.5, 2.1e11, 0.28),
    ],
)
def test_hertz_semi_axes_match_scipy_oracle(force, curv_a, curv_b, young, nu):
    patch = hertz_contact(force, curv_a, curv_b, young, nu)
    a_ref, b_ref = _scipy_hertz(force, curv_a, curv_b, young, nu)
    np.testing.assert_allclose([patch.a, patch.b], [a_ref, b_ref], rtol=1e-8)


def test_hertz_circular_contact_closed_form():
    # A = B: circle, a^3 = 3 N R / (4 E*), R = 1/(2A), E* = E / (2 (1 - nu^2)); approach a^2/R.
    force, curv, young, nu = 3e4, 1.25, 2.1e11, 0.3
    patch = hertz_contact(force, curv, curv, young, nu)
    radius, e_star = 1 / (2 * curv), young / (2 * (1 - nu**2))
    a_ref = (3 * force * radius / (4 * e_star)) ** (1 / 3)
    np.testing.assert_allclose([patch.a, patch.b], [a_ref, a_ref], rtol=1e-13)
    np.testing.assert_allclose(patch.penetration, a_ref**2 / radius, rtol=1e-13)
    p0_ref = 3 * force / (2 * np.pi * a_ref**2)
    np.testing.assert_allclose(patch.peak_pressure, p0_ref, rtol=1e-13)


def test_hertz_worked_example():
    # Reference doc 3.2: r0 = 0.46, R_r = 0.3, tan(delta0) = 0.05, N = 80 kN, E = 210 GPa, nu = 0.3.
    curv_a, curv_b = cone_on_rail_curvatures(0.46, np.arctan(0.05), 0.3)
    np.testing.assert_allclose([curv_a, curv_b], [1.086, 1.667], atol=0.5e-3)
    theta = np.degrees(np.arccos(abs(curv_b - curv_a) / (curv_a + curv_b)))
    assert theta == pytest.approx(77.8, abs=0.05)
    patch = hertz_contact(80e3, curv_a, curv_b, 210e9, 0.3)
    np.testing.assert_allclose(patch.a, 6.65e-3, rtol=0.01)
    np.testing.assert_allclose(patch.b, 5.00e-3, rtol=0.01)
    np.testing.assert_allclose(patch.penetration, 90e-6, rtol=0.01)
    np.testing.assert_allclose(patch.peak_pressure, 1.15e9, rtol=0.01)


def test_hertz_force_scaling_and_symmetry():
    # a, b scale as N^(1/3) and the approach as N^(2/3) (reference doc 3.2).
    small = hertz_contact(1e3, 1.0, 2.5, 2.1e11, 0.3)
    large = hertz_contact(8e3, 1.0, 2.5, 2.1e11, 0.3)
    np.testing.assert_allclose([large.a / small.a, large.b / small.b], 2.0, rtol=1e-12)
    np.testing.assert_allclose(large.penetration / small.penetration, 4.0, rtol=1e-12)
    # Swapping A and B swaps a and b.
    swapped = hertz_contact(1e3, 2.5, 1.0, 2.1e11, 0.3)
    np.testing.assert_allclose([swapped.a, swapped.b], [small.b, small.a], rtol=1e-12)
    # hertz_axis_ratio against the scipy oracle, and a/b(1/r) = 1 / (a/b)(r).
    ratios = jnp.array([1e-3, 0.3, 1.0, 2.0, 1e3])
    expected = [np.divide(*_scipy_hertz(1.0, 1.0, r, 1.0, 0.0)) for r in (0.3, 2.0)]
    axis_ratios = np.asarray(hertz_axis_ratio(ratios))
    np.testing.assert_allclose(axis_ratios[1:4], [expected[0], 1.0, expected[1]], rtol=1e-8)
    product = axis_ratios * hertz_axis_ratio(1 / ratios)
    np.testing.assert_allclose(product, 1.0, rtol=1e-12)


@jax.jit
def _hertz_scaled(force_kn, curv_a, curv_b, young_gpa, nu):
    """Hertz outputs in mm, um and GPa of O(1) inputs, for finite differences."""
    c = hertz_contact(1e3 * force_kn, curv_a, curv_b, 1e9 * young_gpa, nu)
    return jnp.stack([1e3 * c.a, 1e3 * c.b, 1e6 * c.penetration, 1e-9 * c.peak_pressure])


@pytest.mark.parametrize(
    "args",
    [
        (80.0, 1.0856, 1.6667, 210.0, 0.3),
        (50.0, 1.3, 1.3, 200.0, 0.28),  # B/A = 1
        (5.0, 4.0, 0.7, 70.0, 0.33),  # B/A < 1
    ],
)
def test_hertz_gradients(args):
    check_grads(_hertz_scaled, args, order=1, modes=("fwd", "rev"))


def _jacobians(fn, *args):
    """Forward- and reverse-mode Jacobians of `fn` w.r.t. every argument (one jit)."""
    argnums = tuple(range(len(args)))
    both = lambda *x: (jax.jacfwd(fn, argnums)(*x), jax.jacrev(fn, argnums)(*x))
    return jax.jit(both)(*args)


def _all_finite(tree):
    return all(np.all(np.isfinite(leaf)) for leaf in jax.tree_util.tree_leaves(tree))


def test_hertz_loss_of_contact():
    for force in (0.0, -500.0):
        patch = hertz_contact(force, 1.0856, 1.6667, 210e9, 0.3)
        assert all(float(x) == 0.0 for x in (patch.a, patch.b, patch.penetration))
        assert float(patch.peak_pressure) == 0.0
    jac_fwd, jac_rev = _jacobians(_hertz_scaled, 0.0, 1.0856, 1.6667, 210.0, 0.3)
    assert _all_finite((jac_fwd, jac_rev))
    assert np.all(np.asarray(jac_fwd[0]) == 0.0) and np.all(np.asarray(jac_rev[0]) == 0.0)
    check_grads(_hertz_scaled, (-1.0, 1.0856, 1.6667, 210.0, 0.3), order=1)


# ---------------------------------------------------------------------------------------------
# Kalker (reference doc 2.2)

# a/b, C11 (nu = 0, .25, .5), C22 (same), C23 (same): Kalker 1990 Table E.3 as printed in 2.2.
KALKER_TABLE = [
    (0.1, 2.51, 3.31, 4.85, 2.51, 2.52, 2.53, 0.334, 0.473, 0.731),
    (0.2, 2.59, 3.37, 4.81, 2.59, 2.63, 2.66, 0.483, 0.603, 0.809),
    (0.3, 2.68, 3.44, 4.80, 2.68, 2.75, 2.81, 0.607, 0.715, 0.889),
    (0.4, 2.78, 3.53, 4.82, 2.78, 2.88, 2.98, 0.720, 0.823, 0.977),
    (0.5, 2.88, 3.62, 4.83, 2.88, 3.01, 3.14, 0.827, 0.929, 1.07),
    (0.6, 2.98, 3.72, 4.91, 2.98, 3.14, 3.31, 0.930, 1.03, 1.18),
    (0.7, 3.09, 3.81, 4.97, 3.09, 3.28, 3.48, 1.03, 1.14, 1.29),
    (0.8, 3.19, 3.91, 5.05, 3.19, 3.41, 3.65, 1.13, 1.25, 1.40),
    (0.9, 3.29, 4.01, 5.12, 3.29, 3.54, 3.82, 1.23, 1.36, 1.51),
    (1.0, 3.40, 4.12, 5.20, 3.40, 3.67, 3.98, 1.33, 1.47, 1.63),
    (1 / 0.9, 3.51, 4.22, 5.30, 3.51, 3.81, 4.16, 1.44, 1.59, 1.77),
    (1 / 0.8, 3.65, 4.36, 5.42, 3.65, 3.99, 4.39, 1.58, 1.75, 1.94),
    (1 / 0.7, 3.82, 4.54, 5.58, 3.82, 4.21, 4.67, 1.76, 1.95, 2.18),
    (1 / 0.6, 4.06, 4.78, 5.80, 4.06, 4.50, 5.04, 2.01, 2.23, 2.50),
    (1 / 0.5, 4.37, 5.10, 6.11, 4.37, 4.90, 5.56, 2.35, 2.62, 2.96),
    (1 / 0.4, 4.84, 5.57, 6.57, 4.84, 5.48, 6.31, 2.88, 3.24, 3.70),
    (1 / 0.3, 5.57, 6.34, 7.34, 5.57, 6.40, 7.51, 3.79, 4.32, 5.01),
    (1 / 0.2, 6.96, 7.78, 8.82, 6.96, 8.14, 9.79, 5.72, 6.63, 7.89),
    (1 / 0.1, 10.7, 11.7, 12.9, 10.7, 12.8, 16.0, 12.2, 14.6, 18.0),
]

# a/b, C11 (nu = .27 / .30), C22 (same), C23 (same): reference doc 2.2, CONTACT's 1/C rule.
KALKER_NU_TABLE = [
    (0.2, 3.453, 3.585, 2.633, 2.637, 0.615, 0.635),
    (0.4, 3.608, 3.730, 2.888, 2.900, 0.833, 0.849),
    (0.6, 3.794, 3.911, 3.153, 3.173, 1.040, 1.055),
    (0.8, 3.982, 4.095, 3.428, 3.456, 1.261, 1.277),
    (1.0, 4.190, 4.300, 3.693, 3.729, 1.482, 1.500),
    (1 / 0.8, 4.429, 4.537, 4.020, 4.065, 1.764, 1.786),
    (1 / 0.6, 4.848, 4.955, 4.539, 4.599, 2.250, 2.280),
    (1 / 0.4, 5.638, 5.744, 5.538, 5.628, 3.273, 3.323),
    (1 / 0.2, 7.854, 7.968, 8.252, 8.425, 6.716, 6.848),
]


@pytest.mark.parametrize("j, nu", [(0, 0.0), (1, 0.25), (2, 0.5)])
def test_kalker_table_nodes(j, nu):
    table = np.array(KALKER_TABLE)
    coeffs = np.stack(kalker_coefficients(table[:, 0], nu), axis=-1)
    expected = table[:, [1 + j, 4 + j, 7 + j]]
    np.testing.assert_allclose(coeffs, expected, rtol=0.01)


@pytest.mark.parametrize("k, nu", [(0, 0.27), (1, 0.30)])
def test_kalker_poisson_interpolation(k, nu):
    table = np.array(KALKER_NU_TABLE)
    coeffs = np.stack(kalker_coefficients(table[:, 0], nu), axis=-1)
    expected = table[:, [1 + k, 3 + k, 5 + k]]
    np.testing.assert_allclose(coeffs, expected, rtol=0.01)


@jax.jit
def _kalker_stacked(a_over_b, nu):
    return jnp.stack(kalker_coefficients(a_over_b, nu))


@pytest.mark.parametrize(
    "a_over_b, nu", [(0.1, 0.0), (0.5, 0.27), (1.33, 0.3), (4.0, 0.5), (20.0, 0.3)]
)
def test_kalker_gradients(a_over_b, nu):
    # Small step: at a/b = 0.1 the fit meets its linear continuation (C1, not C2).
    check_grads(_kalker_stacked, (a_over_b, nu), order=1, eps=1e-6)


def test_creep_coefficients_manchester_wheel():
    # Reference doc 2.4: one Manchester vehicle-1 wheel, 54.5 kN, r0 = 0.46, R_r = 0.3,
    # E = 210 GPa, nu = 0.3: a/b = 1.33, f11 ~ 9.6 MN, f22 ~ 8.7 MN, f23 ~ 20 kN m (rounded).
    curv_a, curv_b = cone_on_rail_curvatures(0.46, np.arctan(0.05), 0.3)
    patch = hertz_contact(54.5e3, curv_a, curv_b, 210e9, 0.3)
    np.testing.assert_allclose([patch.a, patch.b], [5.9e-3, 4.4e-3], rtol=0.01)
    assert patch.a / patch.b == pytest.approx(1.33, rel=0.005)
    coeffs = creep_coefficients(patch.a, patch.b, shear_modulus(210e9, 0.3), 0.3)
    np.testing.assert_allclose([coeffs.f11, coeffs.f22], [9.6e6, 8.7e6], rtol=0.05)
    np.testing.assert_allclose(coeffs.f23, 20e3, rtol=0.05)
    np.testing.assert_allclose(
        kalker_coefficients(patch.a / patch.b, 0.3), [4.62, 4.17, 1.88], rtol=0.01
    )


@jax.jit
def _creep_coefficients_scaled(a_mm, b_mm, g_gpa, nu):
    c = creep_coefficients(1e-3 * a_mm, 1e-3 * b_mm, 1e9 * g_gpa, nu)
    return jnp.stack([1e-6 * c.f11, 1e-6 * c.f22, 1e-3 * c.f23])


def test_creep_coefficients_gradients_and_loss_of_contact():
    check_grads(_creep_coefficients_scaled, (5.9, 4.4, 80.8, 0.3), order=1)
    zero = creep_coefficients(0.0, 0.0, 8.08e10, 0.3)
    assert all(float(f) == 0.0 for f in (zero.f11, zero.f22, zero.f23))
    assert _all_finite(_jacobians(_creep_coefficients_scaled, 0.0, 0.0, 80.8, 0.3))


# ---------------------------------------------------------------------------------------------
# Creep forces (reference doc 2.1)

COEFFS = CreepCoefficients(f11=jnp.asarray(9.6e6), f22=jnp.asarray(8.7e6), f23=jnp.asarray(2.0e4))


def test_linear_creep_forces():
    fx, fy = linear_creep_forces(1e-3, -2e-3, 0.05, COEFFS)
    assert float(fx) == pytest.approx(-9.6e3, rel=1e-14)
    assert float(fy) == pytest.approx(2 * 8.7e3 - 1e3, rel=1e-14)


def _she_oracle(fx, fy, normal_force, friction):
    """Shen-Hedrick-Elkins written directly from reference doc 2.1 (numpy)."""
    f_lin = np.hypot(fx, fy)
    u = f_lin / (friction * normal_force)
    f = friction * normal_force * (u - u**2 / 3 + u**3 / 27) if u < 3 else friction * normal_force
    return fx * f / f_lin, fy * f / f_lin


@pytest.mark.parametrize(
    "fx, fy", [(100.0, 0.0), (3e3, -4e3), (-9e3, 1.2e4), (1.2e4, 1.6e4), (-6e4, 8e4), (0.0, 2e5)]
)
def test_shen_hedrick_elkins_values(fx, fy):
    got = shen_hedrick_elkins(fx, fy, 5e4, 0.3)
    np.testing.assert_allclose(got, _she_oracle(fx, fy, 5e4, 0.3), rtol=1e-13)
    assert np.hypot(*got) <= 0.3 * 5e4 * (1 + 1e-14)


@jax.jit
def _she_stacked(fx, fy, normal_force, friction):
    return jnp.stack(shen_hedrick_elkins(fx, fy, normal_force, friction))


def test_shen_hedrick_elkins_degenerate_cases():
    assert [float(f) for f in shen_hedrick_elkins(0.0, 0.0, 5e4, 0.3)] == [0.0, 0.0]
    for force in (0.0, -1e3):
        assert [float(f) for f in shen_hedrick_elkins(3e3, -4e3, force, 0.3)] == [0.0, 0.0]
    # Gradients finite at zero creep force and at zero normal force; identity at zero force.
    for args in [(0.0, 0.0, 50.0, 0.3), (3.0, -4.0, 0.0, 0.3), (0.0, 0.0, 0.0, 0.3)]:
        jac_fwd, jac_rev = _jacobians(_she_stacked, *args)
        assert _all_finite((jac_fwd, jac_rev))
        if args[2] > 0.0:  # zero creep force: the saturation is the identity to first order
            for jac in (jac_fwd, jac_rev):
                np.testing.assert_allclose(np.stack(jac[:2], axis=-1), np.eye(2), atol=1e-15)


@pytest.mark.parametrize(
    "args",
    [
        (0.0, 0.0, 50.0, 0.3),  # zero creep force
        (3.0, -4.0, 50.0, 0.3),  # u = 1/3
        (27.0, -36.0, 50.0, 0.3),  # u = 3 (branch switch, C1)
        (60.0, 80.0, 50.0, 0.3),  # saturated
        (3.0, -4.0, -5.0, 0.3),  # lost contact
    ],
)
def test_shen_hedrick_elkins_gradients(args):
    check_grads(_she_stacked, args, order=1, modes=("fwd", "rev"))


def test_linear_creep_gradients_at_zero_creepage():
    @jax.jit
    def forces(xi_x, xi_y, xi_sp):
        fx, fy = linear_creep_forces(xi_x, xi_y, xi_sp, COEFFS)
        return 1e-6 * jnp.stack(shen_hedrick_elkins(fx, fy, 5e4, 0.3))

    check_grads(forces, (0.0, 0.0, 0.0), order=1, modes=("fwd", "rev"), eps=1e-9)
    jac = np.stack(jax.jit(jax.jacrev(forces, argnums=(0, 1, 2)))(0.0, 0.0, 0.0), axis=-1)
    expected = 1e-6 * np.array([[-9.6e6, 0.0, 0.0], [0.0, -8.7e6, -2e4]])
    np.testing.assert_allclose(jac, expected, rtol=1e-14)
