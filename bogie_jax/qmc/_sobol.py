"""Sobol' low-discrepancy points, optionally scrambled with a `key`.

The sequence is the Joe-Kuo one (32-bit direction integers, Gray-code order, as
`scipy.stats.qmc.Sobol` draws it); scrambling is Matousek's linear matrix scrambling plus a
random digital shift, which keeps the (t, m, s)-net property, so N = 2^m points stay balanced.
Shared by the multistart designs (`identify`) and the Sobol' sensitivity indices.
"""

import functools

import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
from jaxtyping import Array, Float, PRNGKeyArray

from .._validation import check_positive_int, check_power_of_two
from ._direction_numbers import DIRECTION_NUMBERS


_BITS = 32
MAX_DIMENSION = len(DIRECTION_NUMBERS)


@functools.cache
def _direction_integers(dim: int) -> np.ndarray:
    """(dim, 32) uint32 direction integers v[d, j] = m_j 2^(31 - j) (Bratley-Fox recurrence)."""
    v = np.zeros((dim, _BITS), dtype=np.uint64)
    for d, (poly, m_init) in enumerate(DIRECTION_NUMBERS[:dim]):
        s = len(m_init)
        m = list(m_init) if d else [1] * _BITS
        for j in range(len(m), _BITS):
            new = m[j - s]
            for k in range(s):
                if (poly >> (s - 1 - k)) & 1:
                    new ^= m[j - k - 1] << (k + 1)
            m.append(new)
        v[d] = [m[j] << (_BITS - 1 - j) for j in range(_BITS)]
    return v.astype(np.uint32)


def _pack(digits):
    """(..., 32) 0/1 digits, most significant first -> uint32."""
    weights = jnp.left_shift(jnp.uint32(1), jnp.arange(_BITS - 1, -1, -1, dtype=jnp.uint32))
    weights = weights.reshape((1,) * (digits.ndim - 1) + (_BITS,))
    return jnp.sum(digits.astype(jnp.uint32) * weights, axis=-1, dtype=jnp.uint32)


def _unpack(x):
    """uint32 -> (..., 32) int32 digits, most significant first."""
    shifts = jnp.arange(_BITS - 1, -1, -1, dtype=jnp.uint32).reshape((1,) * x.ndim + (_BITS,))
    return ((x[..., None] >> shifts) & jnp.uint32(1)).astype(jnp.int32)


def _scramble(v, key):
    """Linear matrix scrambling of the direction integers and a random digital shift."""
    dim = v.shape[0]
    lkey, skey = jr.split(key)
    lower = jr.bernoulli(lkey, 0.5, (dim, _BITS, _BITS)).astype(jnp.int32)
    lower = jnp.tril(lower, k=-1) + jnp.eye(_BITS, dtype=jnp.int32)[None]
    # new digit i = sum_{k <= i} L[i, k] digit k (mod 2): each digit mixes only higher ones.
    digits = jnp.einsum("dik,djk->dji", lower, _unpack(v)) % 2
    shift = jr.bits(skey, (dim,), dtype=jnp.uint32)
    return _pack(digits), shift


@functools.partial(jax.jit, static_argnums=(0,))
def _points(n: int, v, shift):
    index = jnp.arange(n, dtype=jnp.uint32)
    gray = index ^ (index >> jnp.uint32(1))

    def add_bit(b, x):
        on = ((gray >> b.astype(jnp.uint32)) & jnp.uint32(1)).astype(bool)
        return x ^ jnp.where(on[:, None], v[:, b][None, :], jnp.uint32(0))

    x = jax.lax.fori_loop(0, _BITS, add_bit, jnp.broadcast_to(shift, (n, v.shape[0])))
    dtype = jnp.result_type(float)
    return x.astype(dtype) * jnp.asarray(2.0**-_BITS, dtype)


def sobol_sequence(n: int, dim: int, *, key: PRNGKeyArray | None) -> Float[Array, "n dim"]:
    """The first `n` points of the `dim`-dimensional Sobol' sequence in [0, 1)^dim.

    **Arguments:**
    - `n`: number of points, a power of two (only then is the design balanced).
    - `dim`: dimension, at most `MAX_DIMENSION` (128).
    - `key`: PRNG key for the scrambling; pass `None` explicitly for the unscrambled
      sequence (first point 0, identical to `scipy.stats.qmc.Sobol(dim, scramble=False)`).

    **Raises:** `ValueError` for `n` not a power of two or `dim` out of range.
    """
    n = check_power_of_two("n", n)
    check_positive_int("dim", dim)
    if dim > MAX_DIMENSION:
        raise ValueError(f"`dim` must be at most {MAX_DIMENSION}, got {dim}")
    if n > 2**_BITS:
        raise ValueError(f"`n` must be at most 2^{_BITS}, got {n}")
    v = jnp.asarray(_direction_integers(dim))
    if key is None:
        shift = jnp.zeros((dim,), jnp.uint32)
    else:
        v, shift = _scramble(v, key)
    return _points(n, v, shift)
