"""Float64 check: the library never flips global config; it explains how to enable it."""

import warnings

import jax.numpy as jnp


def warn_if_float32(stacklevel: int = 3) -> None:
    """Warn once per call site when JAX runs in float32 (tolerances below 1e-7 are then moot)."""
    if jnp.zeros(()).dtype != jnp.float64:
        warnings.warn(
            "bogie_jax needs float64 for its default tolerances: call "
            "`jax.config.update('jax_enable_x64', True)` before creating any array "
            "(the CLI, tests and notebooks do this).",
            stacklevel=stacklevel,
        )
