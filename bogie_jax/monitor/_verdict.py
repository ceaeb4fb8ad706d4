"""Verdicts per suspension element from an estimate, its standard error and a tolerance band.

Decision rule (documented in the README, "Verdict rules"):

- Every element of one bogie is tested at the decision level z = z_{1 - alpha / (2 m)},
  where `alpha` is the bogie's false-alarm rate (one argument, default 5 %) and m the number of
  elements judged together (Bonferroni). A healthy element's true value lies inside its healthy
  band, so it is called degraded or failed only if a test at that level rejects a true
  hypothesis: probability at most alpha / m per element and at most alpha for the bogie,
  whatever the correlation of the estimates (given correct standard errors).
- The test that an element lies beyond a limit L (a band edge or a failure limit) on the side
  of its estimate: with a `profile` (`monitor` gives one: `_profile.py`), the signed root of
  the profile likelihood-ratio statistic at L exceeds z; it is computed where the Wald
  statistic at L, in p or in ln p, reaches z / 2 (below that, neither Wald test is near
  rejecting and the profile is not fitted). The nearer limit
  is tested first: an element beyond its failure limit is beyond its band's edge as well (the
  profile likelihood falls monotonically away from the estimate). Without a profile (or
  where its fit failed or did not converge: its statistic is then only an upper bound), the
  Wald test: the decision interval I = estimate +- z * standard_error lies beyond L, and I is
  not wider than the healthy band (a linearisation that spans more than the band is not
  trusted to reject).
- `failed`: the element lies beyond the failure limit (below `failed_below`, or above
  `failed_above` where a band has one).
- `degraded`: it lies outside the healthy band (and has not failed).
- `not identifiable`: the sensors cannot decide: the element is flagged unidentifiable by the
  Fisher information of the actual runs, or (no test rejecting) I is wider than the healthy
  band (then no value of the estimate could show the element healthy).
- `healthy`: otherwise: the data give no evidence, at level alpha, that the element left its band.
- `watch` (a flag beside the verdict, not an alarm): the element is judged `healthy` or `not
  identifiable` (no test rejecting), but its 95 % interval lies wholly outside the healthy
  band. Each element on its band's edge is flagged with probability at most 2.5 % (one
  interval's tail), so a bogie's flags are not held to `alpha`: a flag asks for a longer record
  or another run, not for a repair.

The reported 95 % interval is estimate +- t standard errors, independent of `alpha`: t the
0.975 quantile of Student's t with the standard error's effective degrees of freedom (`dof`;
1.96 for an exactly known variance). `monitor` gives the Welch-Satterthwaite degrees of freedom
of its residual and track-record terms (`bogie_jax.identify.satterthwaite_dof`): the track
term is a Monte Carlo estimate from a few draws. The decision level z stays the normal quantile
(docs/monitoring.md says what that costs).
"""

import dataclasses
import math
from statistics import NormalDist

from .._validation import check_range
from ..identify import t_quantile


VERDICTS = ("healthy", "degraded", "failed", "not identifiable")


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
    - `estimate`, `std_error` [unit]; `ci95`: the 95 % interval (module docstring);
    - `band`: the `ToleranceBand`; `evidence`: the decision interval, its z and the reason
      (and `watch`: see the property).
    """

    name: str
    verdict: str
    estimate: float
    std_error: float
    ci95: tuple[float, float]
    band: ToleranceBand
    evidence: dict

    @property
    def watch(self) -> str | None:
        """`"above"` or `"below"`: the element on watch (module docstring); else `None`."""
        return self.evidence.get("watch")

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
    check_range("false_alarm_rate", false_alarm_rate, 0.0, 0.5, open_lo=True, open_hi=True)
    return float(false_alarm_rate)


def decision_z(false_alarm_rate: float, n_elements: int) -> float:
    """z_{1 - alpha / (2 m)}: the half-width of the decision interval in standard errors."""
    alpha = check_false_alarm_rate(false_alarm_rate)
    if n_elements < 1:
        raise ValueError(f"`n_elements` = {n_elements!r} must be >= 1")
    return NormalDist().inv_cdf(1 - alpha / (2 * n_elements))


def _beyond(estimate, std_error, limit, z, wide, profile, evidence) -> bool:
    """Whether the data put the element beyond `limit` (on its estimate's side) at level z:
    the profile test where given and not screened out, the Wald test otherwise (module
    docstring); the statistics used go into `evidence["tests"]`."""
    wald = abs(estimate - limit) / std_error if std_error > 0 else math.inf
    log_wald = (
        abs(math.log(estimate / limit)) * estimate / std_error
        if estimate > 0 and std_error > 0
        else wald
    )
    test = {"limit": limit, "wald": wald, "wald_log": log_wald}
    evidence.setdefault("tests", []).append(test)
    if profile is not None and max(wald, log_wald) >= z / 2:
        point = profile(limit)
        test["profile"] = point.to_dict()
        if point.status == "converged" and math.isfinite(point.statistic):
            return point.statistic > z
    return wald > z and not wide


def judge(
    name: str,
    estimate: float,
    std_error: float,
    band: ToleranceBand,
    *,
    z: float,
    identifiable: bool = True,
    profile=None,
    dof: float = math.inf,
) -> Verdict:
    """The verdict on one element by the rule of the module docstring (`z` from `decision_z`;
    `profile`: `None` or `limit -> ProfilePoint`, the profile test at a limit [unit]; `dof`:
    the standard error's degrees of freedom, for the 95 % interval)."""
    estimate, std_error = float(estimate), float(std_error)
    lo, hi = estimate - z * std_error, estimate + z * std_error
    h_lo, h_hi = band.healthy
    evidence = {"decision_interval": [lo, hi], "z": z}
    wide = hi - lo > h_hi - h_lo
    judged = identifiable and math.isfinite(std_error) and std_error >= 0
    if not judged:
        verdict, reason = "not identifiable", "the sensors do not determine this element"
    else:
        below = estimate < h_lo
        edge, limit = (h_lo, band.failed_below) if below else (h_hi, band.failed_above)
        beyond = lambda x: _beyond(estimate, std_error, x, z, wide, profile, evidence)
        past_limit = limit is not None and (estimate < limit if below else estimate > limit)
        # the nearer limit first: past the failure limit, the edge is rejected with it
        failed = past_limit and beyond(limit)
        outside = failed or ((below or estimate > h_hi) and beyond(edge))
        side = "below" if below else "above"
        if failed:
            verdict, reason = "failed", f"the element lies {side} {limit:.4g}"
        elif outside:
            verdict, reason = "degraded", f"the element lies {side} its healthy band"
        elif wide:
            verdict = "not identifiable"
            reason = "the decision interval is wider than the healthy band"
        else:
            verdict, reason = "healthy", "the data do not put the element outside its healthy band"
    evidence["reason"] = reason
    evidence["ci95_dof"] = float(dof) if math.isfinite(dof) else None
    half = t_quantile(0.975, dof) * std_error
    ci95 = (estimate - half, estimate + half)
    side = interval_outside(ci95, band.healthy)
    if judged and verdict in ("healthy", "not identifiable") and side:
        evidence["watch"] = side
    return Verdict(name, verdict, estimate, std_error, ci95, band, evidence)


def interval_outside(interval, healthy) -> str | None:
    """`"above"` or `"below"` where `interval` `(lo, hi)` lies wholly on that side of the
    band `healthy` `(lo, hi)`; else `None` (also for NaN)."""
    if interval[0] > healthy[1]:
        return "above"
    if interval[1] < healthy[0]:
        return "below"
    return None


WATCH_NOTE = (
    "* watch: the 95 % interval lies outside the healthy band, but no test rejects the band "
    "at the bogie's false-alarm rate; a longer record or another run can decide"
)


def verdict_label(verdict: str, watch: str | None) -> str:
    """The verdict as tables show it: `healthy*` where the element is on watch."""
    return f"{verdict}*" if watch else verdict
