"""Test configuration: float64 (as diffrax and optimistix tests do), 4 host devices, a
compilation cache shared by the tests, and shared fixtures."""

import os


# Four host devices, so the batch runner's sharding is exercised on a CPU (set before JAX loads).
os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=4")

import jax
import jax.random as jr
import pytest


jax.config.update("jax_enable_x64", True)
# A shared persistent cache. JAX writes no program with host callbacks to it, and equinox's
# runtime checks (inside every diffrax solve) are host callbacks here (`EQX_ON_ERROR` is not set,
# so `throw=True` errors still raise): only programs without a solve are reused across tests.
jax.config.update(
    "jax_compilation_cache_dir", os.path.join(os.path.dirname(__file__), "..", ".jax_cache")
)
jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)


@pytest.fixture
def getkey():
    """A fresh PRNG key on every call, from a fixed seed per test."""
    state = {"key": jr.PRNGKey(5678)}

    def _next():
        state["key"], sub = jr.split(state["key"])
        return sub

    return _next
