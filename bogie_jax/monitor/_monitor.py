"""`monitor`: verdicts per suspension element from one or several measurement runs of a bogie.

Steps (each documented where it is done):
1. input checks, before anything is compiled: at least one measurement, one sensor layout
   (and channel list) for all of them, one track per measurement, valid bands and names;
2. the joint objective of all runs (`bogie_jax.cost.make_joint_objective`, shared suspension
   parameters, ln p of every candidate) and its residual Jacobian at the nominal bogie: one
   compiled program (`_host_fit.py`), whose first evaluation gives the Fisher information;
   a run whose simulation fails there is left out (and reported);
3. the identifiability rule (`_elements.py`): elements alone, groups, or not identifiable;
4. a Levenberg-Marquardt fit of the identifiable coordinates (the others held at nominal),
   with the same program; a run whose simulation fails at the estimate, or that the joint fit
   does not explain while it explains another (`_checks.failed_runs`), is left out and the
   fit repeated without it (same program: the run's residuals are masked);
5. the covariance of the estimates (`bogie_jax.cost.covariance_from_jacobian` on the final
   Jacobian) and a verdict per coordinate by `judge` (`_verdict.py`), the decision z set by
   `false_alarm_rate` over the judged coordinates (Bonferroni).
"""

import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..cost import covariance_from_jacobian, make_joint_objective, residual_jacobian
from ..params import BogieParams, ModelOptions, manchester_benchmark
from ..simulation import SolveSettings
from ._checks import RUN_MISFIT, check_inputs, failed_runs, tolerance_bands
from ._elements import MAX_CORRELATION, RESOLUTION, check_candidates, classify_elements
from ._host_fit import levenberg_marquardt
from ._result import FitSummary, MonitorResult, RunStatus
from ._verdict import check_false_alarm_rate, decision_z, judge


NOISE_MODES = ("max", "nominal", "estimated")
_JACOBIAN = eqx.filter_jit(residual_jacobian)


def monitor(
    measurements,
    tracks=None,
    *,
    params: BogieParams | None = None,
    candidates=None,
    band=None,
    false_alarm_rate: float = 0.05,
    noise: str = "max",
    resolution: float = RESOLUTION,
    max_correlation: float = MAX_CORRELATION,
    max_steps: int = 30,
    run_misfit: float = RUN_MISFIT,
    options: ModelOptions = ModelOptions(),
    settings: SolveSettings | None = None,
    weights=None,
    progress=None,
) -> MonitorResult:
    """Verdicts per suspension element (`healthy`, `degraded`, `failed`, `not identifiable`)
    from one or several measurement runs of one bogie, fitted jointly (module docstring).

    **Arguments:**
    - `measurements`: `Measurement`s of one sensor layout (different speeds and tracks);
      `tracks`: one `TrackIrregularity` per measurement (default: rebuilt from each
      measurement's synthetic `TrackReference`).
    - `params`: the nominal bogie (default: Manchester benchmark).
    - `candidates`: parameter names to judge (default `DEFAULT_CANDIDATES`: both anti-yaw
      dampers, the primary vertical damping and the vertical and lateral stiffness of each
      axlebox, both secondary lateral dampers).
    - `band`: tolerance bands: `None` (nominal +- 20 %, failed below 25 % of nominal), a
      relative half-width for all, or a mapping `{name: ToleranceBand or half-width}` (element,
      group or tied names; others default).
    - `false_alarm_rate`: the probability of any false alarm on a healthy bogie (`judge`).
    - `noise`: residual variance of the covariance: `"nominal"` (1: the sensors' noise_std
      weights are right), `"estimated"` (2 J / (m - n) from the fit), `"max"` (default: the
      larger of both: never more confident than the sensors allow, wider when the fit leaves
      more than noise).
    - `resolution`, `max_correlation`: the identifiability rule (`_elements.py`).
    - `max_steps`: Levenberg-Marquardt steps; `run_misfit`: the rule that leaves a run out
      after the fit (`_checks.failed_runs`: a run whose simulation fails, or whose residuals
      stay above sqrt(run_misfit) times the sensors' noise while another run is fitted
      `run_misfit` times better); the verdicts then say they used fewer runs;
    - `options`, `settings`, `weights`: as `make_objective`; `progress`: a callable taking one
      line of text, or `None`.

    **Returns:** a `MonitorResult`.

    **Raises:** `ValueError` before anything is compiled: no measurements, mixed sensor
    layouts, a track count that differs from the measurement count, unknown or repeated
    candidates, a band of zero width, a false-alarm rate outside (0, 0.5), an unknown `noise`.
    `RuntimeError` if the simulation fails for every run.
    """
    tic = time.perf_counter()
    say = progress if progress is not None else (lambda line: None)
    measurements, tracks = check_inputs(measurements, tracks)
    check_false_alarm_rate(false_alarm_rate)
    if noise not in NOISE_MODES:
        raise ValueError(f"`noise` = {noise!r} must be one of {', '.join(NOISE_MODES)}")
    if not 0 < resolution <= 1 or not 0 < max_correlation <= 1:
        raise ValueError(
            f"`resolution` = {resolution!r} and `max_correlation` = {max_correlation!r} must lie "
            "in (0, 1]"
        )
    params = manchester_benchmark() if params is None else params
    names = check_candidates(params, candidates)
    bands = tolerance_bands(params, names, band)
    # throw=False: a failed solve gives infinite residuals for its run (left out, reported)
    # instead of an error that would stop every run of the vmapped program
    if settings is not None and not isinstance(settings, SolveSettings):
        raise TypeError(f"`settings` must be a SolveSettings, got {type(settings).__name__}")
    settings = (SolveSettings.for_objective() if settings is None else settings).replace(
        throw=False
    )
    objective = make_joint_objective(
        measurements, params, tracks, names, options=options, settings=settings, weights=weights
    ).forward_mode()
    n_runs = len(measurements)
    active = np.ones(n_runs, dtype=bool)
    reasons = [""] * n_runs
    timings: dict[str, float] = {}

    def with_active(obj):
        return eqx.tree_at(lambda o: o.residual_model.active, obj, jnp.asarray(active))

    def evaluate(theta):
        r, jac = jax.block_until_ready(_JACOBIAN(objective, jnp.asarray(theta)))
        return np.asarray(r), np.asarray(jac)

    # 2. Fisher information at the nominal bogie (the first call compiles)
    say(f"compiling the joint residual Jacobian ({n_runs} runs, {len(names)} candidates)")
    t0, c0 = time.perf_counter(), time.process_time()
    r0, jac0 = evaluate(np.zeros(len(names)))
    timings["first_jacobian_s"] = time.perf_counter() - t0
    timings["first_jacobian_cpu_s"] = time.process_time() - c0
    slices = objective.residual_model.run_slices
    n_obs_runs = [int(np.isfinite(np.asarray(m.data)).sum()) for m in measurements]
    for k, sl in enumerate(slices):
        if not (np.all(np.isfinite(r0[sl])) and np.all(np.isfinite(jac0[sl]))):
            active[k], reasons[k] = False, "simulation failed at the nominal bogie"
    if not active.any():
        raise RuntimeError("the simulation failed for every run at the nominal bogie")
    if not active.all():
        objective = with_active(objective)
        t0 = time.perf_counter()
        r0, jac0 = evaluate(np.zeros(len(names)))
        timings["jacobian_s"] = time.perf_counter() - t0
    say("Fisher information: " + ", ".join(f"run {k} left out" for k in np.flatnonzero(~active)))

    # 3. identifiability
    z_rule = decision_z(false_alarm_rate, len(names))
    coords, statuses = classify_elements(
        params, names, jac0, bands, band, z_rule,
        resolution=resolution, max_correlation=max_correlation,
    )  # fmt: skip
    say(f"identifiable: {', '.join(c.name for c in coords) or 'none'}")

    # 4. fit of the identifiable coordinates
    a = np.zeros((len(names), len(coords)))
    for j, c in enumerate(coords):
        a[list(c.members), j] = 1.0

    def evaluate_phi(phi):
        r, jac = evaluate(a @ phi)
        return r, jac @ a

    t0 = time.perf_counter()
    fit = None
    if coords:
        fit = levenberg_marquardt(evaluate_phi, np.zeros(len(coords)), max_steps=max_steps)
        while True:
            bad, why = failed_runs(fit.r, slices, active, n_obs_runs, run_misfit)
            if not bad:
                break
            for k in bad:
                active[k], reasons[k] = False, why[k]
            say(f"left out: {'; '.join(f'run {k} ({why[k]})' for k in bad)}; fitting again")
            objective = with_active(objective)
            fit = levenberg_marquardt(evaluate_phi, np.zeros(len(coords)), max_steps=max_steps)
    timings["fit_s"] = time.perf_counter() - t0

    # 5. covariance and verdicts
    n_obs = int(
        sum(np.isfinite(np.asarray(measurements[k].data)).sum() for k in np.flatnonzero(active))
    )
    verdicts, summary = _verdicts(
        coords, statuses, fit, bands, n_obs, noise, false_alarm_rate, active, n_runs
    )
    runs = tuple(
        RunStatus(
            index=k,
            speed=float(np.asarray(m.speed)),
            duration=float(np.asarray(m.times)[-1] - np.asarray(m.times)[0]),
            track=m.track.describe() if m.track is not None else "",
            used=bool(active[k]),
            reason=reasons[k],
            residual_rms=float(np.sqrt(np.mean(fit.r[slices[k]] ** 2)))
            if fit is not None and active[k]
            else float("nan"),
        )
        for k, m in enumerate(measurements)
    )
    timings["total_s"] = time.perf_counter() - tic
    return MonitorResult(
        verdicts=verdicts,
        elements=tuple(statuses),
        fit=summary,
        runs=runs,
        false_alarm_rate=float(false_alarm_rate),
        timings=timings,
    )


def _verdicts(coords, statuses, fit, bands, n_obs, noise, alpha, active, n_runs):
    used = f"{int(active.sum())} of {n_runs} runs"
    verdicts = []
    nan = float("nan")
    summary = FitSummary(
        names=(), status="no identifiable element", steps=0, evaluations=0, cost=nan,
        noise_variance=nan, sigma2=nan, rank=0, condition_number=nan, runs_used=int(active.sum()),
    )  # fmt: skip
    if coords:
        m, n = n_obs, len(coords)
        s2 = 2 * fit.cost / (m - n) if m > n else float("nan")
        sigma2 = {"nominal": 1.0, "estimated": s2, "max": max(1.0, s2)}[noise]
        values = np.array([c.nominal for c in coords]) * np.exp(fit.phi)
        cov = covariance_from_jacobian(fit.jac, sigma2=sigma2, scale=values)
        se = np.asarray(cov.std_errors)
        z = decision_z(alpha, len(coords))
        for c, value, err in zip(coords, values, se):
            v = judge(c.name, value, err, c.band, z=z, identifiable=fit.status != "failed")
            v.evidence.update(
                runs_used=used,
                identifiable=("alone" if len(c.members) == 1 else "as a group"),
                members=[s.name for i, s in enumerate(statuses) if i in c.members],
                fit_status=fit.status,
            )
            if not active.all():
                v.evidence["note"] = f"judged on {used}: see the runs left out"
            verdicts.append(v)
        summary = FitSummary(
            names=tuple(c.name for c in coords), status=fit.status, steps=fit.steps,
            evaluations=fit.evaluations, cost=fit.cost, noise_variance=s2, sigma2=sigma2,
            rank=int(cov.rank), condition_number=float(cov.condition_number),
            runs_used=int(active.sum()), costs=fit.costs,
        )  # fmt: skip
    z = decision_z(alpha, max(len(coords), 1))
    for s in statuses:
        if s.status != "none":
            continue
        nominal = bands[s.name]
        lo, hi = nominal.healthy
        v = judge(s.name, 0.5 * (lo + hi), float("inf"), nominal, z=z, identifiable=False)
        v.evidence.update(
            runs_used=used,
            identifiable="no",
            relative_std_error=s.relative_std_error,
            limit=s.limit,
            max_correlation=s.max_correlation,
            most_correlated=s.most_correlated,
            reason="the Fisher information of these runs does not determine it, alone or in "
            "its group; held at its nominal value in the fit",
        )
        verdicts.append(v)
    return tuple(verdicts), summary
