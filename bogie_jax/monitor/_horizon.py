"""Continuation on the fitted horizon: `monitor`'s fit of a long record starts on its first
second and doubles the span it fits until it covers the whole record.

Why: each run's speed is fitted as a nuisance factor (`_nuisance.py`). A speed wrong by a
fraction e places the track record e v t wrong at time t, so the cost of a record of duration T
oscillates in the speed factor with a period of about lambda / (v T) for the track's shortest
wavelengths lambda: the longer the record, the narrower the basin of the right factor, and a
single fit of a long record from the stated speed can stop in a wrong minimum.

Method: a continuation (homotopy) in the observation horizon. Fit the samples within `start`
seconds of each run's first sample, then within 2 `start`, 4 `start`, ..., each stage starting
from the previous estimate, and finally the whole record: each stage fixes the speed factor
well enough for the drift over twice its horizon to stay inside the right basin (the cost
structure for which multiple shooting is preferred to single shooting on long records: Bock, in
*Numerical Treatment of Inverse Problems in Differential and Integral Equations*, Birkhaeuser
1983, 95-121). The rows beyond the horizon get zero weight and the sensor bias is estimated
over the rows fitted; the solves stop one sample past the horizon (`simulate`'s `stop_after`, a
traced value: one compiled program for every stage), so a stage costs its horizon's share.
A record no longer than `start` is fitted in one stage. A stage stops at a Bates-Watts relative
offset of 0.3 (`_fit.STAGE_OFFSET_TOL`; the last fit keeps 0.01): it only has to reach the next
stage's basin. `benchmarks/detection.py` measures the whole (docs/benchmarks.md).
"""

import math

import numpy as np


HORIZON_START = 1.0  # [s]: the first stage's span


def horizon_stages(durations, start: float | None = HORIZON_START) -> tuple[float, ...]:
    """The horizons [s] fitted before the whole record: `start`, 2 `start`, 4 `start`, ...
    while shorter than the longest of `durations` [s]; `()` for `start` `None` (no
    continuation) or a record no longer than `start`."""
    if start is None:
        return ()
    longest = max((float(d) for d in durations), default=0.0)
    stages, h = [], float(start)
    while h < longest * (1.0 - 1e-9):
        stages.append(h)
        h *= 2.0
    return tuple(stages)


def check_horizon_start(start) -> None:
    """`ValueError` unless `start` is `None` or a finite number > 0 [s]."""
    if start is None:
        return
    if isinstance(start, bool) or not isinstance(start, (int, float)):
        raise ValueError(f"`horizon_start` = {start!r} must be None or a number of seconds > 0")
    if not (math.isfinite(start) and start > 0):
        raise ValueError(f"`horizon_start` = {start!r} s must be None or finite and > 0")


def window_rows(times, slices, n_channels: int, horizon: float) -> np.ndarray:
    """(m,) True for the residual rows of samples within `horizon` [s] of their run's first
    sample; `times`: each run's sample times [s], `slices`: each run's rows (sample-major,
    `n_channels` per sample)."""
    m = max((sl.stop for sl in slices), default=0)
    inside = np.zeros(m, dtype=bool)
    for t, sl in zip(times, slices):
        t = np.asarray(t, dtype=float)
        if sl.stop - sl.start != t.size * n_channels:
            raise ValueError(
                f"a run has {sl.stop - sl.start} rows for {t.size} samples of {n_channels} channels"
            )
        inside[sl] = np.repeat(t - t[0] <= horizon * (1.0 + 1e-9), n_channels)
    return inside
