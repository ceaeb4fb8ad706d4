"""`monitor`'s fitting steps: select the elements, fit them over the horizon (leaving out the runs
the fit cannot explain), reweight by each channel's noise, and weigh a group's members.

Each step takes the values the last one returned and returns new ones; the only state is the
`FitSpace`'s memo of its last evaluation.
"""

import dataclasses

import numpy as np

from ..cost import channel_variances, channel_weights
from ..identify import HostFit, levenberg_marquardt, restart_vanished
from ._checks import failed_runs
from ._elements import classify_elements, group_weights
from ._horizon import horizon_stages, window_rows
from ._program import FitSpace, JointProgram
from ._verdict import decision_z


REWEIGHTS = 3  # at most this many refits with per-channel weights
SETTLED = 0.1  # the weights have settled when none changes by more than this fraction
STAGE_OFFSET_TOL = 0.3  # a horizon stage's relative-offset stop (`_horizon.py`)
VANISHED = float(np.log(1e-3))  # a judged ln(p / nominal) below this is restarted at 0


def select_elements(program: JointProgram, jac0, say):
    """The identifiable coordinates and every candidate's `ElementStatus` (`_elements.py`), from
    the Jacobian `jac0` at the nominal bogie with the sensor bias and the nuisance columns
    profiled out (`_nuisance.py`); and the map `a` of the coordinates (n_candidates, n_coords)."""
    p, o = program.problem, program.problem.options
    space = FitSpace.of(program, np.zeros((len(p.candidates), 0)), o.remove_bias)
    coords, statuses = classify_elements(
        p.params, p.candidates, program.nuisance_layout().profile(space.project(jac0)), p.bands,
        o.band, decision_z(o.false_alarm_rate, len(p.candidates)),
        resolution=o.resolution, max_correlation=o.max_correlation,
    )  # fmt: skip
    say(f"identifiable: {', '.join(c.name for c in coords) or 'none'}")
    a = np.zeros((len(p.candidates), len(coords)))
    for j, c in enumerate(coords):
        a[list(c.members), j] = 1.0
    return coords, statuses, a


def _times(program: JointProgram) -> list[np.ndarray]:
    return [np.asarray(m.times) for m in program.problem.measurements]


def fit_stages(program: JointProgram) -> tuple[float, ...]:
    """The horizons fitted before the whole record (`_horizon.horizon_stages`)."""
    start = program.problem.options.horizon_start
    return horizon_stages([t[-1] - t[0] for t in _times(program)], start)


def _stop_margin(program: JointProgram) -> float:
    """[s]: a stage's solves run one sample spacing past its horizon, so that its last sample
    is simulated whatever the rounding of the sample times."""
    return max((float(np.max(np.diff(t))) for t in _times(program) if t.size > 1), default=0.0)


def fit_over_horizon(space: FitSpace, say) -> tuple[HostFit, ...]:
    """The fits from the nominal bogie (and stated speeds and positions) over the horizon
    stages, each from the last estimate with the solves stopped past the stage's horizon
    (`JointProgram.with_horizon`; J from the looser solves, `with_loose_jacobian`), then of the
    whole record (`space`'s rows); where the stages end at a point whose whole-record
    simulation fails, the whole record again from the start; where a judged element ends
    below 0.1 % of nominal, the whole record again with it restarted at nominal, kept where
    it ends lower (`bogie_jax.identify.restart_vanished`). The last fit is the estimate."""
    program, max_steps = space.program, space.program.problem.options.max_steps
    phi = np.zeros(space.n_coords + program.nuisance_layout().n_extra())
    fits, stages = [], fit_stages(program)
    for horizon in stages:
        window = window_rows(_times(program), program.slices, program.problem.n_channels, horizon)
        say(f"fitting the first {horizon:g} s of every run")
        staged = program.with_horizon(horizon + _stop_margin(program)).with_loose_jacobian()
        short = space.with_program(staged)
        stage = levenberg_marquardt(
            short.with_window(window).evaluate, phi, max_steps=max_steps,
            offset_tol=STAGE_OFFSET_TOL,
        )  # fmt: skip
        fits.append(stage)
        phi = stage.phi if stage.status != "failed" else phi
    fits.append(levenberg_marquardt(space.evaluate, phi, max_steps=max_steps))
    if fits[-1].status == "failed" and stages:
        say("the stages' estimate fails on the whole record: fitting it from the start")
        fits.append(levenberg_marquardt(space.evaluate, np.zeros_like(phi), max_steps=max_steps))
    judged = range(space.n_coords)
    revived = restart_vanished(
        space.evaluate, fits[-1], judged, level=VANISHED, max_steps=max_steps
    )
    if revived is not fits[-1]:
        say("an element fitted at nearly zero: restarted at nominal, the fit ends lower")
        fits.append(revived)
    return tuple(fits)


def fit_runs(space: FitSpace, reasons: tuple[str, ...], say):
    """`fit_over_horizon`, repeated without the runs it leaves unexplained
    (`_checks.failed_runs`, by `run_misfit`) until it leaves none: the last `FitSpace` (its
    program's `active` runs), every fit made, and each run's reason for being left out."""
    program = space.program
    n_obs = [int(np.isfinite(np.asarray(m.data)).sum()) for m in program.problem.measurements]
    fits = fit_over_horizon(space, say)
    while True:
        active = space.program.active
        run_misfit = program.problem.options.run_misfit
        bad, why = failed_runs(fits[-1].r, space.program.slices, active, n_obs, run_misfit)
        if not bad:
            return space, fits, reasons
        reasons = tuple(why.get(k, reason) for k, reason in enumerate(reasons))
        say(f"left out: {'; '.join(f'run {k} ({why[k]})' for k in bad)}; fitting again")
        keep = active & ~np.isin(np.arange(active.size), bad)
        space = space.with_program(space.program.with_active(keep))
        fits = fits + fit_over_horizon(space, say)


@dataclasses.dataclass(frozen=True)
class Reweighted:
    """The fit after reweighting: its `space` (row weights), the estimate `fit`, the `refits`
    made, the channel variances `s2_channels` (n_runs, n_channels; `None` without a fit), the
    `weights` (n_runs, n_channels) of the rows and the number of `reweights`."""

    space: FitSpace
    fit: HostFit
    refits: tuple[HostFit, ...]
    s2_channels: np.ndarray | None
    weights: np.ndarray
    reweights: int


def reweight(space: FitSpace, fit: HostFit, say) -> Reweighted:
    """Each run-channel's residual variance estimated from `fit`
    (`bogie_jax.cost.channel_variances`) and, for a noise model that reweights, the fit repeated
    from its estimate with the rows weighted by 1 / sqrt of it, up to `REWEIGHTS` times, until
    no weight changes by more than `SETTLED`; a failed refit keeps the last fit and weights."""
    o = space.program.problem.options
    w = np.ones((space.program.problem.n_runs, space.program.problem.n_channels))
    done = Reweighted(space, fit, (), None, w, 0)
    if fit.status == "failed":
        return done
    runs = space.runs()
    s2 = channel_variances(fit.r, fit.jac, runs, remove_bias=o.remove_bias)
    done = dataclasses.replace(done, s2_channels=s2)
    if not o.noise.reweights:
        return done
    dof = runs.n_present - space.n_bias - fit.phi.size
    reference = float(fit.r @ fit.r) / dof if dof > 0 else 1.0
    for _ in range(REWEIGHTS):
        new = channel_weights(done.s2_channels, reference=reference)
        if np.nanmax(np.abs(new / done.weights - 1.0)) <= SETTLED:
            break
        spread = np.sqrt(done.s2_channels[space.program.active])
        say(
            f"per-channel noise {np.nanmin(spread):.3g} to {np.nanmax(spread):.3g} of the "
            "assumed; fitting again with these weights"
        )
        trial = done.space.with_rows(runs.expand(new))
        refit = levenberg_marquardt(trial.evaluate, done.fit.phi, max_steps=o.max_steps)
        refits, count = done.refits + (refit,), done.reweights + 1
        if refit.status == "failed":  # keep the last fit and its weights
            return dataclasses.replace(done, refits=refits, reweights=count)
        s2 = channel_variances(refit.r, refit.jac, runs, remove_bias=o.remove_bias, weights=new)
        done = Reweighted(trial, refit, refits, s2, new, count)
    return done


def member_weights(space: FitSpace, coords, fit: HostFit) -> dict[int, dict[str, float]]:
    """Per group coordinate index, its members' weights in its estimate
    (`_elements.group_weights`), from their columns at the estimate in the fit's rows and
    weights; `{}` without a group or a fit."""
    if fit.status == "failed" or not any(len(c.members) > 1 for c in coords):
        return {}
    names = space.program.problem.candidates
    jac_x = space.jacobian_x(fit.phi)
    columns = space.project(jac_x[:, : len(names)]) * space.rows[:, None]
    out = {}
    for j, c in enumerate(coords):
        if len(c.members) > 1:
            v = group_weights(columns[:, list(c.members)], np.delete(fit.jac, j, axis=1))
            out[j] = {names[i]: float(w_i) for i, w_i in zip(c.members, v)}
    return out
