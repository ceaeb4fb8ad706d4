"""`monitor`: verdicts per suspension element from one or several measurement runs of a bogie.

The steps, each a function that takes what the last one returned:

1. `prepare`: the input checked before anything is compiled (`MonitorOptions` checks itself);
2. `first_jacobian`: the joint residual-Jacobian program (`_program.py`) compiled and evaluated
   at the nominal bogie, which gives the Fisher information; a run whose simulation fails
   there is left out;
3. `_fit.select_elements`: the identifiability rule (`_elements.py`) on the Jacobian with the
   sensor bias (`bogie_jax.cost.RunChannels`) and the nuisance columns (`_nuisance.py`)
   profiled out: elements alone, groups, or not identifiable;
4. `_fit.fit_runs`: a Levenberg-Marquardt fit (`bogie_jax.identify.levenberg_marquardt`) of
   the identifiable coordinates with every nuisance parameter, over growing horizons
   (`_horizon.py`), repeated without a run the fit cannot explain (`_checks.failed_runs`);
5. `_fit.reweight`: each run-channel's noise estimated and the fit reweighted, by the noise
   model (`bogie_jax.cost.AbstractNoiseModel`);
6. `_record_shape.record_term`: the track records' error term and bias (`_track_error.py`),
   its shape (like the track, or partly white) chosen by the misfit it leaves;
7. `_judgement.statistics` and `judge_*`: the covariance by the covariance rule, a verdict per
   coordinate (`_verdict.judge`, profile tests by `_profile.py`);
8. `_goodness.fit_goodness`: does the fit explain the data, per run and channel group; where
   it does not, steps 2 to 8 are repeated with the nonlinear model (`_model_refit.py`) and its
   verdicts kept where it does; else `_suspects.screen` names the elements not judged that
   would explain it and withholds an alarm that does not hold with them free;
9. `summarise`: the `FitSummary` and every run's `RunStatus`.

Steps 3 to 9 are numpy on the residuals and Jacobian the one compiled program returns.
"""

import dataclasses
import time

import numpy as np

from ..params import BogieParams, manchester_benchmark
from ._checks import check_inputs, tolerance_bands
from ._elements import check_candidates
from ._fit import fit_runs, fit_stages, member_weights, reweight, select_elements
from ._goodness import fit_goodness
from ._judgement import (
    Estimate,
    ProfileTests,
    Statistics,
    estimate_of,
    fitted_nuisance,
    judge_coordinates,
    judge_unidentifiable,
    statistics,
)
from ._model_refit import model_name, refit_problem
from ._nuisance import check_nuisance
from ._options import MonitorOptions
from ._program import FitSpace, JointProgram, MonitorProblem
from ._record_shape import mixed_record_term, record_term
from ._result import FitSummary, MonitorResult, RunStatus
from ._suspects import screen


def monitor(
    measurements,
    tracks=None,
    *,
    params: BogieParams | None = None,
    options: MonitorOptions | None = None,
    progress=None,
) -> MonitorResult:
    """Verdicts per suspension element (`healthy`, `degraded`, `failed`, `not identifiable`)
    from one or several measurement runs of one bogie, fitted jointly (module docstring).

    **Arguments:** `measurements`: `Measurement`s of one sensor layout (speeds and tracks may
    differ); `tracks`: one `TrackIrregularity` per measurement (default: rebuilt from each
    measurement's synthetic `TrackReference`); `params`: the nominal bogie (default: the
    Manchester benchmark); `options`: `MonitorOptions` (default `MonitorOptions()`);
    `progress`: a callable taking one line of text, or `None`.

    **Returns:** a `MonitorResult`.

    **Raises:** `ValueError` or `TypeError` before anything is compiled (bad input, named);
    `RuntimeError` when every run's simulation fails at the nominal bogie.
    """
    tic = time.perf_counter()
    say = progress if progress is not None else (lambda line: None)
    problem = prepare(measurements, tracks, params, options)
    outcome = judge_problem(problem, say)
    refit = None if outcome.fits_every_run else refit_problem(problem)
    if refit is not None:
        first = model_name(problem.options.model)
        say(f"the {first} model does not explain the data: fitting the model with "
            f"{model_name(refit.options.model)}")  # fmt: skip
        t0 = time.perf_counter()
        again = _refit_outcome(refit, say)
        if again is not None and again.fits_every_run:
            first_s = {"first_model_s": t0 - tic}
            return summarise(again, _total(tic) | first_s, model_refit=True)
        outcome.timings["refit_s"] = time.perf_counter() - t0
        say(f"that model does not explain them either: the {first} model's verdicts stand")
    return summarise(screened(outcome, say), _total(tic))


def _refit_outcome(problem: MonitorProblem, say) -> "_Outcome | None":
    """`judge_problem(problem)`; `None` where every run's simulation fails at the nominal bogie
    with the refit's model (the first model's verdicts then stand)."""
    try:
        return judge_problem(problem, say)
    except RuntimeError as error:
        say(f"the refit stopped: {error}")
        return None


def judge_problem(problem: MonitorProblem, say) -> "_Outcome":
    """Steps 2 to 8 before the suspects: the verdicts on `problem` and the goodness of fit."""
    program, jac0, reasons, timings = first_jacobian(problem, say)
    coords, statuses, a = select_elements(program, jac0, say)
    space = FitSpace.of(program, a, problem.options.remove_bias)
    t0 = time.perf_counter()
    if not coords:
        verdicts = tuple(judge_unidentifiable(space, statuses, 0))
        timings["fit_s"] = 0.0
        timings["verdicts_s"] = time.perf_counter() - t0
        return _Outcome(space, statuses, verdicts, None, reasons, timings)
    space, fits, reasons = fit_runs(space, reasons, say)
    done = reweight(space, fits[-1], say)
    timings["fit_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    done, effect = record_term(done, say)
    if effect is not None:
        timings["track_error_s"] = time.perf_counter() - t0
    weights = member_weights(done.space, coords, done.fit)
    t0 = time.perf_counter()
    estimate = estimate_of(done.space, done.fit, effect, len(coords) + len(problem.nuisance))
    stats = statistics(done.space, coords, estimate)
    tests = ProfileTests(done.space, coords, estimate, stats.sigma2, say)
    verdicts = judge_coordinates(tests, statuses, stats, weights)
    verdicts += judge_unidentifiable(done.space, statuses, len(coords))
    timings["verdicts_s"] = time.perf_counter() - t0
    goodness = fit_goodness(done.space, done.fit, effect)
    judged = _Judged(coords, fits + done.refits, done, estimate, stats, goodness)
    return _Outcome(done.space, statuses, tuple(verdicts), judged, reasons, timings)


def screened(outcome: "_Outcome", say) -> "_Outcome":
    """Step 8's suspects: where the fit does not explain the data, the elements not judged that
    would (`_suspects.screen`), and the verdicts scaled for the misfit and checked with them
    free; `outcome` itself where it does."""
    judged = outcome.judged
    if outcome.explained:
        return outcome
    t0 = time.perf_counter()
    done, effect = judged.reweighted, judged.estimate.track_effect
    mixed = mixed_record_term(effect)  # the misfit the chosen shape leaves, if it differs
    left = None if mixed is effect else fit_goodness(done.space, done.fit, mixed)
    goodness, verdicts = screen(done.space, done.fit, len(judged.coords), list(outcome.verdicts),
                                judged.goodness, judged.stats.s2, say, left=left)  # fmt: skip
    return dataclasses.replace(
        outcome, verdicts=tuple(verdicts), judged=dataclasses.replace(judged, goodness=goodness),
        timings=outcome.timings | {"suspects_s": time.perf_counter() - t0},
    )  # fmt: skip


def compile_programs(measurements, tracks=None, *, params=None, options=None) -> None:
    """Compile the programs that `monitor(measurements, tracks, params=params,
    options=options)` evaluates (or read them from the program store and the persistent
    cache), by evaluating its first Jacobian (`first_jacobian`): a later `monitor` on data of
    the same shapes, channels, track references and options compiles nothing. The data's
    values are not used: measurements of zero data do (`scenario_layout`), so the programs can
    compile while the data are simulated or read. **Raises:** as `monitor`."""
    first_jacobian(prepare(measurements, tracks, params, options), lambda line: None)


def _total(tic: float) -> dict[str, float]:
    return {"total_s": time.perf_counter() - tic}


def prepare(measurements, tracks, params, options) -> MonitorProblem:
    """Step 1: the checked input (`_checks.py`, `_elements.check_candidates`,
    `_nuisance.check_nuisance`, `_checks.tolerance_bands`); `ValueError` or `TypeError` naming
    the argument before anything is compiled."""
    options = MonitorOptions() if options is None else options
    if not isinstance(options, MonitorOptions):
        raise TypeError(f"`options` must be a MonitorOptions, got {type(options).__name__}")
    measurements, tracks = check_inputs(measurements, tracks)
    params = manchester_benchmark() if params is None else params
    names = check_candidates(params, options.candidates)
    nuisance = check_nuisance(params, options.nuisance, names)
    bands = tolerance_bands(params, names, options.band)
    return MonitorProblem(
        measurements, tracks, params, names, nuisance, bands, options, options.solve_settings()
    )


def first_jacobian(problem: MonitorProblem, say):
    """Step 2: the program compiled and evaluated at the nominal bogie: the program (the runs
    whose simulation solved there active), its Jacobian there, each run's reason for being left
    out (`""` where used) and the timings. **Raises:** `RuntimeError` if no run solved."""
    program = JointProgram.build(problem)
    n_x = program.nuisance_layout().n_x
    say(
        f"compiling the joint residual Jacobian ({problem.n_runs} runs, "
        f"{len(problem.candidates)} candidates, {n_x - len(problem.candidates)} nuisance "
        "parameters)"
    )
    t0, c0 = time.perf_counter(), time.process_time()
    # the identifiability rule needs no tighter J: the looser solves compile the residuals'
    # own program beside the Jacobian's (`_program.py`)
    r0, jac0 = program.with_loose_jacobian().evaluate(np.zeros(n_x))
    timings = {
        "first_jacobian_s": time.perf_counter() - t0,
        "first_jacobian_cpu_s": time.process_time() - c0,
    }
    solved = np.array(
        [np.all(np.isfinite(r0[sl])) & np.all(np.isfinite(jac0[sl])) for sl in program.slices]
    )
    reasons = tuple("" if ok else "simulation failed at the nominal bogie" for ok in solved)
    if not solved.any():
        raise RuntimeError("the simulation failed for every run at the nominal bogie")
    if not solved.all():
        program = program.with_active(solved)
        t0 = time.perf_counter()
        r0, jac0 = program.with_loose_jacobian().evaluate(np.zeros(n_x))
        timings["jacobian_s"] = time.perf_counter() - t0
    left_out = ", ".join(f"run {k} left out" for k in np.flatnonzero(~solved))
    say(f"Fisher information: {left_out or f'all {problem.n_runs} runs used'}")
    return program, jac0, reasons, timings


@dataclasses.dataclass(frozen=True)
class _Judged:
    """What the fit and the verdicts on the judged coordinates leave for the summary."""

    coords: tuple
    fits: tuple
    reweighted: object  # `_fit.Reweighted`
    estimate: Estimate
    stats: Statistics
    goodness: object = None  # `_goodness.GoodnessOfFit`


@dataclasses.dataclass(frozen=True)
class _Outcome:
    """The verdicts on one problem before the summary: the fit space, every candidate's status,
    the verdicts, what the fit left (`None` where no element is identifiable), each run's reason
    for being left out and the timings."""

    space: FitSpace
    statuses: tuple
    verdicts: tuple
    judged: _Judged | None
    reasons: tuple
    timings: dict

    @property
    def explained(self) -> bool:
        """False where the goodness-of-fit test fails (`_goodness.py`)."""
        return self.judged is None or self.judged.goodness.explained

    @property
    def fits_every_run(self) -> bool:
        """The fit explains the data and leaves no run out (`_checks.failed_runs`)."""
        return self.explained and not any(self.reasons)


def summarise(outcome: _Outcome, timings: dict, *, model_refit: bool = False) -> MonitorResult:
    """Step 9: the `MonitorResult`, the outcome's timings updated by `timings`; `model_refit`:
    the outcome is `MonitorOptions.refit_model`'s (`_model_refit.py`)."""
    space, judged = outcome.space, outcome.judged
    return MonitorResult(
        verdicts=outcome.verdicts,
        elements=tuple(outcome.statuses),
        fit=fit_summary(space, judged, model_refit),
        runs=run_statuses(space, judged, outcome.reasons),
        false_alarm_rate=float(space.program.problem.options.false_alarm_rate),
        timings=outcome.timings | timings,
        goodness=None if judged is None else judged.goodness,
    )


def fit_summary(space: FitSpace, judged: _Judged | None, model_refit: bool) -> FitSummary:
    """The `FitSummary` of the last fit (module docstring of `_result.py`)."""
    o, active = space.program.problem.options, space.program.active
    nan = float("nan")
    common = dict(
        runs_used=int(active.sum()), noise=o.noise.name, covariance=o.covariance_rule.name,
        bias_removed=bool(o.remove_bias), track_error=o.track_error,
        run_corrections=space.program.nuisance_layout().corrections,
        model=model_name(o.model), model_refit=model_refit,
    )  # fmt: skip
    if judged is None:
        return FitSummary(
            names=(), status="no identifiable element", steps=0, evaluations=0, cost=nan,
            noise_variance=nan, sigma2=nan, rank=0, condition_number=nan, **common,
        )  # fmt: skip
    fit, stats, done = judged.estimate.fit, judged.stats, judged.reweighted
    noise_levels = ()
    if done.s2_channels is not None:
        noise_levels = tuple(
            tuple(float(x) for x in np.sqrt(s2)) if on else ()
            for s2, on in zip(done.s2_channels, active)
        )
    effect = judged.estimate.track_effect
    fits = judged.fits
    return FitSummary(
        names=tuple(c.name for c in judged.coords), status=fit.status,
        steps=sum(f.steps for f in fits), evaluations=sum(f.evaluations for f in fits),
        cost=fit.cost, noise_variance=stats.s2, sigma2=stats.sigma2, rank=stats.rank,
        condition_number=stats.condition_number, costs=fit.costs, bandwidth=stats.bandwidth,
        reweights=done.reweights, channel_noise=noise_levels,
        nuisance=fitted_nuisance(space, stats, len(judged.coords)),
        track_error_draws=0 if effect is None else effect.draws, horizons=fit_stages(space.program),
        misfit_ratio=misfit_ratio(space, judged),
        track_error_white_share=0.0 if effect is None else effect.white_share,
        track_error_long_wave_share=0.0 if effect is None else effect.long_wave_share,
        track_records_calibrated=effect is not None and effect.calibrated, **common,
    )  # fmt: skip


def misfit_ratio(space: FitSpace, judged: _Judged) -> float:
    """2 S over the residual sum of squares the records' error (`_track_error.py`) and the
    sensors' stated noise in the fit's weights leave, less the fitted and bias parameters'
    share; NaN without the records' term."""
    effect, fit = judged.estimate.track_effect, judged.estimate.fit
    if effect is None or not effect.draws:
        return float("nan")
    runs = space.runs()
    m = runs.n_present
    noise_ss = float(np.sum(runs.counts() * judged.reweighted.weights**2))
    noise_ss *= (m - fit.phi.size - space.n_bias) / m
    return 2.0 * fit.cost / (effect.misfit_ss + noise_ss)


def run_statuses(space: FitSpace, judged: "_Judged | None", reasons) -> tuple[RunStatus, ...]:
    """Every run's `RunStatus`: its fitted position offset and speed factor with their standard
    errors (the last of the nuisance coordinates' standard errors) and its residual RMS."""
    p, active = space.program.problem, space.program.active
    layout = space.program.nuisance_layout()
    x = np.zeros(layout.n_x) if judged is None else judged.estimate.x
    offsets, factors = layout.offsets(x), np.exp(layout.log_speed_factors(x))
    fit = None if judged is None else judged.estimate.fit
    fitted = fit is not None and fit.status != "failed" and p.options.run_corrections
    se_runs = np.full((2, p.n_runs), np.nan)
    se_extra = np.zeros(0) if judged is None else judged.stats.se[len(judged.coords) :]
    if fitted and se_extra.size:
        n = int(active.sum())
        se_runs[0, active], se_runs[1, active] = se_extra[-2 * n : -n], se_extra[-n:]
    nan = float("nan")
    return tuple(
        RunStatus(
            index=k, speed=float(np.asarray(m.speed)),
            duration=float(np.asarray(m.times)[-1] - np.asarray(m.times)[0]),
            track=m.track.describe() if m.track is not None else "", used=bool(active[k]),
            reason=reasons[k], residual_rms=_residual_rms(space, fit, k) if active[k] else nan,
            position_offset=float(offsets[k]) if active[k] else nan,
            speed_factor=float(factors[k]) if active[k] else nan,
            position_offset_se=float(se_runs[0, k]), speed_factor_se=float(se_runs[1, k]),
            corrected=bool(fitted and active[k]),
        )
        for k, m in enumerate(p.measurements)
    )  # fmt: skip


def _residual_rms(space: FitSpace, fit, k: int) -> float:
    """Run k's RMS of the fit's residuals in the sensors' stated noise."""
    if fit is None:
        return float("nan")
    sl = space.program.slices[k]
    return float(np.sqrt(np.mean((fit.r[sl] / space.rows[sl]) ** 2)))
