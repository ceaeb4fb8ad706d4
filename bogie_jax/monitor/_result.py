"""What `monitor` returns: verdicts, the identifiability of every candidate, the fit and the
runs, with `to_dict()` for `verdicts.json`."""

import dataclasses
import math

from ._elements import ElementStatus
from ._goodness import GoodnessOfFit, not_explained_warning
from ._record_shape import LONG_BAND
from ._verdict import WATCH_NOTE, Verdict, verdict_label


def _clean(x):
    """JSON-ready: non-finite floats become `None`, tuples lists, recursively."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if hasattr(x, "item") and getattr(x, "ndim", 1) == 0:
        return _clean(x.item())
    return x


@dataclasses.dataclass(frozen=True)
class RunStatus:
    """One measurement run: `index`, `speed` [m/s] (as stated), `duration` [s], `track`
    (description), `used` in the verdicts, `reason` when left out, `residual_rms` of its
    weighted residuals at the estimate (about 1 when the model explains the run to the
    sensors' noise); with `corrected` (`monitor`'s `run_corrections`): the fitted
    `position_offset` [m] added to the run's start position on its track record (a record
    whose irregularity at s is the true one at s + d gives -d) and `speed_factor` [-]
    (true speed / stated speed), with their standard errors `position_offset_se` [m],
    `speed_factor_se` [-] (NaN when not fitted; offset 0 and factor 1 when not corrected)."""

    index: int
    speed: float
    duration: float
    track: str
    used: bool
    reason: str
    residual_rms: float
    position_offset: float = 0.0
    speed_factor: float = 1.0
    position_offset_se: float = float("nan")
    speed_factor_se: float = float("nan")
    corrected: bool = False


# [-]: a larger `FitSummary.misfit_ratio` marks a fit that misses the data (about 1 at the
# right minimum, many times that at a wrong one: docs/monitoring.md)
MISFIT_LIMIT = 3.0


def misfit_warning(misfit_ratio) -> str:
    """The warning for a fit whose `misfit_ratio` (`FitSummary`) exceeds `MISFIT_LIMIT`; `""`
    otherwise (NaN or `None`: nothing to compare with)."""
    if misfit_ratio is None or not float(misfit_ratio) > MISFIT_LIMIT:
        return ""
    return (
        f"WARNING: the fit leaves {float(misfit_ratio):.3g} times the residual that the track "
        f"records' error and the sensors' noise explain (limit {MISFIT_LIMIT:g}): it may have "
        "stopped in a wrong minimum, and these verdicts are not reliable"
    )


REFIT_NOTE = (
    "model: {model}, fitted because the configured model did not explain the data (this one does)"
)


@dataclasses.dataclass(frozen=True)
class FitSummary:
    """The joint fit: fitted coordinate `names`, LM `status` (`converged`, `max_steps`,
    `failed`) of the last fit, `steps` and `evaluations` of the residual Jacobian over all
    fits, `cost` = 1/2 |r|^2 of the last fit (in its weights), `noise_variance`
    2 cost / (m - n - b) (b: bias parameters), `sigma2` of the Gauss-Newton covariance
    (`monitor`'s `noise`), `rank` and `condition_number` of the Jacobian, `runs_used`, `costs`
    after each accepted step of the last fit; `noise` mode, `covariance` kind (`sandwich` or
    `gauss-newton`) and the sandwich's Bartlett `bandwidth` [samples], `bias_removed`,
    `reweights` (refits with per-channel weights), `channel_noise`: per run (empty if left
    out), per channel, the residual standard deviation at the estimate as a multiple of the
    sensor's assumed `noise_std` (degrees of freedom corrected; 1: the assumed noise is
    right); `run_corrections`: whether each run's track position and speed were fitted (the
    values are in `MonitorResult.runs`); `nuisance`: the parameters fitted but not judged,
    `{name: {"estimate", "std_error", "nominal", "unit"}}`; `track_error` [m]: the track
    records' error RMS in the covariance and `track_error_draws` its realisations used (0:
    records taken as exact); `horizons` [s]: the spans fitted before the whole record
    (`monitor`'s `horizon_start`; `()`: one fit of the whole record); `misfit_ratio`: with a
    `track_error`, 2 `cost` over the residual sum of squares that the records' error and the
    sensors' stated noise should leave at the right minimum (`_track_error.py`; about 1 when
    the fit explains the data as well as those errors allow; NaN without a `track_error`);
    `track_error_white_share`: the share of the records' error variance taken as white over
    the recording band rather than shaped like the track (`_record_shape.py`; 0 where the fit
    explains the data with the track-shaped error; the data are not taken as explained by it);
    `track_error_long_wave_share`: the share taken as long-wave drift (`_record_shape.py`; above
    0 where the data hold far less misfit than a track-shaped error leaves);
    `track_records_calibrated`: whether the fit was repeated on records calibrated for the white
    share (`_record_calibration.py`; False where the share is 0 or that fit failed); `model`:
    the fitted model's nonlinear options in words (`_model_refit.model_name`: "linear" with
    none); `model_refit`: this fit is `MonitorOptions.refit_model`'s, made because the
    options' `model` did not explain the data, and kept because it does (`_model_refit.py`)."""

    names: tuple[str, ...]
    status: str
    steps: int
    evaluations: int
    cost: float
    noise_variance: float
    sigma2: float
    rank: int
    condition_number: float
    runs_used: int
    costs: tuple[float, ...] = ()
    noise: str = ""
    covariance: str = "gauss-newton"
    bandwidth: float = float("nan")
    bias_removed: bool = False
    reweights: int = 0
    channel_noise: tuple[tuple[float, ...], ...] = ()
    run_corrections: bool = False
    nuisance: dict = dataclasses.field(default_factory=dict)
    track_error: float = 0.0
    track_error_draws: int = 0
    horizons: tuple[float, ...] = ()
    misfit_ratio: float = float("nan")
    track_error_white_share: float = 0.0
    track_error_long_wave_share: float = 0.0
    track_records_calibrated: bool = False
    model: str = "linear"
    model_refit: bool = False

    @property
    def explains_data(self) -> bool:
        """False where `misfit_ratio` exceeds `MISFIT_LIMIT` (a wrong minimum), else True."""
        return not misfit_warning(self.misfit_ratio)


@dataclasses.dataclass(frozen=True)
class MonitorResult:
    """Result of `monitor`.

    - `verdicts`: one `Verdict` per judged element or group (groups name their members in
      `evidence["members"]` and their weights in the estimate in `evidence["member_weights"]`),
      then one per candidate that is not identifiable;
    - `elements`: the identifiability of every candidate (`ElementStatus`);
    - `fit`: `FitSummary`; `runs`: `RunStatus` per measurement; `false_alarm_rate`;
    - `timings` [s]: `first_jacobian_s` (compile and first evaluation of the residual-Jacobian
      program), `fit_s`, `track_error_s` (with a `track_error`), `verdicts_s`, `total_s`
      (`suspects_s` where the data are not explained);
    - `goodness`: the `GoodnessOfFit` per run and channel group (`_goodness.py`), `None`
      without a fit; `explained` and `misfits` read it.
    """

    verdicts: tuple[Verdict, ...]
    elements: tuple[ElementStatus, ...]
    fit: FitSummary
    runs: tuple[RunStatus, ...]
    false_alarm_rate: float
    timings: dict
    goodness: GoodnessOfFit | None = None

    @property
    def explained(self) -> bool:
        """False where the goodness-of-fit test finds data the fit does not explain."""
        return self.goodness is None or self.goodness.explained

    @property
    def misfits(self) -> tuple:
        """The runs and channel groups the fit does not explain (`_goodness.Misfit`)."""
        return () if self.goodness is None else self.goodness.misfits

    def verdict(self, name: str) -> Verdict:
        """The verdict covering `name` (an element, or its group's verdict)."""
        for v in self.verdicts:
            if v.name == name:
                return v
        for s in self.elements:
            if s.name == name:
                return self.verdict(s.coordinate)
        raise KeyError(
            f"no verdict for {name!r}; verdicts: {', '.join(v.name for v in self.verdicts)}"
        )

    @property
    def alarms(self) -> tuple[Verdict, ...]:
        """The verdicts `degraded` or `failed`."""
        return tuple(v for v in self.verdicts if v.verdict in ("degraded", "failed"))

    @property
    def watches(self) -> tuple[Verdict, ...]:
        """The verdicts on watch (`Verdict.watch`): 95 % interval outside the band, no alarm."""
        return tuple(v for v in self.verdicts if v.watch)

    @property
    def runs_used(self) -> int:
        return sum(r.used for r in self.runs)

    def table(self) -> str:
        """The verdicts as a plain-text table."""
        rows = [f"{'element':28s} {'verdict':17s} {'estimate':>12s} {'95 % interval':>27s} unit"]
        for v in self.verdicts:
            if v.verdict == "not identifiable" and not math.isfinite(v.std_error):
                est, ci = "-", "-"
            else:
                est, ci = f"{v.estimate:12.5g}", f"[{v.ci95[0]:.5g}, {v.ci95[1]:.5g}]"
            label = verdict_label(v.verdict, v.watch)
            rows.append(f"{v.name:28s} {label:17s} {est:>12s} {ci:>27s} {v.band.unit}")
        if self.watches:
            rows.append(WATCH_NOTE)
        for v in self.verdicts:  # what a group's estimate measures (`group_weights`)
            weights = v.evidence.get("member_weights")
            if weights:
                mean = " + ".join(f"{w:.2f} {m}" for m, w in weights.items())
                rows.append(f"{v.name} measures {mean} (each relative to nominal)")
        for name, p in self.fit.nuisance.items():
            rows.append(
                f"fitted, not judged: {name} = {p['estimate']:.5g} +- {p['std_error']:.2g} "
                f"{p['unit']} (nominal {p['nominal']:.5g})"
            )
        for r in self.runs:
            if r.corrected:
                rows.append(
                    f"run {r.index}: track position offset {r.position_offset:+.3f} +- "
                    f"{r.position_offset_se:.2g} m, speed x {r.speed_factor:.5f} +- "
                    f"{r.speed_factor_se:.1e}"
                )
        if self.fit.track_error_white_share > 0:
            calibrated = "the fit repeated on records calibrated for it and its spread "
            rows.append(
                f"track records' error: {100 * self.fit.track_error_white_share:.0f} % of its "
                "variance white over the recording band, "
                f"{calibrated if self.fit.track_records_calibrated else ''}in the standard "
                "errors (the misfit calls for it; the data are not taken as explained by it)"
            )
        if self.fit.track_error_long_wave_share > 0:
            rows.append(
                f"track records' error: {100 * self.fit.track_error_long_wave_share:.4g} % of its "
                f"variance long-wave drift ({LONG_BAND[0]:g}-{LONG_BAND[1]:g} m), in the standard "
                "errors (the residuals hold far less misfit than an error shaped like the track "
                "leaves)"
            )
        if self.fit.model_refit:
            rows.append(REFIT_NOTE.format(model=self.fit.model))
        warning = misfit_warning(self.fit.misfit_ratio)
        if warning:
            rows.append(warning)
        if not self.explained:
            rows.append(not_explained_warning(self.goodness))
        left = [r for r in self.runs if not r.used]
        if left:
            rows.append(
                f"judged on {self.runs_used} of {len(self.runs)} runs; left out: "
                + "; ".join(f"run {r.index} ({r.reason})" for r in left)
            )
        return "\n".join(rows)

    def to_dict(self) -> dict:
        """JSON-ready: `verdicts` (name, verdict, estimate, std_error, ci95, tolerance_band,
        unit, evidence; `None` for values the data do not determine), `elements`, `fit`,
        `runs`, `false_alarm_rate`, `timings`; `fit` holds `explains_data` too; `explained`
        and `goodness_of_fit` (`GoodnessOfFit.to_dict`: the misfits, every test, the suspects)."""
        verdicts = []
        for v in self.verdicts:
            d = v.to_dict()
            if not math.isfinite(v.std_error):
                d["estimate"], d["std_error"], d["ci95"] = None, None, None
            verdicts.append(d)
        return _clean(
            {
                "verdicts": verdicts,
                "elements": [s.to_dict() for s in self.elements],
                "fit": {**dataclasses.asdict(self.fit), "explains_data": self.fit.explains_data},
                "runs": [dataclasses.asdict(r) for r in self.runs],
                "false_alarm_rate": self.false_alarm_rate,
                "timings": self.timings,
                "explained": self.explained,
                "goodness_of_fit": None if self.goodness is None else self.goodness.to_dict(),
            }
        )
