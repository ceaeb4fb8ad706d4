"""A measurement of zeros: the layout, sampling and metadata of a record without simulating it,
for checks that read no data value (input errors, static structure). Shared by test_defaults,
test_identify_objective and test_monitor."""

import numpy as np

from bogie_jax.measure import Measurement, layout_description
from bogie_jax.track import TrackReference


def blank_measurement(sensors, *, n, rate, speed, track_length=None):
    """`n` samples at `rate` [Hz] of zeros on `sensors`, at `speed` [m/s]; with `track_length`
    [m] it names an ERRI-low track (seed 0) and records the layout."""
    extra = {}
    if track_length is not None:
        extra = dict(
            track=TrackReference(spectrum="erri-low", seed=0, length=track_length),
            layout=layout_description(sensors),
        )
    return Measurement(
        times=np.arange(n) / rate,
        data=np.zeros((n, len(sensors))),
        channels=[s.name for s in sensors],
        units=[s.unit for s in sensors],
        speed=speed,
        **extra,
    )
