"""The shape of the track records' error (`bogie_jax/monitor/_record_shape.py`), against numpy
and scipy oracles on linear models (no simulation): a white error's spectrum and level, the
term of a mixed error against a Monte Carlo of that error, and the white share against scipy's
Fisher combination of p-values."""

import types

import numpy as np
import pytest
import scipy.integrate
import scipy.stats

from bogie_jax.monitor import (
    LONG_BAND,
    LONG_SHARES,
    RECORD_BAND,
    GoodnessOfFit,
    Misfit,
    RecordError,
    Sampling,
    TrackErrorEffect,
    least_surprising_share,
    mixed_effect,
    mixed_record_term,
    track_error_effect,
)
from bogie_jax.track import FADE_LENGTH, TrackIrregularity, TrackReference, fade_envelope


SEMI = 0.7465  # [m] contact semi-distance b_0
DS = 0.25  # [m] record spacing


def _record(rng, n):
    """A red (track-like) record of n samples: cumulated white noise, three channels."""
    return np.cumsum(rng.standard_normal((n, 3)), axis=0) * np.array([1e-4, 2e-4, 1e-4])


def _band_correlation(lag, band):
    """The autocorrelation at `lag` [m] of a process white over the wavelength `band` [m]:
    (sin 2 pi k_hi lag - sin 2 pi k_lo lag) / (2 pi lag (k_hi - k_lo)), k = 1 / wavelength."""
    k_lo, k_hi = 1.0 / band[1], 1.0 / band[0]
    return (np.sin(2 * np.pi * k_hi * lag) - np.sin(2 * np.pi * k_lo * lag)) / (
        2 * np.pi * lag * (k_hi - k_lo)
    )


def _curvature_share(band):
    """E (x_{t+1} - 2 x_t + x_{t-1})^2 / E x^2 of a process white over `band` sampled every
    `DS`: the integral of (2 - 2 cos 2 pi k DS)^2 over the band's wavenumbers over its width
    (scipy quadrature)."""
    k_lo, k_hi = 1.0 / band[1], 1.0 / band[0]
    value, _ = scipy.integrate.quad(lambda k: (2 - 2 * np.cos(2 * np.pi * k * DS)) ** 2, k_lo, k_hi)
    return value / (k_hi - k_lo)


@pytest.mark.parametrize(
    "band, n, stationary",
    [(RECORD_BAND, 1200, False), (RECORD_BAND, 1200, True), (LONG_BAND, 4800, True),
     (LONG_BAND, 480, True)],
)  # fmt: skip
def test_a_band_error_is_white_over_the_band_with_the_stated_level(band, n, stationary):
    """Oracles: the autocorrelation of a process white over the band (`_band_correlation`) and
    its second differences' variance (`_curvature_share`, scipy quadrature), over 400 draws on
    records of 300 m and 1200 m, and on a record of 120 m, shorter than the long band's waves
    (only the curvature: a draw scaled to its record's RMS has a biased correlation there; on
    the record's own grid that record holds one wave of the band, periodic). Each draw has the
    stated RMS per channel exactly, and a channel without power in the record gets none."""
    rng = np.random.default_rng(0)
    rms = 2e-4
    values = _record(rng, n)
    values[:, 2] = 0.0
    track = TrackIrregularity(0.0, DS, values)
    error = RecordError(rms, SEMI, band, stationary)
    draws = np.array([error.draw(track, rng) for _ in range(400)])[:, :, :2]
    if n * DS < band[1]:  # the record's own grid: one wave of the band, its own length
        own = np.abs(np.fft.rfft(RecordError(rms, SEMI, band).draw(track, rng)[:, :2], axis=0))
        assert np.all(np.sum(own > 1e-9 * own.max(axis=0), axis=0) == 1) and own[1].min() > 0
    np.testing.assert_allclose(np.sqrt(np.mean(draws**2, axis=1)), rms, rtol=1e-12)
    curvature = np.mean(np.diff(draws, 2, axis=1) ** 2) / np.mean(draws[:, 1:-1] ** 2)
    assert curvature == pytest.approx(_curvature_share(band), rel=0.1)
    if n * DS >= 2 * band[1]:
        for lag in (1, 4, 12, 40, 120):
            got = np.sum(draws[:, lag:] * draws[:, :-lag]) / np.sum(draws[:, lag:] ** 2)
            assert got == pytest.approx(_band_correlation(lag * DS, band), abs=0.04), lag
    zero = np.array([error.draw(track, rng)[:, 2] for _ in range(3)])
    assert np.all(zero == 0.0)


def test_a_band_error_fades_in_and_out_as_a_synthetic_record_does():
    """A synthetic record starts and ends at zero (its fades): so does a stationary band error
    drawn for it (oracle: `bogie_jax.track.fade_envelope`'s zeros and ones), at the stated RMS;
    over the record's middle it is the unfaded error's shape. On the record's own grid it is
    not faded."""
    reference = TrackReference(spectrum="erri-low", seed=3, length=150.0)
    track = reference.build()
    own_grid = RecordError(3e-4, SEMI, RECORD_BAND).draw(track, np.random.default_rng(1), reference)
    assert np.all(own_grid[0, :2] != 0.0)
    for band in (RECORD_BAND, LONG_BAND):
        error = RecordError(3e-4, SEMI, band, stationary=True)
        faded = error.draw(track, np.random.default_rng(1), reference)
        plain = error.draw(track, np.random.default_rng(1))
        np.testing.assert_array_equal(faded[[0, -1]], 0.0)
        assert np.all(plain[0] != 0.0)
        np.testing.assert_allclose(np.sqrt(np.mean(faded**2, axis=0))[:2], 3e-4, rtol=1e-12)
        s = track.ds * np.arange(faded.shape[0])
        middle = fade_envelope(s, FADE_LENGTH) == 1.0
        ratio = faded[middle] / plain[middle]
        np.testing.assert_allclose(ratio, np.broadcast_to(ratio[0], ratio.shape), rtol=1e-9)


class _Mixture:
    """A record error sqrt(1 - w) times a track-shaped and sqrt(w) times a white one, each at
    the full RMS and drawn independently: the error whose term `mixed_effect` claims to be."""

    def __init__(self, rms, w):
        self.track, self.white, self.w = (
            RecordError(rms, SEMI),
            RecordError(rms, SEMI, RECORD_BAND),
            w,
        )

    def draw(self, track, rng, reference=None):
        a = self.track.draw(track, rng, reference)
        return np.sqrt(1 - self.w) * a + np.sqrt(self.w) * self.white.draw(track, rng, reference)


def test_the_mixed_term_is_the_term_of_the_mixed_error():
    """A model linear in its record, r = y - A phi - G e: the covariance of the estimates' shift
    and the misfit outside the span of A of a mixed error (`_Mixture`, 3000 draws) against
    `mixed_effect` of the two shapes' terms (3000 draws each). The relative error of a variance
    from 3000 draws is about sqrt(2 / 3000) = 2.6 %; held to 12 %. The model responds to the
    record's curvature, where the shapes' powers differ: their terms differ several-fold,
    so the check separates w from 1 - w."""
    rng = np.random.default_rng(1)
    n_s, m, n, rms, w = 121, 150, 3, 3e-4, 0.3
    values = _record(rng, n_s)
    track = TrackIrregularity(0.0, DS, values)
    a = rng.standard_normal((m, n))
    # a response to the record's curvature (second differences): short waves count most
    curvature = np.kron(np.diff(np.eye(n_s), 2, axis=0), np.eye(3)) / DS**2
    g = rng.standard_normal((m, curvature.shape[0])) @ curvature * 10.0
    y = rng.standard_normal(m)

    def evaluate_at(tracks, phi):
        e = np.asarray(tracks[0].values) - values
        return y - a @ phi - g @ e.reshape(-1), -a

    residuals_at = lambda tracks, phi: evaluate_at(tracks, phi)[0]
    fit = types.SimpleNamespace(
        evaluate_on=evaluate_at, residuals_on=residuals_at, fit_residuals_on=residuals_at
    )

    def term(error, seed):
        return track_error_effect(fit, [track], np.zeros(n), error, Sampling(3000, seed=seed))

    shaped, white = term(RecordError(rms, SEMI), 2), term(RecordError(rms, SEMI, RECORD_BAND), 3)
    ratio = np.diag(white.covariance) / np.diag(shaped.covariance)
    assert np.all((ratio < 0.5) | (ratio > 2.0))  # the shapes' terms differ several-fold
    mixed, direct = mixed_effect(shaped, white, w), term(_Mixture(rms, w), 4)
    np.testing.assert_allclose(np.diag(mixed.covariance), np.diag(direct.covariance), rtol=0.12)
    assert mixed.misfit_ss == pytest.approx(direct.misfit_ss, rel=0.12)
    mean_power = np.mean(np.sum(mixed.misfits**2, axis=1))
    assert mean_power == pytest.approx(mixed.misfit_ss, rel=1e-9)
    assert mixed.white_share == w
    # the term `record_term` returns keeps the track-shaped misfits (the data stay not
    # explained); the misfit scale reads the mixture's
    kept = mixed._replace(misfits=shaped.misfits, mixed_misfits=mixed.misfits)
    np.testing.assert_array_equal(mixed_record_term(kept).misfits, mixed.misfits)
    assert mixed_record_term(shaped) is shaped
    assert mixed_effect(shaped, white, 0.0) is shaped
    assert mixed_effect(shaped, white, 1.0).white_share == 1.0


def _goodness(p_values, p_lower=None):
    p_lower = [float("nan")] * len(p_values) if p_lower is None else p_lower
    tests = tuple(
        Misfit(run=k, group=f"g{k}", channels=("c",), statistic=1.0, expected=1.0,
               track_record=0.0, ratio=1.0, p_value=float(p), p_lower=float(q))
        for k, (p, q) in enumerate(zip(p_values, p_lower))
    )  # fmt: skip
    return GoodnessOfFit(tests, 0.05)


@pytest.mark.parametrize(
    "centres, widths",
    [
        ([0.3, 0.35, 0.4, 0.3], [0.2, 0.2, 0.3, 0.1]),  # every group best near a third white
        ([0.0, 0.05, 0.1, 0.0], [0.1, 0.2, 0.2, 0.3]),  # the track shape fits: none white
        ([0.9, 1.4, 1.2, 2.0], [0.3, 0.3, 0.5, 0.4]),  # even all white falls short: 1
        ([0.8, 0.0, 0.0, 0.0], [0.2, 0.05, 0.05, 0.05]),  # one group wants it, three do not
    ],
)
def test_the_white_share_is_the_least_surprising_of_the_grid(centres, widths):
    """Oracle: scipy's Fisher combination (`scipy.stats.combine_pvalues`) of each group's
    p-value, p_g(w) = exp(-((w - c_g) / s_g)^2), minimised over the same 21 shares by brute
    force."""
    c, s = np.array(centres), np.array(widths)

    def p_at(w):
        return np.maximum(np.exp(-(((w - c) / s) ** 2)), 1e-300)

    shares = np.linspace(0.0, 1.0, 21)
    combined = [scipy.stats.combine_pvalues(p_at(w), method="fisher")[0] for w in shares]
    got = least_surprising_share(lambda w: _goodness(p_at(w)))
    assert got == pytest.approx(shares[int(np.argmin(combined))], abs=1e-12)
    assert 0.0 <= got <= 1.0


@pytest.mark.parametrize(
    "observed",
    [
        [0.003, 0.002, 0.005, 0.004],  # a drift: the data hold 0.2-0.5 % of the shaped misfit
        [1.0, 0.9, 1.1, 1.0],  # the track shape fits: no long waves
        [0.3, 0.5, 0.2, 0.4],  # a part of the error is long-wave
    ],
)
def test_the_long_wave_share_is_the_least_surprising_in_both_tails(observed):
    """Oracle: scipy's Fisher combination of each group's two-sided p-value, a group's log
    statistic normal about the log of its null mean 1 - w (the long-wave term leaving a
    thousandth of the shaped one's misfit), minimised over `LONG_SHARES` by brute force; the
    grid runs from 0 to 1, 1 - w down to 1e-4."""
    x = np.log(np.array(observed))

    def tails(w):
        z = (x - np.log(1.0 - w + 0.001 * w)) / 0.3
        return scipy.stats.norm.sf(z), scipy.stats.norm.cdf(z)

    def two_sided(w):
        p, q = tails(w)
        return np.maximum(np.minimum(2 * np.minimum(p, q), 1.0), 1e-300)

    combined = [scipy.stats.combine_pvalues(two_sided(w), method="fisher")[0] for w in LONG_SHARES]
    got = least_surprising_share(lambda w: _goodness(*tails(w)), LONG_SHARES, two_sided=True)
    assert got == pytest.approx(LONG_SHARES[int(np.argmin(combined))], abs=1e-12)
    assert LONG_SHARES[0] == 0.0 and LONG_SHARES[-1] == 1.0
    assert np.all(np.diff(LONG_SHARES) > 0) and 1.0 - LONG_SHARES[-2] == pytest.approx(1e-4)
    if observed[0] < 0.01:
        assert 0.99 < got < 1.0  # the drift: nearly all long-wave
    elif observed[0] == 1.0:
        assert got < 0.3


def test_a_long_wave_mixture_records_its_share_in_its_own_field():
    """`mixed_effect` with `share="long_wave_share"`: the long-wave share in its field, the
    white share 0; the covariance mixes linearly (oracle: the two terms' weighted sum)."""
    rng = np.random.default_rng(7)
    n, m = 3, 20

    def term(scale):
        first = rng.standard_normal((8, n)) * scale
        return TrackErrorEffect(
            covariance=first.T @ first / 8, bias=np.full(n, scale), draws=8,
            misfit_ss=scale**2, bias_by_step=np.full((2, n), scale), refit_draws=4,
            misfits=rng.standard_normal((8, m)) * scale, bias_variance=np.full(n, scale**2),
        )  # fmt: skip

    shaped, long = term(1.0), term(0.01)
    mixed = mixed_effect(shaped, long, 0.99, "long_wave_share")
    assert mixed.long_wave_share == 0.99 and mixed.white_share == 0.0
    np.testing.assert_allclose(mixed.covariance, 0.01 * shaped.covariance + 0.99 * long.covariance)
    np.testing.assert_allclose(mixed.bias, 0.01 * 1.0 + 0.99 * 0.01)
    assert mixed_effect(shaped, long, 1.0, "long_wave_share").long_wave_share == 1.0
    assert LONG_BAND[0] == RECORD_BAND[1]  # the long waves begin where the record's band ends


def test_the_white_share_breaks_ties_towards_the_track_shape():
    """Every share equally surprising (every p-value at the floor): no white share."""
    assert least_surprising_share(lambda w: _goodness([0.0, 0.0])) == 0.0


@pytest.mark.parametrize("white, long", [(0.0, 0.0), (0.85, 0.0), (0.0, 0.9999)])
def test_the_record_errors_shape_is_told_in_the_summary_json_and_report(white, long, tmp_path):
    """The white and long-wave shares (`FitSummary.track_error_white_share`,
    `track_error_long_wave_share`) in the result's summary, `verdicts.json` and the report's
    rules (constructed result: nothing is simulated)."""
    from bogie_jax.io import verdicts_record, write_report
    from bogie_jax.monitor import FitSummary, MonitorResult, ToleranceBand, judge

    band = ToleranceBand((3.2e5, 4.8e5), unit="N s/m", failed_below=1e5)
    verdict = judge("yaw_dampers.left.c", 4.0e5, 1e4, band, z=2.96, identifiable=True)
    fit = FitSummary(
        names=("yaw_dampers.left.c",), status="converged", steps=3, evaluations=4, cost=1.0,
        noise_variance=1.0, sigma2=1.0, rank=1, condition_number=1.0, runs_used=1,
        track_error=3e-4, track_error_draws=16, track_error_white_share=white,
        track_error_long_wave_share=long, track_records_calibrated=white > 0,
    )  # fmt: skip
    result = MonitorResult((verdict,), (), fit, (), 0.05, {})
    told = "85 % of its variance white over the recording band"
    drift = "99.99 % of its variance long-wave drift (70-200 m"
    assert (told in result.table()) is (white > 0)
    assert (drift in result.table()) is (long > 0)
    record = verdicts_record(result, date="2026-11-29")
    assert record["fit"]["track_error_white_share"] == white
    assert record["fit"]["track_error_long_wave_share"] == long
    text = write_report(tmp_path / "report.md", record).read_text()
    assert "0.3 mm RMS included" in text
    assert (told in text) is (white > 0)
    assert (drift in text) is (long > 0)
    assert ("shaped like the track" in text) is True
    assert ("not taken as explained by it" in result.table()) is (white > 0)
    assert ("records calibrated for it" in result.table()) is (white > 0)
    assert ("records calibrated for it" in text) is (white > 0)
