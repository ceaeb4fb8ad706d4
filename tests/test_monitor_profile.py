"""The profile likelihood-ratio test of `monitor`'s verdicts (`bogie_jax.monitor.profile_point`),
on a two-parameter decay curve y = a exp(-b t) fitted in ln a, ln b: against scipy's bounded
least squares (the held fit) and against its nominal false-alarm rate in repeated trials."""

import math
from statistics import NormalDist

import numpy as np
import pytest
from scipy.optimize import least_squares

from bogie_jax.monitor import (
    ProfilePoint,
    ToleranceBand,
    judge,
    levenberg_marquardt,
    profile_point,
)


T = np.linspace(0.0, 1.0, 40)
A0, B0 = 1.0, 3.0  # nominal amplitude [-] and rate [1/s]


def _decay(y, sigma):
    """evaluate(phi) -> (r, J) of the curve in phi = (ln a/A0, ln b/B0), residuals / sigma."""

    def evaluate(phi):
        a, b = A0 * np.exp(phi[0]), B0 * np.exp(phi[1])
        f = a * np.exp(-b * T)
        return (f - y) / sigma, np.stack([f, -b * T * f], axis=1) / sigma

    return evaluate


def _fit(evaluate):
    return levenberg_marquardt(evaluate, np.zeros(2), max_steps=50, cost_tol=1e-10)


def test_held_fit_matches_scipy_and_the_statistic_is_the_cost_rise():
    rng = np.random.default_rng(3)
    sigma = 0.2
    y = A0 * np.exp(-B0 * T) + sigma * rng.standard_normal(T.size)
    evaluate = _decay(y, sigma)
    fit = _fit(evaluate)
    phi_b = math.log(0.7)  # b held at 0.7 B0
    point = profile_point(evaluate, fit, 1, phi_b, sigma2=1.0, variance_ratio=1.0)
    oracle = least_squares(lambda u: evaluate(np.array([u[0], phi_b]))[0], [0.0], xtol=1e-14)
    assert point.status == "converged"
    assert point.cost == pytest.approx(oracle.cost, rel=1e-6)
    assert point.statistic == pytest.approx(math.sqrt(2 * (oracle.cost - fit.cost)), rel=1e-5)
    # sigma^2 and the sandwich ratio c scale LR: sqrt(LR / (sigma^2 c))
    scaled = profile_point(evaluate, fit, 1, phi_b, sigma2=2.0, variance_ratio=3.0)
    assert scaled.statistic == pytest.approx(point.statistic / math.sqrt(6.0), rel=1e-5)


def test_profile_test_holds_its_false_alarm_rate_where_wald_tests_do_not():
    """The rate b's relative standard error is about 34 %: the curve is far from linear in b
    over its interval. The truth sits on the band's lower edge; in 2000 noisy trials the
    one-sided test at z = 2.5 (nominal rate 0.62 %) rejects "b >= edge" as often as it
    should by the profile statistic, about 4 times too often by the Wald statistic in b, and
    never by the Wald statistic in ln b (measured 0.55, 2.6 and 0 % in 4000 trials)."""
    rng = np.random.default_rng(0)
    sigma, z, trials = 0.5, 2.5, 2000
    rejected = {"profile": 0, "wald": 0, "wald_log": 0}
    for _ in range(trials):
        evaluate = _decay(A0 * np.exp(-B0 * T) + sigma * rng.standard_normal(T.size), sigma)
        fit = _fit(evaluate)
        b = B0 * math.exp(fit.phi[1])
        if b >= B0:
            continue
        se = b * math.sqrt(np.linalg.inv(fit.jac.T @ fit.jac)[1, 1])
        rejected["profile"] += (
            profile_point(evaluate, fit, 1, 0.0, sigma2=1.0, variance_ratio=1.0).statistic > z
        )
        rejected["wald"] += (B0 - b) / se > z
        rejected["wald_log"] += math.log(B0 / b) * b / se > z
    expected = trials * (1 - NormalDist().cdf(z))  # 12.4
    assert abs(rejected["profile"] - expected) < 3 * math.sqrt(expected), rejected
    assert rejected["wald"] > 2.5 * expected, rejected
    assert rejected["wald_log"] < expected / 3, rejected


BAND = ToleranceBand.relative(400e3, 0.2)  # [320, 480] kN s/m, failed below 100


class _Profile:
    """A stand-in profile: the statistic per limit, the held fit's status, and the limits it
    was asked for."""

    def __init__(self, statistics, status="converged"):
        self.statistics, self.status, self.asked = statistics, status, []

    def __call__(self, limit):
        self.asked.append(limit)
        return ProfilePoint(0, 0.0, 0.0, self.status, 0, self.statistics[limit])


def test_judge_decides_by_the_profile_where_given():
    z = 3.0
    # a wide Wald interval wholly below the band: the Wald rule calls it not identifiable
    assert judge("d", 150e3, 50e3, BAND, z=z).verdict == "not identifiable"
    p = _Profile({320e3: 3.2})
    v = judge("d", 150e3, 50e3, BAND, z=z, profile=p)
    assert v.verdict == "degraded" and p.asked == [320e3]
    assert v.evidence["tests"][0]["profile"]["statistic"] == 3.2
    # below the failure limit: tested there first, and failed without the band's edge
    p = _Profile({320e3: 6.0, 100e3: 3.5})
    assert judge("d", 20e3, 20e3, BAND, z=z, profile=p).verdict == "failed"
    assert p.asked == [100e3]
    p = _Profile({320e3: 6.0, 100e3: 2.5})  # not beyond the failure limit: degraded
    assert judge("d", 20e3, 20e3, BAND, z=z, profile=p).verdict == "degraded"
    assert p.asked == [100e3, 320e3]
    # a narrow Wald interval below the band, but the profile does not reject: healthy
    p = _Profile({320e3: 2.9})
    assert judge("d", 280e3, 10e3, BAND, z=z).verdict == "degraded"
    assert judge("d", 280e3, 10e3, BAND, z=z, profile=p).verdict == "healthy"
    # a failed held fit (NaN) falls back to the Wald rule
    p = _Profile({320e3: float("nan")})
    assert judge("d", 280e3, 10e3, BAND, z=z, profile=p).verdict == "degraded"
    # a held fit that ran out of steps gives only an upper bound: the Wald rule decides
    p = _Profile({320e3: 3.2}, status="max_steps")
    assert judge("d", 150e3, 50e3, BAND, z=z, profile=p).verdict == "not identifiable"
    assert p.asked == [320e3]
    # screened out: both Wald statistics below z / 2, the profile is not fitted
    p = _Profile({})
    assert judge("d", 300e3, 20e3, BAND, z=z, profile=p).verdict == "healthy"
    assert p.asked == []
    # an estimate inside the band is never tested
    assert judge("d", 400e3, 60e3, BAND, z=z, profile=p).verdict == "not identifiable"
    assert p.asked == []
