"""`monitor`'s last steps: the track records' term, the covariance of the estimates, a verdict per
coordinate and the fit's summary.

- The track records' error (`_track_error.py`) adds its covariance term and its bias, removed
  by simulation-extrapolation from the well-determined element coordinates (`estimate_of`);
  where a bias is too large to extrapolate, its square joins the variance on a well-determined
  coordinate or where it points away from nominal.
- The covariance of all fitted coordinates (nuisance included, so the intervals carry the
  nuisance's uncertainty) by the options' covariance rule with the noise model's sigma^2, in the
  coordinates p / p_nominal (`bogie_jax.cost.relative_to_nominal`), plus the records' term and,
  with the Gauss-Newton rule, the model discrepancy's (`_discrepancy.py`).
- A verdict per coordinate by `judge` (`_verdict.py`) at the decision z of the false-alarm rate
  over the judged coordinates (Bonferroni); an element estimated outside its band is tested by
  the profile likelihood ratio (`_profile.py`); the 95 % intervals use the Welch-Satterthwaite
  degrees of freedom of the residual and track terms (`bogie_jax.identify.satterthwaite_dof`).
"""

import dataclasses
import functools
import math

import numpy as np

from ..cost import GaussNewtonCovariance, relative_to_nominal, with_model_error
from ..identify import HostFit, satterthwaite_dof
from ..params import resolve_parameter
from ._discrepancy import model_discrepancy
from ._elements import nominal_values
from ._profile import ProfilePoint, profile_point
from ._program import FitSpace
from ._track_error import RecordError, Sampling, TrackErrorEffect, track_error_effect
from ._verdict import Verdict, decision_z, judge


SIMEX_MAX_SPREAD = 0.1  # [-], ln p: the records' bias is removed where it and their spread are less


def track_record_term(
    space: FitSpace, fit: HostFit, say, band=None, stationary: bool = False, raw=None,
    prepare=None,
) -> TrackErrorEffect | None:  # fmt: skip
    """The track records' error in the fitted coordinates at the estimate (`_track_error.py`),
    shaped like the track or, with a wavelength `band` [m], white over it (`RecordError`, with
    `stationary`); the errors drawn on the problem's records or on `raw` ones, the bias's
    perturbed records made ready by `prepare` (`track_error_effect`'s `refit_records`); `None`
    without a `track_error` or a fit."""
    p = space.program.problem
    o = p.options
    if not o.track_error > 0 or fit.status == "failed":
        return None
    say(f"track record error {1e3 * o.track_error:.3g} mm: {o.track_error_draws} realisations")
    semi_distance = float(np.asarray(p.params.contact.contact_semi_distance))
    loose = space.with_program(space.program.with_loose_jacobian())  # `_program.py`
    return track_error_effect(
        loose, p.tracks if raw is None else raw, fit.phi,
        RecordError(o.track_error, semi_distance, band, stationary), Sampling(o.track_error_draws),
        references=[m.track for m in p.measurements], start=(fit.r, fit.jac),
        refit_records=prepare,
    )  # fmt: skip


@dataclasses.dataclass(frozen=True)
class Estimate:
    """The estimate of a fit: `fit`, its coordinates `phi` less the records' bias where
    `corrected`, the `track_effect` (or `None`), `x` = B `phi` (every parameter), and where the
    bias is kept as uncertainty (`bias_as_variance`, `estimate_of`)."""

    fit: HostFit
    phi: np.ndarray
    corrected: np.ndarray
    track_effect: TrackErrorEffect | None
    x: np.ndarray
    bias_as_variance: np.ndarray


def estimate_of(space: FitSpace, fit: HostFit, track_effect, n_log: int) -> Estimate:
    """The records' bias is removed among the first `n_log` (ln p / p_nominal) coordinates
    where it and the records' first-order spread are both under `SIMEX_MAX_SPREAD` and its
    Monte Carlo variance is known (two refit pairs or more): a
    second-order bias extrapolated from a few Gauss-Newton steps is trusted only there (in ln p
    the steps' own error grows with the spread squared). A bias too large to remove is kept and
    marked `bias_as_variance` (its square joins the variance, `_track_covariance`) where the
    spread is under that limit or the bias points away from nominal (the fit's estimate lies
    beyond the corrected one, seen from nominal: the side of a false alarm); a large bias
    towards nominal on a poorly determined coordinate (a failed damper's, estimated near zero)
    only makes the fitted estimate the cautious one. A bias whose last refit step moved it by
    more than its own size and `SIMEX_MAX_SPREAD` (`unsettled_bias`) is neither: its refits have
    not settled, and the fitted estimate stands. Nuisance coordinates keep their fitted
    values."""
    phi, use = fit.phi, np.zeros(fit.phi.size, dtype=bool)
    large = use.copy()
    if track_effect is not None:
        bias = np.where(unsettled_bias(track_effect), np.nan, track_effect.bias)
        spread = np.sqrt(np.maximum(np.diag(track_effect.covariance), 0.0))
        small = np.isfinite(bias) & (np.abs(bias) < SIMEX_MAX_SPREAD)
        use = small & (spread < SIMEX_MAX_SPREAD) & np.isfinite(track_effect.bias_variance)
        away = bias * fit.phi > 0  # removing it would move the estimate towards nominal
        large = np.isfinite(bias) & ~small & ((spread < SIMEX_MAX_SPREAD) | away)
        use[n_log:], large[n_log:] = False, False
        phi = fit.phi - np.where(use, bias, 0.0)
    return Estimate(fit, phi, use, track_effect, space.matrix() @ phi, large)


def unsettled_bias(track_effect: TrackErrorEffect) -> np.ndarray:
    """(n,) bool: where the records' bias moved by more than its own size and
    `SIMEX_MAX_SPREAD` in its refits' last step (`TrackErrorEffect.bias_by_step`). Measured on
    a failed anti-yaw damper fitted at 1 % of nominal (`track-white`, two 8 s runs, case 17):
    steps +1.30 then -5.84 in ln p, a coordinate whose ln the refits do not hold still."""
    steps = np.asarray(track_effect.bias_by_step, dtype=float)
    if steps.shape[0] < 2:
        return np.zeros(steps.shape[-1], dtype=bool)
    last, change = steps[-1], np.abs(steps[-1] - steps[-2])
    return change > np.maximum(np.abs(last), SIMEX_MAX_SPREAD)


@dataclasses.dataclass(frozen=True)
class Statistics:
    """The estimates' statistics: residual variance `s2` and the noise model's `sigma2`, the
    degrees of freedom `dofs` of the residual, the track and the discrepancy terms, the reported
    `values` of the judged coordinates and `nuisance_values` of the nuisance parameters, the
    standard errors (`se` of every fitted coordinate in reported units, `se_gn` Gauss-Newton,
    `se_residual` of the covariance rule alone, `se_track` of the records' term alone and
    `track_var` its variances, `model_var` the discrepancy term's variances), the covariance
    rule's `bandwidth`, the Jacobian's `rank` and `condition_number`."""

    s2: float
    sigma2: float
    dofs: tuple[float, float]
    values: np.ndarray
    nuisance_values: np.ndarray
    se: np.ndarray
    se_gn: np.ndarray
    se_residual: np.ndarray
    se_track: np.ndarray
    track_var: np.ndarray
    model_var: np.ndarray
    bandwidth: float
    rank: int
    condition_number: float


def _track_covariance(estimate: Estimate, scale) -> np.ndarray:
    """The records' term in reported units, with the Monte Carlo variance of a removed bias and
    the square of a bias kept as uncertainty (`Estimate.bias_as_variance`, `estimate_of`)."""
    effect = estimate.track_effect
    if effect is None:
        return np.zeros((scale.size, scale.size))
    kept = np.where(estimate.bias_as_variance, effect.bias, 0.0) ** 2
    bias_var = np.where(estimate.corrected, effect.bias_variance, kept)
    return np.outer(scale, scale) * (effect.covariance + np.diag(bias_var))


def _discrepancy_covariance(space: FitSpace, estimate: Estimate, scale):
    """(the model discrepancy's covariance in reported units, its degrees of freedom): with the
    Gauss-Newton rule only (`_discrepancy.py`); zeros and inf with the sandwich."""
    p, fit, effect = space.program.problem, estimate.fit, estimate.track_effect
    if not isinstance(p.options.covariance_rule, GaussNewtonCovariance):
        return np.zeros((scale.size, scale.size)), math.inf
    misfits = None if effect is None or not effect.draws else effect.misfits
    rates = [m.sample_rate for m in p.measurements]
    d = model_discrepancy(fit.r, fit.jac, space.runs(), rates, misfits)
    return np.outer(scale, scale) * d.covariance, d.dof


def statistics(space: FitSpace, coords, estimate: Estimate) -> Statistics:
    """The covariance of the estimate (module docstring) and what the verdicts need of it."""
    p, fit = space.program.problem, estimate.fit
    runs, n_bias, k = space.runs(), space.n_bias, len(coords)
    dof = runs.n_present - fit.phi.size - n_bias
    s2 = 2 * fit.cost / dof if dof > 0 else float("nan")
    sigma2 = p.options.noise.sigma2(s2)
    values = np.array([c.nominal for c in coords]) * np.exp(estimate.phi[:k])
    n_log = k + len(p.nuisance)
    extra = nominal_values(p.params, p.nuisance) * np.exp(estimate.phi[k:n_log])
    layout = space.program.nuisance_layout()
    scale = layout.scale(np.concatenate([values, extra]), estimate.x)
    track_p = _track_covariance(estimate, scale)
    model_p, model_dof = _discrepancy_covariance(space, estimate, scale)
    jac, scale = relative_to_nominal(fit.jac, scale, estimate.phi[:n_log])
    rule = p.options.covariance_rule
    cov, gn, bandwidth = rule.estimate(jac, fit.r, runs, n_bias, sigma2, scale)
    se_residual = np.asarray(cov.std_errors)
    if estimate.track_effect is not None or model_p.any():
        cov = with_model_error(cov, track_p + model_p)
    effect = estimate.track_effect
    dofs = (
        p.options.noise.residual_dof(dof),
        max(effect.draws, 1) if effect else math.inf,
        model_dof,
    )
    track_var = np.diag(track_p)
    return Statistics(
        s2, sigma2, dofs, values, extra, np.asarray(cov.std_errors), np.asarray(gn.std_errors),
        se_residual, np.sqrt(np.maximum(track_var, 0.0)), track_var, np.diag(model_p), bandwidth,
        int(gn.rank), float(gn.condition_number),
    )  # fmt: skip


@dataclasses.dataclass(frozen=True)
class ProfileTests:
    """The profile tests of the judged coordinates of `estimate` (`_profile.py`) in `space`'s
    rows, with the residual variance `sigma2`; a limit [unit] is held at ln(limit / nominal)
    plus the records' bias removed from the coordinate."""

    space: FitSpace
    coords: tuple
    estimate: Estimate
    sigma2: float
    say: object

    def test(self, index: int, variance_ratio: float):
        """`limit -> ProfilePoint` for coordinate `index` (`judge`'s `profile`)."""
        return functools.partial(self._at, index, variance_ratio)

    def _at(self, index: int, variance_ratio: float, limit: float) -> ProfilePoint:
        c, fit = self.coords[index], self.estimate.fit
        phi_limit = math.log(limit / c.nominal) + (fit.phi[index] - self.estimate.phi[index])
        self.say(f"profile test: {c.name} held at {np.exp(phi_limit):.3g} x nominal")
        return profile_point(
            self.space.evaluate, fit, index, phi_limit, sigma2=self.sigma2,
            variance_ratio=variance_ratio,
            max_steps=self.space.program.problem.options.max_steps,
        )  # fmt: skip


def runs_used(space: FitSpace) -> str:
    """`"k of n runs"` for the verdicts' evidence."""
    active = space.program.active
    return f"{int(active.sum())} of {active.size} runs"


def judge_coordinates(tests: ProfileTests, statuses, stats: Statistics, member_weights):
    """A verdict per judged coordinate of `tests` (module docstring), with its evidence."""
    space, coords, estimate = tests.space, tests.coords, tests.estimate
    fit, effect = estimate.fit, estimate.track_effect
    z = decision_z(space.program.problem.options.false_alarm_rate, len(coords))
    kind = space.program.problem.options.covariance_rule.name
    verdicts = []
    for j, c in enumerate(coords):
        err, err_gn = stats.se[j], stats.se_gn[j]
        ratio = float(err / err_gn) ** 2 if np.isfinite(err) and err_gn > 0 else 1.0
        variances = (stats.se_residual[j] ** 2, stats.track_var[j], stats.model_var[j])
        dof = satterthwaite_dof(variances, stats.dofs)
        v = judge(
            c.name, stats.values[j], err, c.band, z=z, identifiable=fit.status != "failed",
            profile=tests.test(j, ratio), dof=dof,
        )  # fmt: skip
        v.evidence.update(
            runs_used=runs_used(space),
            identifiable=("alone" if len(c.members) == 1 else "as a group"),
            members=[s.name for i, s in enumerate(statuses) if i in c.members],
            fit_status=fit.status,
            covariance=kind,
            std_error_gauss_newton=float(err_gn),
            std_error_track_record=float(stats.se_track[j]),
            std_error_residuals=float(stats.se_residual[j]),
            std_error_model_discrepancy=float(np.sqrt(max(stats.model_var[j], 0.0))),
            estimate_fitted=float(c.nominal * np.exp(fit.phi[j])),  # before the bias
            track_record_bias=float(effect.bias[j]) if effect is not None else 0.0,  # in ln p
            track_record_bias_se=(  # its Monte Carlo standard error, in ln p
                float(np.sqrt(effect.bias_variance[j])) if effect is not None else 0.0
            ),
            track_record_bias_by_step=(  # after each refit step: the refit's convergence
                [float(b) for b in effect.bias_by_step[:, j]] if effect is not None else []
            ),
        )
        if j in member_weights:
            v.evidence["member_weights"] = member_weights[j]
        if not space.program.active.all():
            v.evidence["note"] = f"judged on {runs_used(space)}: see the runs left out"
        verdicts.append(v)
    return verdicts


def judge_unidentifiable(space: FitSpace, statuses, n_coords: int) -> list[Verdict]:
    """`not identifiable` for every candidate the identifiability rule leaves out."""
    p = space.program.problem
    z = decision_z(p.options.false_alarm_rate, max(n_coords, 1))
    verdicts = []
    for s in (s for s in statuses if s.status == "none"):
        lo, hi = p.bands[s.name].healthy
        v = judge(s.name, 0.5 * (lo + hi), float("inf"), p.bands[s.name], z=z, identifiable=False)
        v.evidence.update(
            runs_used=runs_used(space),
            identifiable="no",
            relative_std_error=s.relative_std_error,
            limit=s.limit,
            max_correlation=s.max_correlation,
            most_correlated=s.most_correlated,
            reason="the Fisher information of these runs does not determine it, alone or in "
            "its group; held at its nominal value in the fit",
        )
        verdicts.append(v)
    return verdicts


def fitted_nuisance(space: FitSpace, stats: Statistics, n_coords: int) -> dict:
    """`{name: {"estimate", "std_error", "nominal", "unit"}}` of the nuisance parameters."""
    p = space.program.problem
    nominal = nominal_values(p.params, p.nuisance)
    se = stats.se[n_coords:]
    return {
        name: {
            "estimate": float(value), "std_error": float(err), "nominal": float(p0),
            "unit": resolve_parameter(p.params, name).spec.unit,
        }
        for name, value, err, p0 in zip(p.nuisance, stats.nuisance_values, se, nominal)
    }  # fmt: skip
