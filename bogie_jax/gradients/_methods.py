"""Gradients of the least-squares objective by every method of paper sections 5.2-5.3.

| method | how | AD mode |
| --- | --- | --- |
| `"reverse"` | reverse-mode AD through the solver, `RecursiveCheckpointAdjoint` | rev |
| `"backsolve"` | continuous adjoint (the paper's adjoint-state method), `BacksolveAdjoint` | rev |
| `"forward"` | forward-mode AD through the solver, `ForwardMode` + `jax.jacfwd` | fwd |
| `"direct"` | `DirectAdjoint`; its reverse mode is inaccurate here (see below) | fwd (or rev) |
| `"fd-forward"`, `"fd-central"` | finite differences (paper eq. 13), step rule below | - |

Reverse mode costs a few forward solves whatever the number of parameters n; forward mode pushes
one tangent per parameter (cost grows with n, slowly while the tangents vectorise); finite
differences cost n (forward) or 2n (central) solves.

Finite-difference steps, per parameter i (Nocedal & Wright, Numerical Optimization, 8.1):
`h_i = eps^(1/2) * max(|theta_i|, typical_scale)` (forward) and
`h_i = eps^(1/3) * max(|theta_i|, typical_scale)` (central), where `eps` is the relative accuracy
of J: by default the larger of machine epsilon and the `rtol` of the solve's step-size controller
(an adaptive solve is only that accurate), and `typical_scale` = 1 (theta is a log or logit
coordinate). Each h_i is then rounded so that theta_i + h_i - theta_i == h_i exactly.
"""

from collections.abc import Callable
from typing import NamedTuple

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from ..cost import Objective, residual_jacobian
from ..runtime.solve_settings import full_checkpoints, traced_tolerances


class _Method(NamedTuple):
    adjoint: Callable[[int, object], dfx.AbstractAdjoint]  # (max_steps, controller) -> adjoint
    modes: tuple[str, ...]  # supported AD modes, the default first


def seminorm_backsolve(max_steps: int, controller=None) -> dfx.BacksolveAdjoint:
    """`BacksolveAdjoint` whose backward solve controls the error of the state and its adjoint
    only (`diffrax.adjoint_rms_seminorm`; Kidger, Chen & Lyons 2021, "Hey, that's not an ODE").

    The parameter adjoints are integrals of the solution and need no step control; with the
    full norm the backward pass resolves them (39 parameter leaves of very different scales) and
    costs hundreds of forward solves. Tolerances are those of the
    forward `controller` (a `PIDController`; other controllers are used as they are).
    """
    del max_steps
    if isinstance(controller, dfx.PIDController):
        controller = eqx.tree_at(lambda c: c.norm, controller, dfx.adjoint_rms_seminorm)
        return dfx.BacksolveAdjoint(stepsize_controller=controller)
    return dfx.BacksolveAdjoint()


AD_METHODS = {
    "reverse": _Method(full_checkpoints, ("rev",)),
    "backsolve": _Method(seminorm_backsolve, ("rev",)),
    "forward": _Method(lambda *_: dfx.ForwardMode(), ("fwd",)),
    "direct": _Method(lambda *_: dfx.DirectAdjoint(), ("fwd", "rev")),
}
FD_METHODS = {"fd-forward": 1 / 2, "fd-central": 1 / 3}  # method -> exponent of eps in h
METHODS = (*AD_METHODS, *FD_METHODS)
_ADJOINT_NAMES = {
    dfx.RecursiveCheckpointAdjoint: "reverse",
    dfx.BacksolveAdjoint: "backsolve",
    dfx.ForwardMode: "forward",
    dfx.DirectAdjoint: "direct",
}


class GradientResult(eqx.Module):
    """`value` = J(theta), `grad` = dJ/dtheta (n,), `jacobian` = dr/dtheta (m, n) or None,
    `residuals` r(theta) (m,); `method` and `mode` ("fwd", "rev" or "fd") that produced them."""

    value: jax.Array
    grad: jax.Array
    residuals: jax.Array
    jacobian: jax.Array | None
    method: str = eqx.field(static=True)
    mode: str = eqx.field(static=True)


def resolve_method(
    method, mode: str | None = None, max_steps: int = 16_384, controller=None
) -> tuple[str, dfx.AbstractAdjoint | None, str]:
    """`(name, adjoint, mode)` for a method name or a diffrax adjoint instance (`max_steps`
    sizes the checkpoints of `"reverse"`; `controller`, the forward solve's step-size
    controller, sets the tolerances of the `"backsolve"` backward pass).

    **Raises:** `ValueError` for an unknown method, an unsupported adjoint, or a mode the method
    cannot do (e.g. forward mode through `RecursiveCheckpointAdjoint`).
    """
    if isinstance(method, dfx.AbstractAdjoint):
        name = _ADJOINT_NAMES.get(type(method))
        if name is None:
            raise ValueError(
                f"unsupported adjoint {type(method).__name__} for `method`; supported: "
                + ", ".join(c.__name__ for c in _ADJOINT_NAMES)
            )
        adjoint = method
    elif method in FD_METHODS:
        if mode is not None:
            raise ValueError(f"`mode` applies to AD methods only, not to {method!r}")
        return method, None, "fd"
    elif method in AD_METHODS:
        name, adjoint = method, AD_METHODS[method].adjoint(max_steps, controller)
    else:
        raise ValueError(f"unknown `method` {method!r}; valid: {', '.join(METHODS)}")
    modes = AD_METHODS[name].modes
    mode = modes[0] if mode is None else mode
    if mode not in ("fwd", "rev"):
        raise ValueError(f"`mode` must be 'fwd' or 'rev', got {mode!r}")
    if mode not in modes:
        raise ValueError(
            f"method {name!r} ({type(adjoint).__name__}) cannot differentiate in {mode!r} mode; "
            f"it supports {' and '.join(repr(m) for m in modes)} (use 'forward' or 'direct' for "
            "forward mode, 'reverse', 'backsolve' or 'direct' for reverse mode)"
        )
    return name, adjoint, mode


def _resolve_for(objective: Objective, method, mode):
    settings = objective.settings
    return resolve_method(method, mode, settings.max_steps, settings.stepsize_controller)


# ------------------------------------------------------------------------------ compiled cores
@eqx.filter_jit
def _residuals(objective: Objective, theta):
    return objective.residuals(theta)


@eqx.filter_jit
def _vjp_theta(objective: Objective, theta, cotangent, alpha):
    """r (m,) and J^T (cotangent + alpha r) (n,)."""
    r, pullback = jax.vjp(objective.residuals, theta)
    return r, pullback(cotangent + jnp.where(alpha != 0, alpha * r, 0.0))[0]


_jacobian = eqx.filter_jit(residual_jacobian)  # the library's one residual Jacobian, compiled
compiled_residuals = _residuals  # r(theta), compiled once per objective structure
residuals_and_pullback = _vjp_theta  # (r, J^T (cotangent + alpha r)), compiled likewise
compiled_jacobian = _jacobian  # (r, dr/dtheta) in forward mode, compiled likewise


@eqx.filter_jit
def _jacrev_theta(objective: Objective, theta):
    return objective.residuals(theta), jax.jacrev(objective.residuals)(theta)


# ------------------------------------------------------------------------------- entry points
def gradient(
    objective: Objective,
    theta,
    *,
    method="reverse",
    mode: str | None = None,
    jacobian: bool = False,
    rel_noise: float | None = None,
    typical_scale: float = 1.0,
) -> GradientResult:
    """J(theta) and dJ/dtheta (and, with `jacobian=True`, the residual Jacobian dr/dtheta).

    **Arguments:**
    - `method`: a name of `METHODS` or a diffrax adjoint instance (e.g.
      `diffrax.BacksolveAdjoint(solver=...)`); it replaces the objective's `adjoint`.
    - `mode`: "fwd" or "rev" for AD methods that support both (`"direct"`); default per method.
    - `jacobian`: also return dr/dtheta (forward mode: free; reverse mode: one reverse pass per
      residual, which is slow for many residuals, see `jacobian_by_mode`).
    - `rel_noise`, `typical_scale`: the finite-difference step rule (module docstring).

    AD methods are pure JAX (usable under `jit`/`vmap`); finite differences evaluate the
    compiled residuals parameter by parameter and need a concrete `theta`.

    **Raises:** `ValueError` for unknown or unsupported method/mode combinations, `TypeError`
    for finite differences under a JAX transformation.
    """
    name, adjoint, mode = _resolve_for(objective, method, mode)
    theta = jnp.asarray(theta, dtype=float)
    if mode == "fd":
        return _finite_differences(objective, theta, name, jacobian, rel_noise, typical_scale)
    objective = objective.with_adjoint(adjoint)
    if mode == "fwd":
        r, jac = _jacobian(objective, theta)
        grad = jac.T @ r
    elif jacobian:
        r, jac = _jacrev_theta(objective, theta)
        grad = jac.T @ r
    else:
        r, grad = _vjp_theta(objective, theta, jnp.zeros(objective.n_residuals), jnp.ones(()))
        jac = None
    return GradientResult(0.5 * jnp.sum(r**2), grad, r, jac if jacobian else None, name, mode)


def jacobian_by_mode(objective: Objective, theta, *, mode: str | None = None) -> GradientResult:
    """The residual Jacobian dr/dtheta (m, n) as a `GradientResult`, by forward or reverse AD, to
    compare the two modes (fits and statistics use `bogie_jax.cost.residual_jacobian`, which this
    calls in forward mode).

    Default `mode`: forward (`ForwardMode` + one tangent per parameter) when
    n_residuals >= n_params, which is every realistic measurement; reverse (one reverse pass per
    residual) otherwise.
    """
    if mode is None:
        mode = default_jacobian_mode(objective.n_residuals, objective.n_params)
    method = {"fwd": "forward", "rev": "reverse"}.get(mode)
    if method is None:
        raise ValueError(f"`mode` must be 'fwd' or 'rev', got {mode!r}")
    return gradient(objective, theta, method=method, jacobian=True)


def default_jacobian_mode(n_residuals: int, n_params: int) -> str:
    """ "fwd" (one tangent per parameter) unless there are fewer residuals than parameters."""
    return "fwd" if n_residuals >= n_params else "rev"


# -------------------------------------------------------------------------- finite differences
def fd_steps(theta, exponent: float, rel_noise: float, typical_scale: float = 1.0) -> np.ndarray:
    """Per-parameter steps h_i = rel_noise^exponent * max(|theta_i|, typical_scale), rounded so
    that (theta_i + h_i) - theta_i == h_i."""
    theta = np.asarray(theta, dtype=float)
    h = rel_noise**exponent * np.maximum(np.abs(theta), typical_scale)
    return (theta + h) - theta


def default_rel_noise(objective: Objective) -> float:
    """Relative accuracy of J: max(machine epsilon, rtol of the step-size controller)."""
    rtol = getattr(objective.settings.stepsize_controller, "rtol", 0.0)
    return max(float(np.finfo(float).eps), float(rtol))


def _finite_differences(objective, theta, name, jacobian, rel_noise, typical_scale):
    if isinstance(theta, jax.core.Tracer):
        raise TypeError(
            f"{name!r} evaluates the compiled residuals point by point and needs a concrete "
            "`theta`; use an AD method under jit/vmap"
        )
    rel_noise = default_rel_noise(objective) if rel_noise is None else float(rel_noise)
    h = fd_steps(theta, FD_METHODS[name], rel_noise, typical_scale)
    res = lambda th: np.asarray(_residuals(objective, jnp.asarray(th)))
    base = np.asarray(theta)
    r0 = res(base)
    cols = []
    for i, step in enumerate(h):
        e = np.zeros_like(base)
        e[i] = step
        if name == "fd-forward":
            cols.append((res(base + e), r0, step))
        else:
            cols.append((res(base + e), res(base - e), 2 * step))
    cost = lambda r: 0.5 * float(np.sum(r**2))
    grad = np.array([(cost(a) - cost(b)) / d for a, b, d in cols])
    jac = np.stack([(a - b) / d for a, b, d in cols], axis=1) if jacobian else None
    return GradientResult(
        jnp.asarray(cost(r0)),
        jnp.asarray(grad),
        jnp.asarray(r0),
        None if jac is None else jnp.asarray(jac),
        name,
        "fd",
    )


# ------------------------------------------------------------------------- scalar-product test
class ScalarProductTest(eqx.Module):
    """<J v_j, w> (`lhs`) against <v_j, J^T w> (`rhs`) for k random directions v_j and one
    random w; `rel_error` = max_j |lhs_j - rhs_j| / max_j max(|lhs_j|, |rhs_j|)."""

    lhs: jax.Array
    rhs: jax.Array
    rel_error: jax.Array


def scalar_product_test(
    objective: Objective, theta, *, key, n_directions: int | None = None, method="reverse"
) -> ScalarProductTest:
    """The scalar-product test of paper section 5.3 (Kern 2003), through the solver.

    J v comes from forward mode (`ForwardMode`: the forward Jacobian J, one tangent per
    parameter, the program `gradient(..., method="forward")` compiles, times v), J^T w from the
    reverse-mode `method` (default `RecursiveCheckpointAdjoint`). Both differentiate the same
    discrete solve, so they agree to rounding (about 1e-12 in float64); `"backsolve"` is the
    continuous adjoint and agrees only to the solver tolerance. `n_directions` defaults to n.
    """
    name, adjoint, mode = _resolve_for(objective, method, "rev")
    theta = jnp.asarray(theta, dtype=float)
    k = theta.size if n_directions is None else n_directions
    key_v, key_w = jr.split(key)
    v = jr.normal(key_v, (k, theta.size), dtype=theta.dtype)
    w = jr.normal(key_w, (objective.n_residuals,), dtype=theta.dtype)
    _, jac = _jacobian(objective.forward_mode(), theta)  # no program of its own
    jv = jac @ v.T
    _, jtw = _vjp_theta(objective.with_adjoint(adjoint), theta, w, jnp.zeros((), theta.dtype))
    lhs, rhs = w @ jv, v @ jtw
    scale = jnp.maximum(jnp.max(jnp.abs(lhs)), jnp.max(jnp.abs(rhs)))
    return ScalarProductTest(lhs, rhs, jnp.max(jnp.abs(lhs - rhs)) / scale)


def reference_gradient(
    objective: Objective, theta, *, rtol: float = 1e-12, atol: float = 1e-14, max_steps=None
):
    """dJ/dtheta by forward mode with the solve at a tight tolerance (PID `rtol`, `atol`).

    The tolerances are traced, so this shares the compilation of `gradient(..., "forward")`
    unless `max_steps` (default: the objective's) changes.
    """
    controller = traced_tolerances(dfx.PIDController(rtol=rtol, atol=atol))
    settings = {} if max_steps is None else {"max_steps": max_steps}
    tight = objective.replace(stepsize_controller=controller, **settings)
    return gradient(tight, theta, method="forward").grad
