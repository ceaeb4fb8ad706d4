"""Verdicts per suspension element from an estimate, its standard error and a tolerance band.

Decision rule (documented in the README, "Verdict rules"):

- Every element of one bogie is judged on the interval
      I = estimate +- z * standard_error,   z = z_{1 - alpha / (2 m)},
  where `alpha` is the bogie's false-alarm rate (one argument, default 5 %) and m the number of
  elements judged together (Bonferroni). A healthy element's true value lies inside its healthy
  band, so it is called degraded or failed only if I misses the truth: probability at most
  alpha / m per element and at most alpha for the bogie, whatever the correlation of the
  estimates (given correct standard errors).
- `failed`: I lies entirely beyond the failure limit (below `failed_below`, or above
  `failed_above` where a band has one).
- `degraded`: I lies entirely outside the healthy band (and the element is not failed).
- `not identifiable`: the sensors cannot decide: the element is flagged unidentifiable by the
  Fisher information of the actual runs, or I is wider than the healthy band (then no value of
  the estimate could show the element healthy or not).
- `healthy`: otherwise: the data give no evidence, at level alpha, that the element left its band.

The reported 95 % interval is estimate +- 1.96 standard errors, independent of `alpha`.
"""

import dataclasses
import math
from statistics import NormalDist


VERDICTS = ("healthy", "degraded", "failed", "not identifiable")
Z95 = NormalDist().inv_cdf(0.975)


@dataclasses.dataclass(frozen=True)
class ToleranceBand:
    """The healthy range of one element and its failure limits, in the element's `unit`.

    - `healthy`: `(lo, hi)`, the values a healthy element takes (maintenance tolerance);
    - `failed_below`, `failed_above`: an element beyond either limit has failed (`None`: no
      such limit); `failed_below < lo` and `failed_above > hi`.
    """

    healthy: tuple[float, float]
    unit: str = ""
    failed_below: float | None = None
    failed_above: float | None = None

    def __post_init__(self):
        lo, hi = (float(x) for x in self.healthy)
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ValueError(
                f"tolerance band `healthy` = {self.healthy!r} {self.unit} must be finite with "
                "lo < hi (a band of zero width cannot hold a healthy element)"
            )
        if self.failed_below is not None and not self.failed_below < lo:
            raise ValueError(f"`failed_below` = {self.failed_below!r} must be below {lo!r}")
        if self.failed_above is not None and not self.failed_above > hi:
            raise ValueError(f"`failed_above` = {self.failed_above!r} must be above {hi!r}")
        object.__setattr__(self, "healthy", (lo, hi))

    @classmethod
    def relative(
        cls,
        nominal: float,
        tolerance: float,
        *,
        unit: str = "",
        failed_fraction: float | None = 0.25,
    ) -> "ToleranceBand":
        """`nominal * (1 -+ tolerance)`, failed below `failed_fraction * nominal`."""
        if not 0 < tolerance < 1:
            raise ValueError(f"`tolerance` = {tolerance!r} must lie in (0, 1)")
        lo, hi = nominal * (1 - tolerance), nominal * (1 + tolerance)
        failed = None if failed_fraction is None else failed_fraction * nominal
        return cls((lo, hi), unit=unit, failed_below=failed)

    def to_dict(self) -> dict:
        return {
            "healthy": list(self.healthy),
            "failed_below": self.failed_below,
            "failed_above": self.failed_above,
            "unit": self.unit,
        }


@dataclasses.dataclass(frozen=True)
class Verdict:
    """The verdict on one element (or a group the sensors cannot split).

    - `name`: element or group name; `verdict`: one of `VERDICTS`;
    - `estimate`, `std_error` [unit]; `ci95`: estimate +- 1.96 standard errors;
    - `band`: the `ToleranceBand`; `evidence`: the decision interval, its z and the reason.
    """

    name: str
    verdict: str
    estimate: float
    std_error: float
    ci95: tuple[float, float]
    band: ToleranceBand
    evidence: dict

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "verdict": self.verdict,
            "estimate": self.estimate,
            "std_error": self.std_error,
            "ci95": list(self.ci95),
            "tolerance_band": self.band.to_dict(),
            "unit": self.band.unit,
            "evidence": self.evidence,
        }


def check_false_alarm_rate(false_alarm_rate: float) -> float:
    """`false_alarm_rate` as a float in (0, 0.5); raises `ValueError` naming it otherwise."""
    alpha = float(false_alarm_rate)
    if not 0 < alpha < 0.5:
        raise ValueError(f"`false_alarm_rate` = {false_alarm_rate!r} must lie in (0, 0.5)")
    return alpha


def decision_z(false_alarm_rate: float, n_elements: int) -> float:
    """z_{1 - alpha / (2 m)}: the half-width of the decision interval in standard errors."""
    alpha = check_false_alarm_rate(false_alarm_rate)
    if n_elements < 1:
        raise ValueError(f"`n_elements` = {n_elements!r} must be >= 1")
    return NormalDist().inv_cdf(1 - alpha / (2 * n_elements))


def judge(
    name: str,
    estimate: float,
    std_error: float,
    band: ToleranceBand,
    *,
    z: float,
    identifiable: bool = True,
) -> Verdict:
    """The verdict on one element by the rule of the module docstring (`z` from `decision_z`)."""
    estimate, std_error = float(estimate), float(std_error)
    lo, hi = estimate - z * std_error, estimate + z * std_error
    h_lo, h_hi = band.healthy
    evidence = {"decision_interval": [lo, hi], "z": z}
    if not (identifiable and math.isfinite(std_error) and std_error >= 0):
        verdict, reason = "not identifiable", "the sensors do not determine this element"
    elif hi - lo > h_hi - h_lo:
        verdict = "not identifiable"
        reason = "the decision interval is wider than the healthy band"
    elif band.failed_below is not None and hi < band.failed_below:
        verdict, reason = "failed", f"the decision interval lies below {band.failed_below:.4g}"
    elif band.failed_above is not None and lo > band.failed_above:
        verdict, reason = "failed", f"the decision interval lies above {band.failed_above:.4g}"
    elif hi < h_lo or lo > h_hi:
        verdict, reason = "degraded", "the decision interval lies outside the healthy band"
    else:
        verdict, reason = "healthy", "the decision interval overlaps the healthy band"
    evidence["reason"] = reason
    half = Z95 * std_error
    return Verdict(
        name, verdict, estimate, std_error, (estimate - half, estimate + half), band, evidence
    )
