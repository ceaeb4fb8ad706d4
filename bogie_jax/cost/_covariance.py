"""Covariance and standard errors from a residual Jacobian: the one computation behind fits
(`bogie_jax.identify.fit`) and Fisher information (`bogie_jax.sensitivity.fisher_information`).

For weighted residuals r (unit noise variance with the default weights of `make_objective`) and
their Jacobian J (m, n), the Gauss-Newton covariance of the estimates is

    C = sigma^2 (J^T J)^+,

with the pseudo-inverse taken from the singular value decomposition J = U S V^T (more accurate
than forming J^T J). An information eigenvalue s_k^2 <= `rcond` * max(s^2) counts as zero: its
direction V[:, k] is not identifiable. The rank-deficient case is reported, not inverted:
`rank`, `null` and `directions` name the unidentifiable combinations, and a parameter with a
component along them has an infinite standard error and NaN correlations (the pseudo-inverse's
finite diagonal would understate it).
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int


NULL_LOADING = 1e-6  # a parameter with sum_k V[i, k]^2 above this over null directions is loose


class Covariance(eqx.Module):
    """Covariance of estimates from a residual Jacobian (jit- and vmap-safe).

    **Fields** (in the reported coordinates: those of J, scaled by `scale` if given):
    - `covariance`: `(n, n)` sigma^2 (J^T J)^+ (pseudo-inverse on the identifiable subspace).
    - `std_errors`: `(n,)` square roots of its diagonal; `inf` for a parameter with a component
      along a null direction.
    - `correlation`: `(n, n)`; NaN in the rows and columns of such a parameter.
    - `eigenvalues`: `(n,)` eigenvalues s^2 of the information J^T J, ascending (in J's
      coordinates, without sigma^2); `directions`: `(n, n)` their unit eigenvectors, in columns.
    - `null`: `(n,)` True for a direction counted as zero (unidentifiable).
    - `rank`: number of identifiable directions.
    - `condition_number`: largest / smallest information eigenvalue (inf if rank-deficient).
    """

    covariance: Float[Array, "n n"]
    std_errors: Float[Array, " n"]
    correlation: Float[Array, "n n"]
    eigenvalues: Float[Array, " n"]
    directions: Float[Array, "n n"]
    null: Bool[Array, " n"]
    rank: Int[Array, ""]
    condition_number: Float[Array, ""]

    @property
    def null_directions(self) -> np.ndarray:
        """`(n, k)` the unidentifiable directions (concrete; `k = n - rank`)."""
        return np.asarray(self.directions)[:, np.asarray(self.null)]

    @property
    def identifiable(self) -> np.ndarray:
        """`(n,)` True where the standard error is finite."""
        return np.isfinite(np.asarray(self.std_errors))


def covariance_from_jacobian(
    jacobian, *, sigma2=1.0, rcond: float = 1e-12, scale=None
) -> Covariance:
    """`Covariance` of the estimates from the residual Jacobian `(m, n)`.

    **Arguments:**
    - `jacobian`: dr/dx for the coordinates x in which identifiability is judged (e.g. the
      unconstrained theta of a fit, or d/d ln p for relative scaling); choose them so that the
      columns are of comparable size, since `rcond` compares eigenvalues.
    - `sigma2`: residual variance (1 for residuals weighted by 1/sigma; `2 J / (m - n)` for the
      estimated noise of a fit).
    - `rcond`: information eigenvalues at or below `rcond` times the largest are zero, in
      [0, 1).
    - `scale`: optional `(n,)` dp/dx of an element-wise map to the reported coordinates p (the
      delta method: C_p = diag(scale) C_x diag(scale)).

    **Raises:** `ValueError` for a Jacobian that is not 2-D, a bad `rcond` or `scale` shape.
    """
    jac = jnp.asarray(jacobian)
    if jac.ndim != 2 or jac.shape[1] == 0:
        raise ValueError(f"`jacobian` must be 2-D (m, n) with n >= 1, got shape {jac.shape}")
    if not 0.0 <= float(rcond) < 1.0:
        raise ValueError(f"`rcond` = {rcond!r} must lie in [0, 1)")
    n = jac.shape[1]
    _, s, vt = jnp.linalg.svd(jac, full_matrices=False)
    order = jnp.argsort(s)  # ascending information
    s, v = s[order], vt.T[:, order]
    eig = s**2
    largest = eig[-1]
    null = ~(eig > rcond * largest) | ~(largest > 0)
    inv = jnp.where(null, 0.0, 1.0 / jnp.where(null, 1.0, eig))
    cov = sigma2 * (v * inv) @ v.T
    loose = jnp.sum(jnp.where(null[None, :], v**2, 0.0), axis=1) > NULL_LOADING
    std = jnp.where(loose, jnp.inf, jnp.sqrt(jnp.maximum(jnp.diag(cov), 0.0)))
    unit = jnp.where(loose, jnp.nan, std)
    corr = cov / jnp.outer(unit, unit)
    if scale is not None:
        d = jnp.asarray(scale)
        if d.shape != (n,):
            raise ValueError(f"`scale` must have shape ({n},), got {d.shape}")
        cov = cov * jnp.outer(d, d)
        std = std * jnp.abs(d)
        corr = corr * jnp.outer(jnp.sign(d), jnp.sign(d))
    rank = jnp.sum(~null)
    cond = jnp.where(jnp.any(null), jnp.inf, largest / jnp.where(jnp.any(null), 1.0, eig[0]))
    return Covariance(cov, std, corr, eig, v, null, rank, cond)
