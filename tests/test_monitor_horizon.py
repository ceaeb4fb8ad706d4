"""The horizon continuation of `monitor`'s fit (`bogie_jax/monitor/_horizon.py`): its stages
and row windows (numpy, oracle: counting by hand). Its use in `monitor`: tests/test_monitor.py."""

import numpy as np
import pytest

from bogie_jax.monitor import HORIZON_START, horizon_stages, window_rows


def test_stages_double_from_the_start_until_the_record():
    assert HORIZON_START == 1.0
    assert horizon_stages([8.0, 8.0]) == (1.0, 2.0, 4.0)
    assert horizon_stages([3.0, 8.0 + 1e-12]) == (1.0, 2.0, 4.0)  # the longest run counts
    assert horizon_stages([8.5]) == (1.0, 2.0, 4.0, 8.0)
    assert horizon_stages([2.0]) == (1.0,)
    assert horizon_stages([1.0]) == ()  # a 1 s record: one fit, as before
    assert horizon_stages([0.5, 0.99]) == ()
    assert horizon_stages([0.5], start=0.125) == (0.125, 0.25)
    assert horizon_stages([8.0], start=None) == ()


def test_window_rows_keep_the_samples_within_the_horizon_of_each_run():
    # run 0: 5 samples at 10 Hz from t = 2 s; run 1: 3 samples at 4 Hz from t = 0; 2 channels
    times = [2.0 + 0.1 * np.arange(5), 0.25 * np.arange(3)]
    slices = (slice(0, 10), slice(10, 16))
    inside = window_rows(times, slices, 2, 0.25)
    # run 0: t - t0 = 0, 0.1, 0.2 within (3 samples, 6 rows); run 1: 0, 0.25 (2 samples, 4 rows)
    expected = np.array([1] * 6 + [0] * 4 + [1] * 4 + [0] * 2, dtype=bool)
    np.testing.assert_array_equal(inside, expected)
    assert window_rows(times, slices, 2, 10.0).all()
    with pytest.raises(ValueError, match="rows for 5 samples of 3 channels"):
        window_rows(times, slices, 3, 1.0)
