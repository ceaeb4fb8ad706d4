"""Hertz normal contact of two bodies of the same elastic material (reference doc 3.1).

Contains pure-JAX complete elliptic integrals (arithmetic-geometric mean), the solver for the
semi-axis ratio of the contact ellipse, and the contact patch itself.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike


# AGM steps: the AGM converges quadratically; 10 steps give ~1e-15 relative accuracy for
# parameters -1e6 < m < 1 - 1e-12, far beyond any contact ellipse met in practice.
_AGM_STEPS = 10
# Newton steps on u = ln(a/b): ln(B/A) is increasing and nearly linear in u, and from the start
# (2/3) ln(B/A) 6 steps reach machine precision for 1e-6 < B/A < 1e6 (checked).
_NEWTON_STEPS = 6


def _agm(m: Array, m_complement: Array) -> tuple[Array, Array]:
    """Return `K(m)` and `P(m) = (K(m) - E(m)) / (m K(m))` by the AGM, for `m < 1`.

    `m_complement = 1 - m` is passed separately so that callers who know it exactly keep full
    accuracy as `m -> 1`. Abramowitz & Stegun 17.6: with `a0 = 1`, `b0 = sqrt(1 - m)`, `c0^2 = m`,
    `K = pi / (2 a_inf)` and `E = K (1 - sum_n 2^(n-1) c_n^2)`. The terms are carried as
    `q_n = c_n^2 / m` through `c_(n+1) = c_n^2 / (4 a_(n+1))`, so `P = sum_n 2^(n-1) q_n` stays
    finite (and differentiable) at `m = 0`, where `P = 1/2`. Valid for negative `m` too.
    """

    def step(n, carry):
        a, b, q, p = carry
        a_next = 0.5 * (a + b)
        q = m * q**2 / (16.0 * a_next**2)
        return a_next, jnp.sqrt(a * b), q, p + 2.0 ** (n - 1) * q

    ones = jnp.ones_like(m)
    init = (ones, jnp.sqrt(m_complement), ones, 0.5 * ones)
    a, _, _, p = jax.lax.fori_loop(1, _AGM_STEPS + 1, step, init)
    return jnp.pi / (2.0 * a), p


def ellipk(m: ArrayLike) -> Array:
    """Complete elliptic integral of the first kind `K(m)`, parameter `m = k^2 < 1`.

    Same convention as `scipy.special.ellipk`. Pure JAX (AGM, Abramowitz & Stegun 17.6),
    differentiable in `m`.
    """
    m = jnp.asarray(m, dtype=jnp.result_type(m, float))
    k, _ = _agm(m, 1.0 - m)
    return k


def ellipe(m: ArrayLike) -> Array:
    """Complete elliptic integral of the second kind `E(m)`, parameter `m = k^2 < 1`.

    Same convention as `scipy.special.ellipe`. Pure JAX (AGM, Abramowitz & Stegun 17.6),
    differentiable in `m`.
    """
    m = jnp.asarray(m, dtype=jnp.result_type(m, float))
    k, p = _agm(m, 1.0 - m)
    return k * (1.0 - m * p)


def _log_curvature_ratio(u: Array) -> Array:
    """`ln(B/A)` of the gap `A x^2 + B y^2` whose Hertz ellipse has `ln(a/b) = u`.

    Reference doc 3.1: `B/A = (E/(1-e^2) - K) / (K - E)` with `e^2 = 1 - (b/a)^2`. Written with
    `P = (K - E)/(e^2 K)` this is `B/A = (1 - P) / ((1 - e^2) P)`, free of the 0/0 at `a = b`.
    It is analytic in `u` and holds for `a < b` (`e^2 < 0`) by analytic continuation, so one
    formula covers `B/A` below, at and above 1.
    """
    _, p = _agm(-jnp.expm1(-2.0 * u), jnp.exp(-2.0 * u))
    return 2.0 * u + jnp.log1p(-p) - jnp.log(p)


@jax.custom_jvp
def _log_axis_ratio(log_curvature_ratio: Array) -> Array:
    """Solve `_log_curvature_ratio(u) = ln(B/A)` for `u = ln(a/b)` by fixed-step Newton.

    Starts from the approximation `a/b = (B/A)^(2/3)` (reference doc 3.2). Derivatives come from
    the implicit function theorem, `du/d ln(B/A) = 1 / Phi'(u)` (custom JVP, so reverse mode and
    higher orders work too), not from differentiating the Newton iterations.
    """

    def step(_, u):
        value, slope = jax.jvp(_log_curvature_ratio, (u,), (jnp.ones_like(u),))
        return u - (value - log_curvature_ratio) / slope

    return jax.lax.fori_loop(0, _NEWTON_STEPS, step, (2.0 / 3.0) * log_curvature_ratio)


@_log_axis_ratio.defjvp
def _log_axis_ratio_jvp(primals, tangents):
    (log_curvature_ratio,), (tangent,) = primals, tangents
    u = _log_axis_ratio(log_curvature_ratio)
    _, slope = jax.jvp(_log_curvature_ratio, (u,), (jnp.ones_like(u),))
    return u, tangent / slope


def hertz_axis_ratio(curvature_ratio: ArrayLike) -> Array:
    """Semi-axis ratio `a/b` of the Hertz contact ellipse for the gap `h = A x^2 + B y^2`.

    Solves the eccentricity equation of reference doc 3.1,
    `B/A = (E(e)/(1-e^2) - K(e)) / (K(e) - E(e))`, `b/a = sqrt(1 - e^2)`, for any `B/A > 0`
    (above, at or below 1). The unknown is `u = ln(a/b)`, smooth and odd in `ln(B/A)`.

    **Arguments:**

    - `curvature_ratio`: `B/A` > 0 [-], lateral over rolling relative curvature.

    **Returns:**

    `a/b` [-], `a` along `x` (the direction of curvature `A`), `b` along `y`.
    """
    log_ratio = jnp.log(jnp.asarray(curvature_ratio))
    return jnp.exp(_log_axis_ratio(log_ratio))


def cone_on_rail_curvatures(
    rolling_radius: ArrayLike, contact_angle: ArrayLike, rail_head_radius: ArrayLike
) -> tuple[Array, Array]:
    """Relative curvatures `A, B` [1/m] of a cone on a circular rail head (reference doc 3.1).

    The gap is `h = A x^2 + B y^2` with `A = cos(delta) / (2 r)` (wheel curvature in the rolling
    direction `x`; the rail is straight) and `B = 1 / (2 R_r)` (lateral `y`; the cone generator is
    straight).

    **Arguments:**

    - `rolling_radius`: wheel rolling radius `r` [m].
    - `contact_angle`: contact angle `delta` [rad].
    - `rail_head_radius`: rail head crown radius `R_r` [m].

    **Returns:**

    `(A, B)` [1/m].
    """
    curvature_rolling = jnp.cos(contact_angle) / (2.0 * jnp.asarray(rolling_radius))
    curvature_lateral = 0.5 / jnp.asarray(rail_head_radius)
    return curvature_rolling, jnp.broadcast_to(curvature_lateral, jnp.shape(curvature_rolling))


class HertzContact(eqx.Module):
    """Hertzian contact ellipse (reference doc 3.1). All zero when out of contact.

    - `a`: semi-axis in the rolling direction [m].
    - `b`: lateral semi-axis [m].
    - `penetration`: approach of the two bodies (normal compression) [m].
    - `peak_pressure`: maximum contact pressure `p0 = 3N / (2 pi a b)` [Pa].
    """

    a: Array
    b: Array
    penetration: Array
    peak_pressure: Array


def hertz_contact(
    normal_force: ArrayLike,
    curvature_rolling: ArrayLike,
    curvature_lateral: ArrayLike,
    young_modulus: ArrayLike,
    poisson_ratio: ArrayLike,
) -> HertzContact:
    """Hertz contact ellipse of two bodies of the same elastic material (reference doc 3.1).

    With `E* = E / (2 (1 - nu^2))`, `g = b/a` from [`hertz_axis_ratio`][] and `m = 1 - g^2`
    (CONTACT `hzcalc3d` form, reconciled with the classical `m, n` form in reference doc 3.1):

    - `b^3 = 3 N g E(m) / (2 pi E* (A + B))`, `a = b / g`
    - `penetration = (A + B) b^2 K(m) / E(m)`, `p0 = 3 N / (2 pi a b)`

    These hold for `a < b` too (then `m < 0`, by analytic continuation). A normal force `N <= 0`
    (loss of contact) gives all zeros, with finite (zero) gradients.

    **Arguments:**

    - `normal_force`: normal load `N` [N].
    - `curvature_rolling`: relative curvature `A` > 0 in the rolling direction [1/m].
    - `curvature_lateral`: relative curvature `B` > 0 in the lateral direction [1/m].
    - `young_modulus`: Young's modulus `E` of both bodies [Pa].
    - `poisson_ratio`: Poisson's ratio `nu` of both bodies [-].

    **Returns:**

    A [`HertzContact`][].
    """
    force = jnp.asarray(normal_force)
    curv_a = jnp.asarray(curvature_rolling)
    curv_b = jnp.asarray(curvature_lateral)
    e_star = young_modulus / (2.0 * (1.0 - jnp.square(poisson_ratio)))
    u = _log_axis_ratio(jnp.log(curv_b / curv_a))
    m = -jnp.expm1(-2.0 * u)
    k_m, p = _agm(m, jnp.exp(-2.0 * u))
    e_m = k_m * (1.0 - m * p)
    curv_sum = curv_a + curv_b
    # Double-where: evaluate the powers at a harmless force when out of contact.
    in_contact = force > 0.0
    safe_force = jnp.where(in_contact, force, 1.0)
    b = jnp.cbrt(3.0 * safe_force * jnp.exp(-u) * e_m / (2.0 * jnp.pi * e_star * curv_sum))
    a = b * jnp.exp(u)
    penetration = curv_sum * b**2 * k_m / e_m
    peak_pressure = 3.0 * safe_force / (2.0 * jnp.pi * a * b)
    zero = jnp.zeros_like(b)
    return HertzContact(
        a=jnp.where(in_contact, a, zero),
        b=jnp.where(in_contact, b, zero),
        penetration=jnp.where(in_contact, penetration, zero),
        peak_pressure=jnp.where(in_contact, peak_pressure, zero),
    )
