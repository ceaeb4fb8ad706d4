"""The shape of the track records' error (`bogie_jax/monitor/_record_shape.py`), against numpy
and scipy oracles on linear models (no simulation): a white error's spectrum and level, the
term of a mixed error against a Monte Carlo of that error, and the white share against scipy's
Fisher combination of p-values."""

import types

import numpy as np
import pytest
import scipy.stats

from bogie_jax.monitor import (
    RECORD_BAND,
    GoodnessOfFit,
    Misfit,
    RecordError,
    Sampling,
    mixed_effect,
    mixed_record_term,
    track_error_effect,
    white_share,
)
from bogie_jax.track import TrackIrregularity


SEMI = 0.7465  # [m] contact semi-distance b_0
DS = 0.25  # [m] record spacing


def _record(rng, n):
    """A red (track-like) record of n samples: cumulated white noise, three channels."""
    return np.cumsum(rng.standard_normal((n, 3)), axis=0) * np.array([1e-4, 2e-4, 1e-4])


def test_a_band_error_is_white_over_the_band_with_the_stated_level():
    """Oracle: the discrete Fourier transform. Over 400 draws the mean power of every bin inside
    the band is the same (chi^2_2 per draw: relative spread 1 / sqrt(400) = 5 % per bin, held
    to 25 %), none lies outside, each draw has the stated RMS per channel exactly, and a
    channel without power in the record gets none."""
    rng = np.random.default_rng(0)
    n, rms = 1200, 2e-4
    values = _record(rng, n)
    values[:, 2] = 0.0
    track = TrackIrregularity(0.0, DS, values)
    error = RecordError(rms, SEMI, RECORD_BAND)
    draws = np.array([error.draw(track, rng) for _ in range(400)])
    np.testing.assert_allclose(np.sqrt(np.mean(draws**2, axis=1))[:, :2], rms, rtol=1e-12)
    assert np.all(draws[:, :, 2] == 0.0)
    power = np.mean(np.abs(np.fft.rfft(draws[:, :, :2], axis=1)) ** 2, axis=0)
    wavenumber = np.fft.rfftfreq(n, d=DS)
    inside = (wavenumber >= 1 / RECORD_BAND[1]) & (wavenumber <= 1 / RECORD_BAND[0])
    assert inside.sum() > 80 and np.all(power[~inside] < 1e-20 * power[inside].mean())
    np.testing.assert_allclose(power[inside] / power[inside].mean(axis=0), 1.0, atol=0.25)


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
    fit = types.SimpleNamespace(evaluate_on=evaluate_at, residuals_on=residuals_at)

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


def _goodness(p_values):
    tests = tuple(
        Misfit(run=k, group=f"g{k}", channels=("c",), statistic=1.0, expected=1.0,
               track_record=0.0, ratio=1.0, p_value=float(p))
        for k, p in enumerate(p_values)
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
    got = white_share(lambda w: _goodness(p_at(w)))
    assert got == pytest.approx(shares[int(np.argmin(combined))], abs=1e-12)
    assert 0.0 <= got <= 1.0


def test_the_white_share_breaks_ties_towards_the_track_shape():
    """Every share equally surprising (every p-value at the floor): no white share."""
    assert white_share(lambda w: _goodness([0.0, 0.0])) == 0.0


@pytest.mark.parametrize("white", [0.0, 0.85])
def test_the_record_errors_shape_is_told_in_the_summary_json_and_report(white, tmp_path):
    """The white share (`FitSummary.track_error_white_share`) in the result's summary,
    `verdicts.json` and the report's rules (constructed result: nothing is simulated)."""
    from bogie_jax.io import verdicts_record, write_report
    from bogie_jax.monitor import FitSummary, MonitorResult, ToleranceBand, judge

    band = ToleranceBand((3.2e5, 4.8e5), unit="N s/m", failed_below=1e5)
    verdict = judge("yaw_dampers.left.c", 4.0e5, 1e4, band, z=2.96, identifiable=True)
    fit = FitSummary(
        names=("yaw_dampers.left.c",), status="converged", steps=3, evaluations=4, cost=1.0,
        noise_variance=1.0, sigma2=1.0, rank=1, condition_number=1.0, runs_used=1,
        track_error=3e-4, track_error_draws=16, track_error_white_share=white,
    )  # fmt: skip
    result = MonitorResult((verdict,), (), fit, (), 0.05, {})
    told = "85 % of its variance white over the recording band"
    assert (told in result.table()) is (white > 0)
    record = verdicts_record(result, date="2026-11-29")
    assert record["fit"]["track_error_white_share"] == white
    text = write_report(tmp_path / "report.md", record).read_text()
    assert "0.3 mm RMS included" in text
    assert (told in text) is (white > 0)
    assert ("shaped like the track" in text) is True
    assert ("not taken as explained by it" in result.table()) is (white > 0)
