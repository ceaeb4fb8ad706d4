"""The program store: a batch program exported in one runner is loaded by a fresh runner of the
same identity without tracing its member again and gives bit-identical outputs; another
identity, another argument shape or an identity that does not pickle gets its own program or
none; the store is off by default and where equinox's errors are host callbacks; a store that
cannot be written still runs the export.

Oracle: the per-device runner's own outputs without the store (Newton's square root, as in
`test_per_device_runner.py`)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import bogie_jax.runtime.program_store as store
from bogie_jax.runtime.batch import per_device_runner


ARGS = jnp.asarray([4.0, 1e12, 2.0, 1e-6, 9.0, 3.0e7, 0.5, 1e3])
TRACES = []


def _member(scale):
    """Newton's iteration for sqrt(scale * a); each trace of its step is counted in TRACES."""

    def step(carry):
        TRACES.append(1)
        a, x, k = carry
        return a, 0.5 * (x + a / x), k + 1

    def running(carry):
        a, x, k = carry
        return (jnp.abs(x * x - a) > 1e-12 * a) & (k < 60)

    def member(a):
        _, x, k = jax.lax.while_loop(running, step, (scale * a, scale * a + 1.0, 0))
        return x, k

    return member


def _runner(scale, identity):
    return per_device_runner(_member(scale)).with_identity(identity)


@pytest.fixture
def on(tmp_path, monkeypatch):
    """The store in `tmp_path`, with equinox's errors as NaNs (as the command line runs)."""
    monkeypatch.setattr("equinox._config.EQX_ON_ERROR", "nan")
    monkeypatch.setattr(store, "_CALLS", {})  # as in a fresh process
    store.use_program_store(tmp_path)
    yield tmp_path
    store.use_program_store(None)


def test_a_fresh_runner_loads_the_program_without_tracing_and_matches(on):
    plain = _runner(2.0, None)(ARGS)
    TRACES.clear()
    first = _runner(2.0, ("sqrt", 2.0))(ARGS)
    assert len(TRACES) == 1 and len(list(on.glob(f"*{store.SUFFIX}"))) == 1
    store._CALLS.clear()  # a new process: only the file remains
    TRACES.clear()
    second = _runner(2.0, ("sqrt", 2.0))(ARGS)
    assert TRACES == []  # loaded: the member was not traced
    for a, b, c in zip(plain.outputs, first.outputs, second.outputs):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
        np.testing.assert_array_equal(np.asarray(a), np.asarray(c))
    np.testing.assert_allclose(np.asarray(second.outputs[0]) ** 2, 2.0 * ARGS, rtol=1e-12)
    np.testing.assert_array_equal(np.asarray(second.failed), np.asarray(plain.failed))


def test_identity_and_shapes_key_the_programs(on):
    _runner(2.0, ("sqrt", 2.0))(ARGS)
    # another identity (here: another closed-over scale) is another program, not the first
    three = _runner(3.0, ("sqrt", 3.0))(ARGS)
    np.testing.assert_allclose(np.asarray(three.outputs[0]) ** 2, 3.0 * ARGS, rtol=1e-12)
    _runner(2.0, ("sqrt", 2.0))(ARGS[:4])  # another batch shape (padded to the devices: 4, not 8)
    assert len(list(on.glob(f"*{store.SUFFIX}"))) == 3
    a = store.program_key(("sqrt", 2.0), (ARGS,))
    assert a == store.program_key(("sqrt", 2.0), (ARGS + 1.0,))  # values are inputs, not keys
    assert a != store.program_key(("sqrt", 2.0), (ARGS.astype(jnp.float32),))


def test_unpicklable_identity_and_default_are_not_stored(on, monkeypatch):
    TRACES.clear()
    out = _runner(2.0, ("sqrt", lambda: 2.0))(ARGS)  # a lambda does not pickle
    assert store.program_key(("sqrt", lambda: 2.0), (ARGS,)) is None
    assert len(TRACES) == 1 and not list(on.glob(f"*{store.SUFFIX}"))
    np.testing.assert_allclose(np.asarray(out.outputs[0]) ** 2, 2.0 * ARGS, rtol=1e-12)
    # equinox's errors as host callbacks (its default): such programs cannot be exported
    monkeypatch.setattr("equinox._config.EQX_ON_ERROR", "raise")
    _runner(2.0, ("sqrt", 2.0))(ARGS)
    store.use_program_store(None)  # off (the library's default)
    monkeypatch.setattr("equinox._config.EQX_ON_ERROR", "nan")
    _runner(2.0, ("sqrt", 2.0))(ARGS)
    assert not list(on.glob(f"*{store.SUFFIX}"))


def test_a_store_that_cannot_be_written_still_runs_the_export(on):
    blocked = on / "not_a_directory"
    blocked.write_text("")  # the store's directory is a file: writing fails
    store.use_program_store(blocked)
    with pytest.warns(UserWarning, match="batch program not written"):
        out = _runner(2.0, ("sqrt", 2.0))(ARGS)
    np.testing.assert_allclose(np.asarray(out.outputs[0]) ** 2, 2.0 * ARGS, rtol=1e-12)
    TRACES.clear()
    _runner(2.0, ("sqrt", 2.0))(ARGS)  # this process keeps the export: no new trace
    assert TRACES == []
