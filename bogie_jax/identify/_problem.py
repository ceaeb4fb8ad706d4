"""The least-squares problem every identification method consumes, and the box transform.

A problem is a residual function `residuals(theta, args) -> r` in *unconstrained* coordinates
`theta` plus a parameter transform that maps `theta` to physical values inside their bounds.
Any transform with `lower`, `upper`, `to_theta(physical)` and `to_physical(theta)` works (the
`ParameterSelection` of `bogie_jax.cost` has them); `BoxTransform` is the built-in one.
"""

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from ..cost import forward_mode


class BoxTransform(eqx.Module):
    """Scaled logistic map between unconstrained `theta` and a box `[lower, upper]`.

    `physical = lower + (upper - lower) * sigmoid(theta)`, so an estimate can never leave its
    bounds; `to_theta` is the inverse (scaled logit).

    **Arguments:**
    - `lower`, `upper`: bounds in physical units, 1-D, `lower < upper` elementwise.
    - `names`: optional parameter names (reported in results).
    - `nominal`: optional default start in physical units (default: the box midpoint).
    """

    lower: jax.Array
    upper: jax.Array
    nominal: jax.Array
    names: tuple[str, ...] | None = eqx.field(static=True, default=None)

    def __init__(self, lower, upper, names=None, nominal=None):
        lower = np.atleast_1d(np.asarray(lower, dtype=float))
        upper = np.atleast_1d(np.asarray(upper, dtype=float))
        if lower.ndim != 1 or lower.shape != upper.shape:
            raise ValueError(
                f"`lower` and `upper` must be 1-D of one shape, got {lower.shape} and {upper.shape}"
            )
        if not (
            np.all(np.isfinite(lower)) and np.all(np.isfinite(upper)) and np.all(lower < upper)
        ):
            raise ValueError(f"need finite `lower` < `upper`, got lower={lower}, upper={upper}")
        if names is not None and len(names) != lower.size:
            raise ValueError(f"`names` has {len(names)} entries for {lower.size} parameters")
        self.lower = jnp.asarray(lower)
        self.upper = jnp.asarray(upper)
        self.nominal = jnp.asarray(0.5 * (lower + upper) if nominal is None else nominal, float)
        self.names = None if names is None else tuple(names)

    def to_physical(self, theta):
        return self.lower + (self.upper - self.lower) * jax.nn.sigmoid(theta)

    def to_theta(self, physical):
        u = (physical - self.lower) / (self.upper - self.lower)
        return jnp.log(u) - jnp.log1p(-u)


class LeastSquaresProblem(eqx.Module):
    """`residuals(theta, args) -> r` (1-D) in unconstrained coordinates, with its transform."""

    residuals: Callable
    transform: object
    args: object = None

    def cost(self, theta):
        """Half the sum of squared residuals, `J = 0.5 r^T r`."""
        r = jnp.ravel(problem_residuals(theta, self))
        return 0.5 * jnp.sum(r**2)


def problem_residuals(theta, problem: LeastSquaresProblem):
    """optimistix's `fn(y, args)`, `args` the problem itself."""
    return problem.residuals(theta, problem.args)


def on_bound(transform, physical, bound_tol):
    """Whether each parameter lies within `bound_tol` box widths of a bound of `transform`; a
    parameter without a finite box (log scale: bounds 0 and inf) never does."""
    lower, upper = transform.lower, transform.upper
    boxed = jnp.isfinite(lower) & jnp.isfinite(upper)
    u = (physical - jnp.where(boxed, lower, 0.0)) / jnp.where(boxed, upper - lower, 1.0)
    return boxed & ((u < bound_tol) | (u > 1.0 - bound_tol))


def as_problem(problem) -> LeastSquaresProblem:
    """Accept a `LeastSquaresProblem` or an `Objective`-like object.

    An objective is anything with `residuals(theta, args)` and a transform attribute named
    `selection` (as `bogie_jax.cost.Objective` has) or `transform`. With `selection`, the
    objective is switched to forward mode (`bogie_jax.cost.forward_mode`: no adjoint switch by
    the caller) and its residuals are wrapped in `JacobianResiduals` (the Jacobian materialised
    once per linearisation).
    """
    if isinstance(problem, LeastSquaresProblem):
        return problem
    transform = getattr(problem, "selection", None) or getattr(problem, "transform", None)
    selection = getattr(problem, "selection", None)
    if callable(getattr(problem, "residuals", None)) and selection is not None:
        # A simulation objective: residuals with a materialised forward-mode Jacobian (one
        # tangent solve per linearisation instead of one per Jacobian-vector product).
        from ._jacobian import JacobianResiduals

        return LeastSquaresProblem(JacobianResiduals(forward_mode(problem)), transform, None)
    if callable(getattr(problem, "residuals", None)) and transform is not None:
        # A bound method of an eqx.Module is itself a pytree: the objective's arrays stay leaves.
        return LeastSquaresProblem(problem.residuals, transform, None)
    raise TypeError(
        "`problem` must be a LeastSquaresProblem or an objective with `residuals(theta, args)` "
        f"and a `selection`/`transform`; got {type(problem).__name__}"
    )


def bounds(transform) -> tuple[np.ndarray, np.ndarray]:
    """Concrete `(lower, upper)` of a transform; raises on an empty selection."""
    lower = np.atleast_1d(np.asarray(transform.lower, dtype=float))
    upper = np.atleast_1d(np.asarray(transform.upper, dtype=float))
    if lower.size == 0:
        raise ValueError("empty parameter selection: select at least one parameter to identify")
    return lower, upper


def param_names(transform, n: int) -> tuple[str, ...]:
    names = getattr(transform, "names", None)
    return tuple(names) if names is not None else tuple(f"p{i}" for i in range(n))


def start_theta(transform, start) -> jax.Array:
    """Map a physical start (default: the transform's nominal) to `theta`, checking bounds."""
    lower, upper = bounds(transform)
    if start is None:
        nominal = getattr(transform, "nominal", None)
        start = 0.5 * (lower + upper) if nominal is None else nominal
    start = np.atleast_1d(np.asarray(start, dtype=float))
    if start.shape != lower.shape:
        raise ValueError(f"`start` must have shape {lower.shape}, got {start.shape}")
    outside = ~((start > lower) & (start < upper))
    if np.any(outside):
        names = param_names(transform, lower.size)
        bad = ", ".join(
            f"{names[i]}={start[i]:g} not in ({lower[i]:g}, {upper[i]:g})"
            for i in np.flatnonzero(outside)
        )
        raise ValueError(f"`start` must lie strictly inside the bounds: {bad}")
    return jnp.asarray(transform.to_theta(jnp.asarray(start)))


# Solver status: `optimistix.RESULTS`. On the host (records, `MultistartResult.status`) a status
# is the name of its member, one of `RESULT_NAMES`.
RESULT_NAMES = tuple(
    name
    for name in (
        "successful",
        "max_steps_reached",
        "singular",
        "breakdown",
        "stagnation",
        "conlim",
        "nonfinite_input",
        "nonlinear_max_steps_reached",
        "nonlinear_divergence",
        "nonfinite",
    )
    if hasattr(optx.RESULTS, name)
)


def is_successful(result) -> jax.Array:
    """Whether `result` (an `optimistix.RESULTS`, batched under vmap) is successful."""
    return result == optx.RESULTS.successful


def status_names(result) -> np.ndarray:
    """The member names (`RESULT_NAMES`) of a concrete, possibly batched, `optimistix.RESULTS`
    (`"unknown"` for a member not listed there)."""
    shape = np.shape(np.asarray(result == optx.RESULTS.successful))
    names = np.full(shape, "unknown", dtype=object)
    for name in RESULT_NAMES:
        names = np.where(np.asarray(result == getattr(optx.RESULTS, name)), name, names)
    return names.astype(str)


def status_name(result) -> str:
    """The member name of one concrete `RESULTS` (e.g. `"nonlinear_max_steps_reached"`)."""
    return str(status_names(result).reshape(-1)[0])


def results_from_names(names) -> "optx.RESULTS":
    """A batched `optimistix.RESULTS` from member names (e.g. read back from records).

    **Raises:** `ValueError` for a name that is not one of `RESULT_NAMES`."""
    names = [str(n) for n in names]
    bad = sorted(set(names) - set(RESULT_NAMES))
    if bad:
        raise ValueError(f"unknown solver status {bad}; valid names: {list(RESULT_NAMES)}")
    items = [getattr(optx.RESULTS, n) for n in names]
    return jax.tree.map(lambda *codes: jnp.stack([jnp.asarray(c) for c in codes]), *items)
