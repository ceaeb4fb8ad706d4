"""The imperfections of real data (issue 19, item 4) in `bogie_jax.monitor`: each checked
against its definition, computed here independently with numpy, on hand-made measurements (no
simulation)."""

import json

import jax.random as jr
import numpy as np
import pytest

from bogie_jax.measure import Measurement, default_sensor_layout, layout_description
from bogie_jax.monitor import (
    channel_rms,
    nonlinear_options,
    recorded_track,
    with_channel_noise,
    with_sensor_bias,
    with_speed_error,
    worn_wheels,
)
from bogie_jax.params import get_parameter, manchester_benchmark
from bogie_jax.track import TrackReference


PARAMS = manchester_benchmark()
SENSORS = default_sensor_layout(PARAMS)
N = 2000  # samples per run


def _runs(n_runs=2, seed=0):
    """Measurements of the default layout with channel c of amplitude (c + 1) / 10 (units of its
    sensor), and one missing sample."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n_runs):
        data = rng.standard_normal((N, len(SENSORS))) * (np.arange(len(SENSORS)) + 1) / 10
        data[5, 3] = np.nan
        out.append(
            Measurement(
                times=np.arange(N) / 100.0,
                data=data,
                channels=tuple(s.name for s in SENSORS),
                units=tuple(s.unit for s in SENSORS),
                speed=40.0 + 10 * k,
                layout=layout_description(SENSORS),
            )
        )
    return tuple(out)


def _noise_std(m):
    return np.array([d["noise_std"] for d in json.loads(m.layout)])


def test_recorded_track_error_rms_and_offset():
    ref = TrackReference(spectrum="erri-low", seed=3, length=80.0)
    true, semi = ref.build(), 0.75
    rec = recorded_track(ref, noise=3e-4, offset=0.4, semi_distance=semi)
    err = np.asarray(rec.values) - np.asarray(true.values)
    rms = np.sqrt(np.mean(err**2, axis=0))
    np.testing.assert_allclose(rms, [3e-4, 3e-4, 3e-4 / (2 * semi)], rtol=1e-12)
    assert float(rec.s0) == pytest.approx(float(true.s0) - 0.4, abs=1e-15)
    exact = recorded_track(ref, noise=0.0, offset=0.0, semi_distance=semi)
    np.testing.assert_array_equal(np.asarray(exact.values), np.asarray(true.values))
    with pytest.raises(ValueError, match="`noise`"):
        recorded_track(ref, noise=-1e-3, offset=0.0, semi_distance=semi)


def test_speed_error():
    m = _runs(1)[0]
    told = with_speed_error(m, 0.01)
    assert float(told.speed) == pytest.approx(40.0 * 1.01, rel=1e-15)
    np.testing.assert_array_equal(np.asarray(told.data), np.asarray(m.data))
    with pytest.raises(ValueError, match="`error`"):
        with_speed_error(m, float("nan"))


def test_sensor_bias_is_a_fraction_of_the_pooled_rms_or_of_noise_std():
    runs = _runs()
    pooled = np.concatenate([np.asarray(m.data) for m in runs])
    rms = np.sqrt(np.nanmean(pooled**2, axis=0))
    np.testing.assert_allclose(channel_rms(runs), rms, rtol=1e-14)
    frac = np.linspace(-0.05, 0.05, len(SENSORS))
    for m, b in zip(runs, with_sensor_bias(runs, frac)):
        np.testing.assert_allclose(np.asarray(b.data) - np.asarray(m.data), frac * rms + 0 * m.data)
        assert b.layout == m.layout
    std = np.array([float(s.noise_std) for s in SENSORS])
    b = with_sensor_bias(runs, 0.5, relative_to="noise_std")[1]
    np.testing.assert_allclose(np.asarray(b.data)[0] - np.asarray(runs[1].data)[0], 0.5 * std)
    with pytest.raises(ValueError, match="`fraction`"):
        with_sensor_bias(runs, [0.1, 0.2])


def test_channel_noise_level_and_declared_layout():
    """Statistical check, one draw of 2 x 2000 samples per channel: the sample std of the added
    noise estimates its level with relative standard error 1/sqrt(2 * 4000) = 1.1 %, asserted
    within 6 % (over 5 standard errors)."""
    runs = _runs()
    rms = channel_rms(runs)
    noisy = with_channel_noise(runs, 0.02, key=jr.PRNGKey(0))
    added = np.concatenate([np.asarray(n.data) - np.asarray(m.data) for m, n in zip(runs, noisy)])
    np.testing.assert_allclose(np.nanstd(added, axis=0), 0.02 * rms, rtol=0.06)
    np.testing.assert_allclose(_noise_std(noisy[0]), 0.02 * rms, rtol=1e-12)
    assert noisy[0].layout == noisy[1].layout
    hidden = with_channel_noise(runs, 0.02, key=jr.PRNGKey(0), declared=False)
    assert hidden[0].layout == runs[0].layout
    with pytest.raises(ValueError, match="`fraction`"):
        with_channel_noise(runs, -0.01, key=jr.PRNGKey(0))


def test_worn_wheels_changes_only_the_cone_slope():
    worn = worn_wheels(PARAMS, 0.7)
    slope = float(get_parameter(PARAMS, "contact.cone_slope"))
    assert float(get_parameter(worn, "contact.cone_slope")) == pytest.approx(0.7 * slope)
    assert float(get_parameter(worn, "yaw_dampers.left.c")) == float(
        get_parameter(PARAMS, "yaw_dampers.left.c")
    )
    with pytest.raises(ValueError, match="`factor`"):
        worn_wheels(PARAMS, 0.0)


def test_nonlinear_options():
    opts = nonlinear_options()
    assert (opts.creep_saturation, opts.nonlinear_dampers, opts.flange_contact) == (
        True,
        True,
        False,
    )
