"""Test configuration: float64 and strict promotion (as diffrax/optimistix do), shared fixtures."""

import os


# Four host devices, so the batch runner's sharding is exercised on a CPU (set before JAX loads).
os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=4")

import jax
import jax.random as jr
import pytest


jax.config.update("jax_enable_x64", True)


@pytest.fixture
def getkey():
    """A fresh PRNG key on every call, from a fixed seed per test."""
    state = {"key": jr.PRNGKey(5678)}

    def _next():
        state["key"], sub = jr.split(state["key"])
        return sub

    return _next
