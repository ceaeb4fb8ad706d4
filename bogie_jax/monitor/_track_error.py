"""The track record's error as a model-error term of the estimates' covariance (issue 19,
item 4a).

The fit takes a recording car's measurement of the track as the true track. The record's
error (about 0.3 mm RMS per channel) moves the estimates by a fixed amount per run, and most
of that shift lies in the span of the Jacobian, where the residuals do not show it: the
sandwich covariance, estimated from the residuals, misses it. With longer records the standard
errors shrink but this shift does not (detection benchmark: 95 % coverage 90 % with 1 s runs,
87 % with 2 s).

Model: the error of each channel of a record is a stationary random process with the spectral
shape of the record itself: the record with its Fourier phases drawn at random (uniform; the
amplitude spectrum kept), scaled to RMS `rms` [m] in alignment and vertical level and
`rms / (2 b_0)` [rad] in cross level (a level error of `rms` on each rail over the contact
distance 2 b_0); the runs' errors are independent. (A recording error shaped like the track is
what `recorded_track` simulates; a measured error spectrum would replace the record's own.)

Propagation, to first order at the fit's end: the error e shifts the estimates by
`dv = -J^+ (r(record + e) - r(record))` (J and r in the fitted coordinates, with the fit's
weights and bias projection; the run corrections take their share). The term is the mean of
`dv dv^T` over `draws` realisations (Monte Carlo: the relative error of a variance is about
sqrt(2 / draws)); each draw is one evaluation of the compiled residual Jacobian.
"""

import numpy as np

from ..track import TrackIrregularity


def record_error(values, rms: float, semi_distance: float, rng) -> np.ndarray:
    """One realisation `(n, 3)` of a record's error (module docstring) for the record
    `values` `(n, 3)` (alignment [m], vertical [m], cross level [rad]); `rng`: a numpy
    `Generator`. A channel that is zero throughout gets no error."""
    v = np.asarray(values, dtype=float)
    n = v.shape[0]
    spectrum = np.abs(np.fft.rfft(v - v.mean(axis=0), axis=0))
    phases = rng.uniform(0.0, 2.0 * np.pi, spectrum.shape)
    phases[0] = 0.0  # the mean (zero) stays real
    if n % 2 == 0:
        phases[-1] = 0.0  # so does the Nyquist term
    error = np.fft.irfft(spectrum * np.exp(1j * phases), n=n, axis=0)
    now = np.sqrt(np.mean(error**2, axis=0))
    target = np.array([rms, rms, rms / (2.0 * semi_distance)])
    return error * np.where(now > 0, target / np.where(now > 0, now, 1.0), 0.0)


def track_error_covariance(residuals_with, tracks, jacobian, *, rms, semi_distance, draws, seed=0):
    """`(n, n)` covariance of the estimates' shift by the records' error (module docstring),
    in the coordinates of `jacobian` `(m, n)` (the fit's, at its estimate), and the number of
    draws used.

    - `residuals_with(tracks) -> (m,)`: the fit's residuals at its estimate with these track
      records (in the fit's weights and projection);
    - `tracks`: the runs' `TrackIrregularity` records; `rms` [m], `semi_distance` b_0 [m];
    - `draws` realisations from `numpy.random.default_rng(seed)`; a draw whose residuals are
      not finite (a failed solve) is left out.
    """
    rng = np.random.default_rng(seed)
    pinv = np.linalg.pinv(np.asarray(jacobian, dtype=float))
    r0 = np.asarray(residuals_with(list(tracks)), dtype=float)
    shifts = []
    for _ in range(draws):
        perturbed = [
            TrackIrregularity(
                t.s0, t.ds, np.asarray(t.values) + record_error(t.values, rms, semi_distance, rng)
            )
            for t in tracks
        ]
        change = np.asarray(residuals_with(perturbed), dtype=float) - r0
        if np.all(np.isfinite(change)):
            shifts.append(-pinv @ change)
    if not shifts:
        n = pinv.shape[0]
        return np.full((n, n), np.nan), 0
    s = np.array(shifts)
    return s.T @ s / len(shifts), len(shifts)
