"""The per-device batch runner (`bogie_jax.runtime.batch.per_device_runner`): members split over
the devices and run on their own, in input order, padded, a block of one unbatched, failures
flagged, sharded equal to one device, compiled ahead.

Oracle: each member's answer computed independently in numpy (Newton's iteration for a square
root in a `while_loop`, whose step count depends on the member).
"""

import jax
import jax.numpy as jnp
import numpy as np

from bogie_jax.runtime.batch import BatchRunner, per_device_runner


MAX_STEPS = 60
TRACES = []  # one entry per trace of the member


def _newton_sqrt(a):
    """Newton's iteration for sqrt(a) from x0 = a + 1: (x, steps)."""
    TRACES.append(1)

    def running(carry):
        x, k = carry
        return (jnp.abs(x * x - a) > 1e-12 * a) & jnp.isfinite(x) & (k < MAX_STEPS)

    return jax.lax.while_loop(running, lambda c: (0.5 * (c[0] + a / c[0]), c[1] + 1), (a + 1.0, 0))


def _numpy_newton(a):
    x, k = a + 1.0, 0
    while abs(x * x - a) > 1e-12 * a and np.isfinite(x) and k < MAX_STEPS:
        x, k = 0.5 * (x + a / x), k + 1
    return x, k


# arguments spanning 1e-6 .. 1e12: from 2 to ~45 Newton steps, 13 members on 4 devices (padded)
ARGS = np.array([4.0, 1e12, 2.0, 1e-6, 9.0, 3.0e7, 0.5, 1e3, 16.0, 7.0, 1e-3, 123.0, 2.5])


def test_members_match_the_member_by_member_oracle_in_input_order():
    assert jax.device_count() == 4  # conftest exposes 4 host devices
    for args in (ARGS, ARGS[:4]):  # 4 members on 4 devices: blocks of one, not vmapped
        res = per_device_runner(_newton_sqrt)(jnp.asarray(args))
        x, k = (np.asarray(v) for v in res.outputs)
        expected = [_numpy_newton(a) for a in args]
        np.testing.assert_allclose(x, [e[0] for e in expected], rtol=1e-12)
        np.testing.assert_array_equal(k, [e[1] for e in expected])
        assert not np.any(np.asarray(res.failed))
    assert len(set(k.tolist())) > 2  # the members take different numbers of steps


def test_failed_members_are_flagged_and_the_rest_kept():
    args = ARGS.copy()
    args[[2, 7]] = -1.0  # sqrt of a negative number: x -> NaN, flagged, the others unaffected
    run = per_device_runner(_newton_sqrt, failure_fn=lambda out: out[1] >= MAX_STEPS)
    res = run(jnp.asarray(args))
    failed = np.asarray(res.failed)
    assert failed.tolist() == [i in (2, 7) for i in range(len(args))]
    ok = ~failed
    np.testing.assert_allclose(np.asarray(res.outputs[0])[ok], np.sqrt(args[ok]), rtol=1e-12)


def test_sharded_equals_one_device_and_compiles_ahead():
    sharded = per_device_runner(_newton_sqrt)(jnp.asarray(ARGS))
    one = per_device_runner(_newton_sqrt, devices=jax.devices()[:1])(jnp.asarray(ARGS))
    np.testing.assert_array_equal(np.asarray(sharded.outputs[0]), np.asarray(one.outputs[0]))
    run = per_device_runner(_newton_sqrt)
    assert isinstance(run, BatchRunner)
    TRACES.clear()
    run.compile(jnp.asarray(ARGS))
    assert len(TRACES) == 1
    run(jnp.asarray(ARGS))
    assert len(TRACES) == 1  # the run used the program compiled ahead
