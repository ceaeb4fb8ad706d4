"""Continuation on the fitted horizon: `monitor`'s fit of a long record starts on its first
second and doubles the span it fits until it covers the whole record.

Why: each run's speed is fitted as a nuisance factor (`_nuisance.py`). A speed wrong by a
fraction e places the track record e v t wrong at time t, so the cost of a record of duration T
oscillates in the speed factor with a period of about lambda / (v T) for the track's shortest
wavelengths lambda: the longer the record, the narrower the basin of the right factor. With
8 s runs at 30-60 m/s and speeds known to +-1 % (up to 4.8 m of drift), 5 of 19 single-start
fits from the stated speed stopped in a wrong minimum (case 5 of the detection benchmark: a
speed factor of 0.9962 against the true 1.0085, its position offset at the 1 m bound, residual
variance 5083 times the sensors' noise against 29-238 in the good fits), while over 200 cases
of 1 s runs (at most 0.6 m of drift) none did.

Method: a continuation (homotopy) in the observation horizon. Fit the samples within `start`
seconds of each run's first sample, then within 2 `start`, 4 `start`, ..., each stage starting
from the previous estimate, and finally the whole record. The idea is that each stage fixes
the speed factor well enough for the drift over twice its horizon to stay inside the right
basin (the same cost structure is why multiple shooting is preferred to single shooting for
long records: Bock, in *Numerical Treatment of Inverse Problems in Differential and Integral
Equations*, Birkhaeuser 1983, 95-121); `benchmarks/detection.py` measures whether it does. The
rows beyond the horizon get zero weight and the sensor bias is estimated over the rows fitted;
the simulation still covers the whole run, so nothing is compiled again. A record no longer
than `start` is fitted in one stage, as before.

A stage stops at a Bates-Watts relative offset of 0.3 (`_monitor.STAGE_OFFSET_TOL`; the last
fit keeps 0.01): it only has to reach the next stage's basin. On the detection benchmark's
case 5 (8 s) both gave the same final cost to 4 digits; the stages took 16 evaluations of the
residual Jacobian against 24 with 0.01. Each evaluation simulates the whole record, so the
stages cost about as many whole-record evaluations as they take: the fit of case 5 took 158 s
against 48 s for the single fit (2-core CPU, two cases at once).

Measured (2026-11-27, 2-core CPU): detection cases 5 (left anti-yaw damper failed) and 18
(healthy) with 8 s runs, which the single fit had got wrong: the continuation found the true
speed factors (to 1.5e-4) and positions (to 4 cm), residual variance 191 and 93 (was 5083 and
3611), and the right verdicts (the damper `failed`, 5.9 kN s/m for 4; no alarm on the healthy
bogie). On all 19 cases that the single fit had run (`benchmarks/README.md`, "8 s runs with
the fit continued over the horizon"): every fit used both runs (the single fit had left one out
in 5 cases) and found the speed factors to 3.6e-4 and the positions to 5.2 cm; the verdicts
were right in all 19 (12 defects, 7 healthy), against 10 cases with wrong verdicts or a run
left out before. tests/test_monitor.py shows it on a 0.5 s record with an 8 % speed error.
"""

import math

import numpy as np


HORIZON_START = 1.0  # [s]: the first stage's span (1 s runs: no wrong minimum in 200 cases)


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
