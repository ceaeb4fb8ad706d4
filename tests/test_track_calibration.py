"""The Wiener calibration of a record for a white error, against the analytic Wiener gain and
the regression slope it should restore."""

import numpy as np
import pytest

from bogie_jax.track import TrackIrregularity, calibrated_record, wiener_gain


DS = 0.25  # [m]
N = 65536
BAND = (3.0, 70.0)  # [m]


def band_white(rng, rms, band=BAND, n=N):
    """`(n, 3)` white over the wavelength `band` [m], scaled to RMS `rms` per channel."""
    k = np.fft.rfftfreq(n, DS)
    inside = (k >= 1 / band[1]) & (k <= 1 / band[0])
    c = (rng.standard_normal((k.size, 3)) + 1j * rng.standard_normal((k.size, 3))) * inside[:, None]
    x = np.fft.irfft(c, n=n, axis=0)
    return x * (np.asarray(rms) / np.sqrt(np.mean(x**2, axis=0)))


def in_band(k):
    return (k >= 1 / BAND[1]) & (k <= 1 / BAND[0])


@pytest.mark.parametrize("ratio", [0.5, 1.0, 2.0])
def test_gain_is_the_analytic_wiener_gain_for_white_track_and_error(ratio):
    """Track and error both white over the band, RMS sigma_x and sigma_e: H = sigma_x^2 /
    (sigma_x^2 + sigma_e^2) in the band (Wiener 1949), 1 outside."""
    rng = np.random.default_rng(3)
    rms_e = np.array([1e-3, 1e-3, 1e-3])
    x = band_white(rng, ratio * rms_e)
    e = band_white(rng, rms_e)
    gain = wiener_gain(x + e, DS, rms_e, BAND)
    k = np.fft.rfftfreq(N, DS)
    expected = ratio**2 / (ratio**2 + 1.0)
    assert np.mean(gain[in_band(k)], axis=0) == pytest.approx([expected] * 3, abs=0.03)
    assert np.all(gain[~in_band(k)] == 1.0)


def test_calibration_restores_the_regression_slope():
    """A track whose spectrum falls as k^-2 plus an error white over the band: the least-squares
    slope of the track on the raw record in the short waves is attenuated (S_x / (S_x + S_e) <
    0.6), on the calibrated record it is 1 within 0.1 (regression calibration)."""
    rng = np.random.default_rng(7)
    k = np.fft.rfftfreq(N, DS)
    shape = np.where(k > 1 / 200.0, 1.0 / np.maximum(k, 1e-9), 0.0)
    coefficients = (
        rng.standard_normal((k.size, 3)) + 1j * rng.standard_normal((k.size, 3))
    ) * shape[:, None]
    x = np.fft.irfft(coefficients, n=N, axis=0)
    x *= np.array([2e-3, 2e-3, 2e-3 / 1.5]) / np.sqrt(np.mean(x**2, axis=0))
    e = band_white(rng, [3e-4, 3e-4, 3e-4 / 1.5])
    record = TrackIrregularity(0.0, DS, x + e)
    calibrated = np.asarray(calibrated_record(record, 3e-4, BAND, semi_distance=0.75).values)
    short = (k >= 1 / 5.0) & (k <= 1 / 3.0)

    def slope(y):
        X, Y = np.fft.rfft(x, axis=0)[short], np.fft.rfft(y, axis=0)[short]
        return np.real(np.sum(np.conj(Y) * X, axis=0)) / np.sum(np.abs(Y) ** 2, axis=0)

    assert np.all(slope(x + e) < 0.6)
    assert slope(calibrated) == pytest.approx([1.0] * 3, abs=0.1)


def test_no_error_leaves_the_record():
    rng = np.random.default_rng(1)
    x = band_white(rng, [1e-3, 1e-3, 1e-3])
    record = TrackIrregularity(0.0, DS, x)
    out = calibrated_record(record, 0.0, BAND, semi_distance=0.75)
    np.testing.assert_allclose(np.asarray(out.values), x, atol=1e-15)
