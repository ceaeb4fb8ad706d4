"""`FlatSpectrum`: band-limited white irregularity, against analytic oracles.

- its variance over a band is the level times the band's width in rad/m (the integral of a
  constant), and `with_rms` inverts that;
- a synthesis over a band has its power inside the band, spread evenly over frequency (a
  windowed periodogram of the realisation, numpy's FFT), and the RMS asked for.
"""

import math

import jax.random as jr
import numpy as np
import pytest

from bogie_jax.track import FlatSpectrum, band_variance, synthesise_track


BAND = (3.0, 70.0)  # [m]


def width(band):
    """The band's width in spatial angular frequency [rad/m]."""
    return 2 * math.pi / band[0] - 2 * math.pi / band[1]


def test_band_variance_is_level_times_band_width():
    psd = FlatSpectrum(alignment=2e-8, vertical=5e-8, cross_level=3e-9)
    for band in (BAND, (70.0, 200.0), (1.0, 3.0)):
        expected = np.array([2e-8, 5e-8, 3e-9]) * width(band)
        # Gauss-Legendre integrates a constant exactly: equal to rounding
        np.testing.assert_allclose(band_variance(psd, band), expected, rtol=1e-12)


def test_with_rms_gives_the_rms_over_its_band():
    rms = np.array([0.2e-3, 0.3e-3, 0.1e-3])
    for band in (BAND, (70.0, 200.0)):
        psd = FlatSpectrum.with_rms(*rms, wavelength_band=band)
        np.testing.assert_allclose(np.sqrt(band_variance(psd, band)), rms, rtol=1e-12)
    value = np.asarray(psd(np.array([[0.01, 1.0], [5.0, 30.0]])))
    assert value.shape == (2, 2, 3) and np.all(value == value[0, 0])  # flat in omega


@pytest.mark.parametrize(
    "bad", [dict(wavelength_band=(70.0, 3.0)), dict(wavelength_band=(0.0, 3.0)), dict(rms=0.0)]
)
def test_with_rms_rejects_a_bad_band_or_rms(bad):
    rms = bad.pop("rms", 1e-3)
    with pytest.raises(ValueError):
        FlatSpectrum.with_rms(rms, 1e-3, 1e-3, **bad)


def test_synthesis_is_white_within_the_band():
    """8 km at 0.25 m spacing without fades: the Hann-windowed periodogram holds >= 99 % of its
    power at wavelengths within the band widened by 5 % (window leakage), and the band's lower
    and upper halves in omega hold equal power to 15 % (a flat spectrum: the ratio's spread
    over keys is about 5 % at this length); the realisation's RMS is the asked one to 5 %."""
    rms = np.array([0.3e-3, 0.2e-3, 0.2e-3])
    psd = FlatSpectrum.with_rms(*rms, wavelength_band=BAND)
    track = synthesise_track(
        psd, key=jr.PRNGKey(7), length=8000.0, wavelength_band=BAND, fade_length=0.0
    )
    x = np.asarray(track.values)
    np.testing.assert_allclose(np.sqrt(np.mean(x**2, axis=0)), rms, rtol=0.05)
    window = np.hanning(len(x))[:, None]
    power = np.abs(np.fft.rfft(x * window, axis=0)) ** 2
    omega = 2 * math.pi * np.fft.rfftfreq(len(x), d=float(track.ds))
    lo, hi = 2 * math.pi / BAND[1], 2 * math.pi / BAND[0]
    inside = (omega >= lo / 1.05) & (omega <= hi * 1.05)
    assert np.all(power[inside].sum(axis=0) / power.sum(axis=0) >= 0.99)
    mid = 0.5 * (lo + hi)
    lower = power[(omega >= lo) & (omega < mid)].sum(axis=0)
    upper = power[(omega >= mid) & (omega <= hi)].sum(axis=0)
    np.testing.assert_allclose(lower / upper, 1.0, atol=0.15)
