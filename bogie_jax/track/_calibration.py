"""A track record calibrated for a white recording error: the Wiener estimate of the track.

A recording car's record x_r = x + e holds the track x and an error e. Where e is white over a
wavelength band with a known RMS, its power spectral density S_e is known; the record's own
S_r = S_x + S_e is estimated from its periodogram, smoothed, and the track's best linear
estimate from the record is the Wiener filter (Wiener, *Extrapolation, Interpolation, and
Smoothing of Stationary Time Series*, 1949; Bendat and Piersol, *Random Data*, 4th ed. 2010,
sec. 6.1): X_hat(k) = H(k) X_r(k) with H = S_x / S_r = max(1 - S_e / S_r, 0), S_r the running
mean of the record's periodogram over `SMOOTHING_BINS` bins of the band (Bendat and Piersol,
sec. 11.5: frequency smoothing), its inverse made unbiased for the mean's chi-squared spread.

Why a fit wants it (regression calibration: Carroll et al., *Measurement Error in Nonlinear
Models*, 2nd ed. 2006, ch. 4): the bogie's response is linear in the track (the linear contact
model), so the response to the track is that to X_hat plus that to x - X_hat; for jointly
normal stationary x and e the latter is uncorrelated with X_hat, so a least-squares fit on
X_hat is not attenuated the way a fit on the raw record is, where the error's share of a band
makes the model's response there look too large for the measured one. Where the error
dominates a band (S_e >= S_r) the band is taken out of the record altogether.
"""

import numpy as np

from ._irregularity import TrackIrregularity


SMOOTHING_BINS = 21  # periodogram bins in the running mean that estimates S_r (odd; in-band only)


def wiener_gain(values, ds: float, error_rms, band) -> np.ndarray:
    """The gain H `(k, 3)` on the record `values` `(n, 3)` sampled every `ds` [m] (rfft bins)
    for an error white over the wavelength `band` (lo, hi) [m] of RMS `error_rms` `(3,)` per
    channel (module docstring); 1 outside the band."""
    v = np.asarray(values, dtype=float)
    n = v.shape[0]
    k = np.fft.rfftfreq(n, d=ds)
    inside = (k >= 1.0 / band[1]) & (k <= 1.0 / band[0])
    power = np.abs(np.fft.rfft(v - v.mean(axis=0), axis=0)) ** 2 * inside[:, None]
    kernel = np.ones(SMOOTHING_BINS)
    count = np.convolve(inside.astype(float), kernel, mode="same")  # in-band bins in the mean
    total = np.stack([np.convolve(power[:, c], kernel, mode="same") for c in range(v.shape[1])], 1)
    smooth = total / np.maximum(count, 1.0)[:, None]
    # the white error's expected periodogram: its variance n^2 rms^2 / 2 over the band's bins
    error_power = n**2 * np.asarray(error_rms, dtype=float) ** 2 / (2.0 * max(inside.sum(), 1))
    # a mean of `count` periodogram ordinates is S chi^2_nu / nu with nu = 2 count, and
    # E[1 / that] = nu / ((nu - 2) S): the factor makes S_e / S_r unbiased
    unbias = np.clip(1.0 - 1.0 / np.maximum(count, 1.0), 0.0, 1.0)[:, None]
    ratio = unbias * error_power[None, :] / np.where(smooth > 0, smooth, np.inf)
    gain = np.clip(1.0 - ratio, 0.0, 1.0)
    return np.where(inside[:, None], gain, 1.0)


def calibrated_record(
    track: TrackIrregularity, error_rms: float, band, semi_distance: float
) -> TrackIrregularity:
    """`track` (a record) with its white error taken out by the Wiener filter (module
    docstring): the error white over the wavelength `band` (lo, hi) [m] with RMS `error_rms`
    [m] in alignment and vertical level and `error_rms / (2 semi_distance)` [rad] in cross
    level."""
    v = np.asarray(track.values, dtype=float)
    rms = np.array([error_rms, error_rms, error_rms / (2.0 * semi_distance)])
    gain = wiener_gain(v, float(np.asarray(track.ds)), rms, band)
    mean = v.mean(axis=0)
    out = mean + np.fft.irfft(gain * np.fft.rfft(v - mean, axis=0), n=v.shape[0], axis=0)
    return TrackIrregularity(float(np.asarray(track.s0)), float(np.asarray(track.ds)), out)
