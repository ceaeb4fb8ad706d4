"""The queued batch runner: members of different lengths, refills, order, failures, devices.

Oracle: each member's answer computed independently in numpy (Newton's iteration for a square
root, whose step count depends on the member), and the step counts the queue must reproduce.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from bogie_jax.runtime.batch import BatchRunner
from bogie_jax.runtime.queued_batch import IterativeMember, queued_runner


MAX_STEPS = 60


def _newton_sqrt_member():
    """Newton's iteration for sqrt(a) from x0 = a + 1: carry (a, x, steps)."""

    def init(a):
        return a, a + 1.0, jnp.asarray(0)

    def step(carry):
        a, x, k = carry
        return a, 0.5 * (x + a / x), k + 1

    def done(carry):
        a, x, k = carry
        return (jnp.abs(x * x - a) <= 1e-12 * a) | ~jnp.isfinite(x) | (k >= MAX_STEPS)

    def output(carry):
        _, x, k = carry
        return x, k

    return IterativeMember(init=init, step=step, done=done, output=output)


def _numpy_newton(a):
    x, k = a + 1.0, 0
    while k < MAX_STEPS:
        x, k = 0.5 * (x + a / x), k + 1
        if abs(x * x - a) <= 1e-12 * a or not np.isfinite(x):
            break
    return x, k


# arguments spanning 1e-6 .. 1e12: from 2 to ~45 Newton steps, so lanes finish at different times
ARGS = np.array([4.0, 1e12, 2.0, 1e-6, 9.0, 3.0e7, 0.5, 1e3, 16.0, 7.0, 1e-3, 123.0, 2.5])


@pytest.mark.parametrize("lanes", [1, 3, 20])
def test_queue_matches_member_by_member_oracle(lanes):
    run = queued_runner(_newton_sqrt_member(), lanes=lanes)
    res = run(jnp.asarray(ARGS))
    x, k = (np.asarray(v) for v in res.outputs)
    expected = [_numpy_newton(a) for a in ARGS]
    np.testing.assert_allclose(x, [e[0] for e in expected], rtol=1e-12)
    np.testing.assert_array_equal(k, [e[1] for e in expected])  # in input order
    assert len(set(k.tolist())) > 5  # the members really take different numbers of steps
    np.testing.assert_allclose(x, np.sqrt(ARGS), rtol=1e-12)
    assert not np.any(np.asarray(res.failed))


def test_queue_reports_failed_members_and_keeps_the_rest():
    args = ARGS.copy()
    args[[2, 7]] = -1.0  # sqrt of a negative number: x -> NaN, flagged, the others unaffected
    run = queued_runner(_newton_sqrt_member(), lanes=2, failure_fn=lambda out: out[1] >= MAX_STEPS)
    res = run(jnp.asarray(args))
    failed = np.asarray(res.failed)
    assert failed.tolist() == [i in (2, 7) for i in range(len(args))]
    ok = ~failed
    np.testing.assert_allclose(np.asarray(res.outputs[0])[ok], np.sqrt(args[ok]), rtol=1e-12)


def test_queue_sharded_equals_one_device_and_post_sees_inputs():
    assert jax.device_count() == 4  # conftest exposes 4 host devices

    def post(a, out):
        return out[0] - jnp.sqrt(a)  # per member, after the queue

    member = _newton_sqrt_member()
    sharded = queued_runner(member, lanes=2, post=post)(jnp.asarray(ARGS))
    one = queued_runner(member, lanes=2, post=post, devices=jax.devices()[:1])(jnp.asarray(ARGS))
    np.testing.assert_array_equal(np.asarray(sharded.outputs), np.asarray(one.outputs))
    np.testing.assert_array_less(np.abs(np.asarray(one.outputs)), 1e-9 * np.sqrt(ARGS))


def test_queue_compiles_ahead_and_rejects_bad_lanes():
    traced = []
    member = _newton_sqrt_member()
    counting = IterativeMember(
        init=lambda a: (traced.append(1), member.init(a))[1],
        step=member.step,
        done=member.done,
        output=member.output,
    )
    run = queued_runner(counting, lanes=2)
    assert isinstance(run, BatchRunner)
    run.compile(jnp.asarray(ARGS))
    n_traced = len(traced)
    assert n_traced > 0
    run(jnp.asarray(ARGS))
    assert len(traced) == n_traced  # the run used the program compiled ahead
    jitted, args = run.program(jnp.asarray(ARGS))
    assert "stablehlo.while" in jitted.lower(*args).as_text()  # the queue's one loop
    assert len(traced) == n_traced
    with pytest.raises(ValueError, match="`lanes` must be >= 1, got 0"):
        queued_runner(member, lanes=0)
