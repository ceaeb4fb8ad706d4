"""simulate(): input checks, vmap over speeds / parameters / tracks, the batch runner, no
retracing for new parameter values."""

import types

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

import bogie_jax as bj
from bogie_jax.runtime.batch import batch_runner
from bogie_jax.simulation import simulate
from bogie_jax.track import ERRIB176Spectrum, synthesise_track


DURATION, RATE = 0.4, 100.0


@pytest.fixture(scope="module")
def tracks():
    keys = jr.split(jr.PRNGKey(3), 2)
    return [
        synthesise_track(ERRIB176Spectrum.high(), key=k, length=80.0, fade_length=2.0) for k in keys
    ]


def _run(params, track, speed):
    return simulate(
        params,
        track,
        speed=speed,
        duration=DURATION,
        sample_rate=RATE,
        throw=False,
        stepsize_controller=dfx.PIDController(rtol=1e-8, atol=1e-10),
        max_steps=4096,
    ).q


@pytest.fixture(scope="module")
def single():
    """`_run` jitted once for the module (`run`), and its traces (`traces`): every test calls it
    with the same argument types (float64 arrays, never weak-typed Python floats), so every
    call after the first must reuse its program."""
    traces = []

    def counted(params, track, speed):
        traces.append(1)
        return _run(params, track, speed)

    return types.SimpleNamespace(run=jax.jit(counted), traces=traces)


def _with_ky(params, ky):
    return eqx.tree_at(lambda p: p.primary.ky, params, ky)


@pytest.mark.parametrize(
    "kwargs, pattern",
    [
        ({"speed": 0.0}, r"`speed` = 0 m/s is outside the valid range \(0, 150\] m/s"),
        ({"speed": 200.0}, r"`speed` = 200 m/s is outside"),
        ({"duration": -1.0}, r"`duration` = -1 s is outside"),
        ({"sample_rate": 0.0}, r"`sample_rate` = 0 Hz is outside"),
        ({"max_steps": 0}, r"`max_steps` must be an integer"),
    ],
)
def test_bad_input_is_rejected_before_solving(kwargs, pattern, tracks):
    args = dict(speed=50.0, duration=1.0, sample_rate=100.0) | kwargs
    with pytest.raises(ValueError, match=pattern):
        simulate(bj.manchester_benchmark(), tracks[0], **args)


def test_vmap_over_speeds_parameters_and_tracks_equals_loop(single, tracks):
    params = bj.manchester_benchmark()
    speeds = jnp.array([40.0, 55.0])
    kys = jnp.array([3e6, 5e6])
    stacked_tracks = jax.tree.map(lambda *x: jnp.stack(x), *tracks)
    batched = jax.jit(jax.vmap(lambda ky, tr, v: _run(_with_ky(params, ky), tr, v)))(
        kys, stacked_tracks, speeds
    )
    for i in range(2):
        one = single.run(_with_ky(params, kys[i]), tracks[i], speeds[i])
        # A batched adaptive solve takes its own step sequence: agreement to the solver
        # tolerance (rtol 1e-8, accumulated over the run), not bit for bit.
        np.testing.assert_allclose(batched[i], one, rtol=0, atol=1e-5 * np.max(np.abs(one)))
    assert np.max(np.abs(np.asarray(batched))) > 1e-5  # the tracks really excite the bogie


def test_batch_runner_sharded_equals_single_device_and_reports_failures(single, tracks):
    """Five members over four devices in chunks of one: two chunks per device (`lax.map`), three
    padding slots, and the NaN member in one vmapped solve with the members of the other devices
    (the sharded `while_loop` waits for all of them). Every member that runs is compared with
    the same member run alone on one device through the module's compiled `_run` (an unbatched,
    unsharded program: no batch runner at all), so no second batch program is compiled."""
    assert jax.device_count() >= 4, "tests/conftest.py exposes 4 host devices"
    params = bj.manchester_benchmark()

    traces = []

    def member(ky):
        traces.append(1)
        return _run(_with_ky(params, ky), tracks[0], 50.0)

    kys = jnp.array([3e6, 4e6, jnp.nan, 5e6, 6e6])  # the NaN member must fail alone
    run = batch_runner(member, chunk_size=1)
    run.compile(kys)  # ahead of time; the call below runs that program
    sharded = run(kys)
    assert len(traces) == 1  # traced once, by the compile: the run did not compile again
    assert list(np.asarray(sharded.failed)) == [False, False, True, False, False]
    ok = ~np.asarray(sharded.failed)
    alone = np.stack(
        [
            single.run(_with_ky(params, ky), tracks[0], jnp.asarray(50.0, dtype=float))
            for ky in kys[ok]
        ]
    )
    scale = np.max(np.abs(alone))
    np.testing.assert_allclose(  # to solver tolerance, see the vmap test
        np.asarray(sharded.outputs)[ok], alone, rtol=0, atol=1e-5 * scale
    )


def test_new_parameter_values_do_not_retrace(single, tracks):
    """New parameter values (and, when the tests above ran first, other tracks and speeds of
    the same shapes) reuse the one program: `_run` was traced once in this module."""
    params = bj.manchester_benchmark()
    speed = jnp.asarray(50.0, dtype=float)
    for ky in (3e6, 4e6, 5e6):
        single.run(_with_ky(params, jnp.asarray(ky, dtype=float)), tracks[0], speed)
    assert len(single.traces) == 1


def test_float32_is_explained():
    from bogie_jax.simulation import warn_if_float32

    with jax.enable_x64(False):
        with pytest.warns(UserWarning, match="jax_enable_x64"):
            warn_if_float32()


def test_stop_after_stops_the_solve_and_keeps_the_samples_before_it(tracks):
    """A solve stopped past `stop_after` has the whole run's samples up to there (the same steps,
    so the same values), inf states after the step that passed it, fewer steps, and a
    successful result; one program for every stop time."""
    params = bj.manchester_benchmark()
    speed = jnp.asarray(40.0)

    @jax.jit
    def run(stop_after):
        return simulate(
            params, tracks[0], speed=speed, duration=DURATION, sample_rate=RATE, throw=False,
            stepsize_controller=dfx.PIDController(rtol=1e-8, atol=1e-10), max_steps=4096,
            stop_after=stop_after,
        )  # fmt: skip

    whole, short = run(jnp.asarray(np.inf)), run(jnp.asarray(0.15))
    kept = np.asarray(short.ts - short.ts[0]) <= 0.15 + 1e-12
    assert bool(whole.successful) and bool(short.successful)
    np.testing.assert_allclose(np.asarray(short.q)[kept], np.asarray(whole.q)[kept], rtol=0, atol=0)
    assert np.all(~np.isfinite(np.asarray(short.q)[-5:]))
    assert int(short.num_steps) < 0.6 * int(whole.num_steps)
    assert run._cache_size() == 1
