"""A least-squares linear solver for lineax written in plain XLA operations (no LAPACK).

The Gauss-Newton and Levenberg-Marquardt steps solve min |A x - b| for a tall A (residuals x
parameters, or [J; sqrt(lambda) I]). lineax's default `QR` calls LAPACK's `geqrf`; under `vmap`
that becomes one batched custom call, which jaxlib 0.10 splits over XLA's CPU thread pool while
blocking a pool thread. With a multistart batch sharded over as many CPU devices as pool threads,
every pool thread can block at once, and the process deadlocks (seen with 6 parameters on 2
devices). Householder QR in a `fori_loop` over the (few) columns has no custom call, batches
under `vmap` like any other operation and costs O(m n^2), as LAPACK does.

The same solver serves the square Newton systems of the static equilibrium, and `solve_square`
its implicit-function-theorem tangent solves: lineax's `LU` rejects its right-hand side inside
`shard_map` (its structure check compares the shape structs' mesh annotation), so an
equilibrium solved inside a sharded multistart batch needs a solver that does not run that
check. `HouseholderQR` also transposes square systems (lineax's solver interface).
Algorithm: Golub & Van Loan, Matrix Computations (4th ed.), 5.2.2 and 5.3.3.
"""

from typing import Any

import equinox.internal as eqxi
import jax
import jax.numpy as jnp
import lineax as lx
import lineax.internal as lxi


class HouseholderQR(lx.AbstractLinearSolver):
    """Least-squares solution of a full-column-rank (m >= n) system by Householder QR; for a
    square system also the transposed solve (A^T x = b, what reverse-mode AD of an implicit
    solve needs)."""

    def init(self, operator: lx.AbstractLinearOperator, options: dict[str, Any]):
        del options
        matrix = operator.as_matrix()
        rows, cols = matrix.shape
        if rows < cols:
            raise ValueError(
                f"HouseholderQR needs at least as many rows as columns, got a {rows} x {cols} "
                "operator"
            )
        return matrix, lxi.pack_structures(operator), eqxi.Static(False)

    def compute(self, state, vector, options: dict[str, Any]):
        del options
        matrix, packed, transposed = state
        if transposed.value:
            matrix = matrix.T
        # not `lxi.ravel_vector`: its structure check also compares the mesh annotation of the
        # shape structs, which differs between the operator and the vector inside `shard_map`
        leaves = jax.tree.leaves(vector)
        dtype = jnp.result_type(*leaves)
        b = jnp.concatenate([x.astype(dtype).reshape(-1) for x in leaves])
        r, qtb = triangularise(matrix, b)
        x = back_substitute(r, qtb)
        # numerically rank deficient: a diagonal of R at rounding level of the largest
        diag = jnp.abs(jnp.diagonal(r))
        rank_tol = jnp.finfo(r.dtype).eps * max(matrix.shape) * jnp.max(diag)
        ok = jnp.all(diag > rank_tol) & jnp.all(jnp.isfinite(x))
        result = lx.RESULTS.where(ok, lx.RESULTS.successful, lx.RESULTS.singular)
        return lxi.unravel_solution(x, packed), result, {}

    def transpose(self, state, options: dict[str, Any]):
        del options
        matrix, packed, transposed = state
        if matrix.shape[0] != matrix.shape[1]:
            raise NotImplementedError(
                f"HouseholderQR transposes square systems only, got a {matrix.shape} operator"
            )
        return (
            matrix,
            lxi.transpose_packed_structures(packed),
            eqxi.Static(not transposed.value),
        ), {}

    def conj(self, state, options: dict[str, Any]):
        raise NotImplementedError("HouseholderQR is for real systems")

    def assume_full_rank(self) -> bool:
        return True


def triangularise(a, b):
    """Householder reflections applied to a (m, n) and b (m,) column by column: R (n, n) and
    the first n entries of Q^T b."""
    m, n = a.shape
    rows = jnp.arange(m)

    def reflect(k, carry):
        a, b = carry
        x = jnp.where(rows >= k, a[:, k], 0.0)
        norm = jnp.sqrt(jnp.sum(x**2))
        alpha = -jnp.where(x[k] >= 0, 1.0, -1.0) * norm  # sign avoids cancellation
        v = x.at[k].add(-alpha)
        vv = jnp.sum(v**2)
        beta = jnp.where(vv > 0, 2.0 / jnp.where(vv > 0, vv, 1.0), 0.0)
        a = a - beta * v[:, None] * (v @ a)[None, :]
        b = b - beta * v * (v @ b)
        return a, b

    r, qtb = jax.lax.fori_loop(0, n, reflect, (a, b))
    return r[:n], qtb[:n]


def back_substitute(r, y):
    """x with R x = y for an upper-triangular R (n, n)."""
    n = r.shape[0]
    cols = jnp.arange(n)

    def step(i, x):
        k = n - 1 - i
        s = y[k] - jnp.sum(jnp.where(cols > k, r[k] * x, 0.0))
        return x.at[k].set(s / r[k, k])

    return jax.lax.fori_loop(0, n, step, jnp.zeros(n, dtype=r.dtype))


def solve_square(a, b):
    """x with A x = b for a square non-singular A (n, n) by Householder QR (no LAPACK call)."""
    r, qtb = triangularise(a, b)
    return back_substitute(r, qtb)
