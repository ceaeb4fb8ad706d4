"""Saltelli's design on Sobol' points (`bogie_jax.qmc.sobol_sequence`)."""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float, PRNGKeyArray

from ..qmc import MAX_DIMENSION, sobol_sequence
from ._validation import check_bounds


class SaltelliSample(eqx.Module):
    """Saltelli's design for first-order and total indices: `n (d + 2)` points.

    `a` and `b` are two independent `(n, d)` matrices (columns `0..d-1` and `d..2d-1` of one
    Sobol' design); `ab[i]` is `a` with column `i` taken from `b`.
    """

    a: Float[Array, "n d"]
    b: Float[Array, "n d"]
    ab: Float[Array, "d n d"]

    def stacked(self) -> Float[Array, "n*(d+2) d"]:
        """All points as one batch, in the order `[a; b; ab[0]; ...; ab[d-1]]`."""
        d = self.a.shape[1]
        return jnp.concatenate([self.a, self.b, self.ab.reshape(-1, d)])


def saltelli_sample(lower, upper, n: int, *, key: PRNGKeyArray | None) -> SaltelliSample:
    """Saltelli's sampling scheme over the box `[lower, upper]` (inputs uniform on it).

    **Arguments:**
    - `lower`, `upper`: `(d,)` bounds of the inputs, `lower < upper`.
    - `n`: base sample size, a power of two; the design has `n (d + 2)` points.
    - `key`: PRNG key scrambling the Sobol' sequence (`None`: unscrambled).

    **Returns:** a `SaltelliSample`.

    **Raises:** `ValueError` for bad bounds or `n` (before anything is drawn).

    > ??? cite "Reference"
    >     A. Saltelli et al., "Variance based sensitivity analysis of model output. Design and
    >     estimator for the total sensitivity index", Comput. Phys. Commun. 181, 259-270 (2010).
    """
    lo, hi = check_bounds(lower, upper)
    d = lo.size
    if 2 * d > MAX_DIMENSION:
        raise ValueError(f"at most {MAX_DIMENSION // 2} parameters are supported, got {d}")
    base = sobol_sequence(n, 2 * d, key=key)
    dtype = base.dtype
    lo, width = jnp.asarray(lo, dtype), jnp.asarray(hi - lo, dtype)
    a = lo[None] + width[None] * base[:, :d]
    b = lo[None] + width[None] * base[:, d:]
    ab = jnp.where(jnp.eye(d, dtype=bool)[:, None, :], b[None], a[None])
    return SaltelliSample(a=a, b=b, ab=ab)
