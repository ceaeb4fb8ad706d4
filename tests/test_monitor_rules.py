"""The verdict rule and the drift test: error rates from repeated random trials (counts stated
in each test), the t tail and quantile against scipy, the 95 % interval with a Monte Carlo
variance, and bad input."""

import math

import numpy as np
import pytest
import scipy.stats

from bogie_jax.monitor import (
    WATCH_NOTE,
    FitSummary,
    MonitorResult,
    ToleranceBand,
    decision_z,
    judge,
    satterthwaite_dof,
    t_quantile,
    trend,
    two_sided_p_value,
    verdict_label,
)


BAND = ToleranceBand.relative(400e3, 0.2, unit="N s/m")  # healthy 320-480 kN s/m, failed < 100


def test_verdict_categories():
    z = decision_z(0.05, 1)
    assert judge("d", 400e3, 10e3, BAND, z=z).verdict == "healthy"
    assert judge("d", 200e3, 10e3, BAND, z=z).verdict == "degraded"
    assert judge("d", 20e3, 10e3, BAND, z=z).verdict == "failed"
    assert judge("d", 300e3, 20e3, BAND, z=z).verdict == "healthy"  # interval reaches the band
    assert judge("d", 400e3, 60e3, BAND, z=z).verdict == "not identifiable"  # wider than band
    assert judge("d", 400e3, 10e3, BAND, z=z, identifiable=False).verdict == "not identifiable"
    v = judge("d", 200e3, 10e3, BAND, z=z)
    assert v.ci95 == pytest.approx((200e3 - 1.959964 * 10e3, 200e3 + 1.959964 * 10e3))
    assert v.to_dict()["tolerance_band"]["healthy"] == [320e3, 480e3]


def test_false_alarm_rate_of_a_healthy_bogie_is_at_most_alpha():
    """20 000 simulated healthy bogies of 4 elements each, every true value on the edge of
    its band (the worst case), estimates with their correct standard errors."""
    rng = np.random.default_rng(0)
    alpha, m, trials = 0.05, 4, 20_000
    z = decision_z(alpha, m)
    truth = np.array([320e3, 480e3, 320e3, 480e3])
    se = np.array([20e3, 15e3, 10e3, 25e3])
    estimates = truth + se * rng.standard_normal((trials, m))
    alarms = np.array(
        [
            any(judge("e", e, s, BAND, z=z).verdict != "healthy" for e, s in zip(row, se))
            for row in estimates
        ]
    )
    rate = alarms.mean()
    # exact rate at the edges: m * alpha / (2 m) = alpha / 2; binomial 4-sigma margin
    assert rate <= alpha / 2 + 4 * np.sqrt(alpha / 2 / trials)
    assert rate >= alpha / 2 - 4 * np.sqrt(alpha / 2 / trials)


def test_a_halved_damper_is_found_when_its_error_is_small():
    """2 000 trials of a damper at 50 % with a 3 % standard error: detected in all of them."""
    rng = np.random.default_rng(1)
    z = decision_z(0.05, 4)
    found = [
        judge("d", 200e3 + 6e3 * rng.standard_normal(), 6e3, BAND, z=z).verdict != "healthy"
        for _ in range(2000)
    ]
    assert all(found)


def test_watch_flags_an_interval_outside_the_band_that_raises_no_alarm():
    """`Verdict.watch`: the 95 % interval wholly outside the band while no test rejects."""
    z = decision_z(0.05, 10)  # 2.81: Wald at the edge 2.5 rejects nothing below
    above = judge("d", 505e3, 10e3, BAND, z=z)  # 95 %: 485-525 > 480
    assert (above.verdict, above.watch) == ("healthy", "above")
    below = judge("d", 295e3, 10e3, BAND, z=z)  # 95 %: 275-315 < 320
    assert (below.verdict, below.watch) == ("healthy", "below")
    wide = judge("d", 560e3, 30e3, BAND, z=z)  # decision interval 168e3 > the band's 160e3
    assert (wide.verdict, wide.watch) == ("not identifiable", "above")
    assert judge("d", 495e3, 10e3, BAND, z=z).watch is None  # 95 %: 475-515 reaches the band
    assert judge("d", 200e3, 10e3, BAND, z=z).watch is None  # degraded: an alarm, no watch
    assert judge("d", 505e3, 10e3, BAND, z=z, identifiable=False).watch is None
    assert verdict_label(above.verdict, above.watch) == "healthy*"
    assert above.to_dict()["evidence"]["watch"] == "above"
    fit = FitSummary(("d",), "converged", 1, 1, 0.0, 1.0, 1.0, 1, 1.0, 1)
    result = MonitorResult((above, judge("e", 400e3, 10e3, BAND, z=z)), (), fit, (), 0.05, {})
    assert result.watches == (above,) and not result.alarms
    table = result.table()
    assert "healthy*" in table.splitlines()[1] and table.splitlines()[-1] == WATCH_NOTE


def test_watch_rate_of_an_element_on_its_band_edge_is_one_tail():
    """20 000 estimates of an element on its band's upper edge with their correct standard
    error: flagged where the 95 % interval clears the edge and the Wald test at z does not
    reject, P(1.96 < Z < z) = 2.25 % (alarms take the rest of the tail): bounded by one
    interval's tail, 2.5 %, not by alpha / m."""
    rng = np.random.default_rng(2)
    trials, se = 20_000, 15e3
    z = decision_z(0.05, 10)
    flags = [judge("e", e, se, BAND, z=z).watch for e in 480e3 + se * rng.standard_normal(trials)]
    rate = np.mean([f == "above" for f in flags])
    assert not any(f == "below" for f in flags)
    expected = scipy.stats.norm.cdf(z) - scipy.stats.norm.cdf(1.959964)
    assert abs(rate - expected) <= 4 * np.sqrt(expected * (1 - expected) / trials)


def test_zero_width_band_and_bad_alpha_are_refused():
    with pytest.raises(ValueError, match="zero width"):
        ToleranceBand((1.0, 1.0))
    with pytest.raises(ValueError, match="false_alarm_rate"):
        decision_z(0.0, 3)
    with pytest.raises(ValueError, match="failed_below"):
        ToleranceBand((1.0, 2.0), failed_below=1.5)


@pytest.mark.parametrize("dof", [1, 3, 7, 30])
def test_student_t_tail_matches_scipy(dof):
    for t in (0.1, 1.0, 2.5, 8.0):
        assert two_sided_p_value(t, dof) == pytest.approx(2 * scipy.stats.t.sf(t, dof), rel=1e-9)
    assert two_sided_p_value(1.96, None) == pytest.approx(0.05, abs=1e-4)


@pytest.mark.parametrize("dof", [1, 2.5, 16, 17.7, 300])
def test_student_t_quantile_matches_scipy(dof):
    for p in (0.6, 0.975, 0.9975, 0.025):
        assert t_quantile(p, dof) == pytest.approx(scipy.stats.t.ppf(p, dof), rel=1e-9)
    assert t_quantile(0.975, math.inf) == pytest.approx(1.959964, abs=1e-6)
    with pytest.raises(ValueError, match="probability"):
        t_quantile(1.0, 3)


def test_intervals_with_a_monte_carlo_variance_cover_95_percent():
    """The monitor's situation: a standard error whose square is an exactly known variance plus
    a variance estimated from 16 Monte Carlo draws (the track-record term, 90 % of the total).
    Oracle: 20 000 simulated estimates with known normal errors. The Satterthwaite t interval
    covers 95 % (binomial standard error 0.15 %); +- 1.96 standard errors covers about 93.7 %."""
    rng = np.random.default_rng(7)
    trials, draws = 20_000, 16
    exact, term = 0.1, 0.9  # variances of the two parts of the error
    error = rng.normal(0.0, math.sqrt(exact + term), trials)
    estimated = np.mean(rng.normal(0.0, math.sqrt(term), (trials, draws)) ** 2, axis=1)
    se = np.sqrt(exact + estimated)
    dof = [satterthwaite_dof((exact, v), (math.inf, draws)) for v in estimated]
    t = np.array([t_quantile(0.975, d) for d in dof])
    covered_t = np.mean(np.abs(error) <= t * se)
    covered_z = np.mean(np.abs(error) <= 1.959964 * se)
    assert abs(covered_t - 0.95) < 0.005, covered_t
    assert covered_z < 0.94, covered_z  # the normal quantile's shortfall the t one removes
    assert satterthwaite_dof((1.0, 0.0), (math.inf, 16)) == math.inf
    assert satterthwaite_dof((0.0, 2.0), (math.inf, 16)) == pytest.approx(16.0)
    # an unbounded variance (a rank-deficient fit's standard error is inf): no finite dof
    assert satterthwaite_dof((math.inf, 0.0, 0.0), (5181, math.inf, math.inf)) == math.inf


def test_the_95_percent_interval_uses_the_standard_errors_degrees_of_freedom():
    band = ToleranceBand((0.8, 1.2))
    z = decision_z(0.05, 1)
    exact = judge("c", 1.0, 0.01, band, z=z)
    few = judge("c", 1.0, 0.01, band, z=z, dof=16)
    assert exact.ci95 == pytest.approx((1 - 0.01959964, 1 + 0.01959964), rel=1e-6)
    half = scipy.stats.t.ppf(0.975, 16) * 0.01
    assert few.ci95 == pytest.approx((1 - half, 1 + half), rel=1e-9)
    assert few.evidence["ci95_dof"] == 16 and exact.evidence["ci95_dof"] is None
    assert few.verdict == exact.verdict == "healthy"


def _series(rng, n, slope, scatter_factor=1.0):
    days = np.cumsum(rng.uniform(20, 40, n))
    se = rng.uniform(5e3, 15e3, n)
    values = 400e3 + slope * days + scatter_factor * se * rng.standard_normal(n)
    dates = np.datetime64("2026-01-01") + days.astype("timedelta64[D]")
    return dates, values, se


def test_drift_false_alarm_rate_without_drift():
    """4 000 series of 8 runs without drift: the flag rate stays at or below alpha (the
    Birge-ratio inflation makes the test conservative when the errors are right)."""
    rng = np.random.default_rng(2)
    trials, alpha = 4000, 0.05
    flags = [
        trend("c", *_series(rng, 8, 0.0)[:3], false_alarm_rate=alpha).drift for _ in range(trials)
    ]
    assert np.mean(flags) <= alpha + 3 * np.sqrt(alpha / trials)


def test_drift_false_alarm_rate_when_errors_are_underestimated():
    """4 000 series whose scatter is twice their stated standard errors: the inflation keeps
    the false-alarm rate near alpha (without it, it would be about 0.33)."""
    rng = np.random.default_rng(3)
    trials, alpha = 4000, 0.05
    flags = [
        trend("c", *_series(rng, 8, 0.0, scatter_factor=2.0), false_alarm_rate=alpha).drift
        for _ in range(trials)
    ]
    assert np.mean(flags) <= alpha + 4 * np.sqrt(alpha / trials)


def test_drift_is_found_and_projected_to_the_band_edge():
    """500 series losing 300 N s/m a day over 8 runs (about 70 kN s/m in total): flagged in at
    least 95 % of them; the projected crossing of the lower band edge is about right."""
    rng = np.random.default_rng(4)
    results = [trend("c", *_series(rng, 8, -300.0), band=BAND) for _ in range(500)]
    assert np.mean([r.drift for r in results]) >= 0.95
    r = results[0]
    assert r.slope == pytest.approx(-300.0, rel=0.5)
    expected = (BAND.healthy[0] - r.level) / r.slope
    assert r.days_to_band_edge == pytest.approx(max(expected, 0.0))


def test_trend_recovers_an_exact_line():
    dates = ["2026-01-01", "2026-02-01", "2026-03-01", "2026-04-01"]
    days = np.array([0.0, 31.0, 59.0, 90.0])
    r = trend("c", dates, 400e3 - 100.0 * days, np.full(4, 1e3))
    assert r.slope == pytest.approx(-100.0, rel=1e-12)
    assert r.level == pytest.approx(400e3 - 9000.0, rel=1e-12)
    assert r.birge_ratio == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize(
    "dates, match",
    [
        (["2026-02-01", "2026-01-01", "2026-03-01"], "unsorted"),
        (["2026-01-01", "2026-01-01", "2026-03-01"], "duplicate"),
        ([], "empty"),
    ],
)
def test_bad_history_is_refused(dates, match):
    with pytest.raises(ValueError, match=match):
        trend("c", dates, np.ones(len(dates)), np.ones(len(dates)))
