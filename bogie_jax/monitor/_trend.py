"""Trends of one element's estimates over a series of dated runs, with a drift flag.

Weighted least squares on the estimates p_k at times t_k with their standard errors s_k
(Bevington & Robinson, Data Reduction and Error Analysis, 3rd ed., ch. 6):

    p_k = a + b (t_k - t_w) + e_k,   weights w_k = 1 / s_k^2,   t_w = sum w t / sum w,
    b = sum w (t - t_w) p / S_tt,    se(b) = 1 / sqrt(S_tt),   S_tt = sum w (t - t_w)^2.

Drift flag: |b| / se(b) > z_{1 - alpha/2} (two-sided test of "no drift" at false-alarm rate
alpha). When the scatter about the line exceeds what the standard errors allow (Birge ratio
R^2 = chi^2 / (n - 2) > 1), se(b) is multiplied by R and the quantile is Student's t with n - 2
degrees of freedom, so estimates whose errors were underestimated do not raise false alarms.
"""

import dataclasses
import math

import numpy as np

from ..identify import two_sided_p_value
from ._elements import same_measure
from ._verdict import ToleranceBand, check_false_alarm_rate


SECONDS_PER_DAY = 86_400.0


@dataclasses.dataclass(frozen=True)
class Trend:
    """The trend of one element.

    - `name`; `times` [days since the first run] and `dates` (ISO strings);
    - `slope` [unit/day] and `slope_std_error`; `level` [unit] at the last run and its error;
    - `birge_ratio`: sqrt(chi^2 / (n - 2)) (about 1 when the standard errors explain the
      scatter; `nan` for two runs);
    - `drift`: the flag of the module's test; `p_value` of that test;
    - `days_to_band_edge`: days after the last run until the line leaves the healthy band
      (`None` without a band, without drift or when it moves away from the edges).
    """

    name: str
    dates: tuple[str, ...]
    times: np.ndarray
    estimates: np.ndarray
    std_errors: np.ndarray
    slope: float
    slope_std_error: float
    level: float
    level_std_error: float
    birge_ratio: float
    drift: bool
    p_value: float
    days_to_band_edge: float | None = None

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "dates": list(self.dates),
            "estimates": [float(x) for x in self.estimates],
            "std_errors": [float(x) for x in self.std_errors],
            "slope_per_day": self.slope,
            "slope_std_error": self.slope_std_error,
            "level": self.level,
            "level_std_error": self.level_std_error,
            "birge_ratio": self.birge_ratio,
            "drift": self.drift,
            "p_value": self.p_value,
            "days_to_band_edge": self.days_to_band_edge,
        }


def as_days(dates) -> tuple[np.ndarray, tuple[str, ...]]:
    """Days since the first of `dates` (ISO strings, `datetime64` or `datetime`), strictly
    increasing; raises `ValueError` naming the first unsorted or duplicate date."""
    stamps = np.array([np.datetime64(d, "s") for d in dates])
    if stamps.size == 0:
        raise ValueError("`dates` is empty: a trend needs at least two dated results")
    steps = np.diff(stamps).astype(float)
    bad = np.flatnonzero(steps <= 0)
    if bad.size:
        k = int(bad[0])
        kind = "duplicate" if steps[k] == 0 else "unsorted"
        raise ValueError(
            f"`dates` must be strictly increasing: {kind} date {stamps[k + 1]} after {stamps[k]} "
            f"(results {k} and {k + 1})"
        )
    days = (stamps - stamps[0]).astype(float) / SECONDS_PER_DAY
    return days, tuple(str(s) for s in stamps)


def trend(
    name: str,
    dates,
    estimates,
    std_errors,
    *,
    false_alarm_rate: float = 0.05,
    band: ToleranceBand | None = None,
) -> Trend:
    """The weighted-regression trend of one element over dated runs (see module docstring).

    **Raises:** `ValueError` for fewer than two runs, unsorted or duplicate dates, lengths that
    differ, or standard errors that are not finite and > 0.
    """
    alpha = check_false_alarm_rate(false_alarm_rate)
    t, iso = as_days(dates)
    p = np.asarray(estimates, dtype=float)
    s = np.asarray(std_errors, dtype=float)
    if not (p.shape == s.shape == t.shape):
        raise ValueError(
            f"`dates`, `estimates` and `std_errors` need one entry per run; got lengths "
            f"{t.size}, {p.size}, {s.size}"
        )
    if t.size < 2:
        raise ValueError(f"a trend needs at least two dated results, got {t.size}")
    if not np.all(np.isfinite(s) & (s > 0)) or not np.all(np.isfinite(p)):
        raise ValueError(f"`estimates` must be finite and `std_errors` finite and > 0: {s!r}")
    w = 1.0 / s**2
    t_w = np.sum(w * t) / np.sum(w)
    s_tt = np.sum(w * (t - t_w) ** 2)
    slope = float(np.sum(w * (t - t_w) * p) / s_tt)
    mean = float(np.sum(w * p) / np.sum(w))
    dof = t.size - 2
    chi2 = float(np.sum(w * (p - mean - slope * (t - t_w)) ** 2))
    birge = math.sqrt(chi2 / dof) if dof > 0 else math.nan
    inflate = birge if dof > 0 and birge > 1 else 1.0
    se_slope = inflate / math.sqrt(s_tt)
    dt_last = t[-1] - t_w
    level = mean + slope * dt_last
    se_level = inflate * math.sqrt(1 / np.sum(w) + dt_last**2 / s_tt)
    statistic = abs(slope) / se_slope
    p_value = two_sided_p_value(statistic, dof if inflate > 1 else None)
    drift = bool(p_value < alpha)
    return Trend(
        name=name,
        dates=iso,
        times=t,
        estimates=p,
        std_errors=s,
        slope=slope,
        slope_std_error=se_slope,
        level=level,
        level_std_error=se_level,
        birge_ratio=birge,
        drift=drift,
        p_value=p_value,
        days_to_band_edge=_days_to_edge(level, slope, band) if drift else None,
    )


def _days_to_edge(level: float, slope: float, band: ToleranceBand | None) -> float | None:
    if band is None or slope == 0:
        return None
    lo, hi = band.healthy
    edge = lo if slope < 0 else hi
    days = (edge - level) / slope
    return float(max(days, 0.0))


def band_of_row(row) -> ToleranceBand:
    """The tolerance band of one `verdicts.json` row (its `tolerance_band` object)."""
    b = row["tolerance_band"]
    return ToleranceBand(
        tuple(b["healthy"]),
        unit=b.get("unit", ""),
        failed_below=b.get("failed_below"),
        failed_above=b.get("failed_above"),
    )


def comparable_estimates(rows):
    """Of one element's `(date, verdicts.json row)` pairs in date order, those a trend may use:
    each with an estimate and a standard error and, for a group, weighing its members as the
    latest of them does (`same_measure`). Returns `(kept, left_out)`: the pairs kept and the
    dates of the estimates left out for weighing the members otherwise."""
    known = [(d, r) for d, r in rows if r.get("estimate") is not None and r.get("std_error")]
    if not known:
        return [], []
    weights = lambda row: (row.get("evidence") or {}).get("member_weights")
    reference = weights(known[-1][1])
    same = [same_measure(weights(row), reference) for _, row in known]
    kept = [item for item, alike in zip(known, same) if alike]
    return kept, [d for (d, _), alike in zip(known, same) if not alike]


def trend_of_rows(name: str, rows, false_alarm_rate: float = 0.05) -> Trend:
    """`trend` of one element over `(date, verdicts.json row)` pairs that `comparable_estimates`
    kept (two or more), judged against the band of the latest."""
    return trend(
        name,
        [d for d, _ in rows],
        [row["estimate"] for _, row in rows],
        [row["std_error"] for _, row in rows],
        false_alarm_rate=false_alarm_rate,
        band=band_of_row(rows[-1][1]),
    )
