"""Test configuration: float64 (as diffrax and optimistix tests do), 4 host devices, a
compilation cache shared by the tests, the longest files first, and shared fixtures."""

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


# The longest files first, so that no long file starts last while the other worker idles
# (longest-processing-time order for xdist's `loadfile`; its own order, by number of tests,
# `--no-loadscope-reorder` turns off, started the few-test files of minutes last). Order of the
# files' measured times in a full run (2-core machine, 2026-11-26: 239 s for the first to 13 s
# for the last listed); the others follow in collection order.
LONGEST_FIRST = (
    "test_monitor.py",
    "test_notebooks.py",
    "test_gradients.py",
    "test_identify.py",
    "test_twin.py",
    "test_equilibrium.py",
    "test_identify_objective.py",
    "test_run_corrections.py",
    "test_fleet_run.py",
    "test_fleet_db.py",
    "test_contact_profile_model.py",
    "test_cost.py",
    "test_model.py",
    "test_simulate.py",
    "test_lead_in.py",
    "test_cli.py",
    "test_sensitivity.py",
    "test_defaults.py",
    "test_jacobian_residuals.py",
    "test_measure.py",
    "test_identifiability.py",
    "test_contact.py",
    "test_levenberg_marquardt.py",
    "test_closed_form_terms.py",
    "test_chunked.py",
    "test_track.py",
)


def pytest_collection_modifyitems(config, items):
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: files stay whole


@pytest.fixture
def getkey():
    """A fresh PRNG key on every call, from a fixed seed per test."""
    state = {"key": jr.PRNGKey(5678)}

    def _next():
        state["key"], sub = jr.split(state["key"])
        return sub

    return _next
