"""Standard errors of a fit that does not explain the data, scaled by the misfit in the rows
that inform each estimate.

Where the goodness-of-fit test rejects (`_goodness.py`), part of the misfit has the shape of
the fitted columns and moves the estimates by more than any noise model of the residuals
predicts (it is absorbed, not left in the residuals). The conventional remedy for data that
are inconsistent with their model is to scale the standard errors by the square root of the
ratio of the observed misfit to the expected one (Birge, Phys. Rev. 40 (1932) 207; the
Particle Data Group's scale factor, e.g. Navas et al., Phys. Rev. D 110 (2024) 030001,
Introduction 5.2). Here the ratio is taken per estimate: coordinate j's estimate is a linear
combination a_j = (J^+)_j of the weighted residual rows, so a misfit that multiplies the
power of run-group g by rho_g multiplies the estimate's variance by

    rho_j = sum_g rho_g s_jg,   s_jg = sum over g's rows of a_j^2 / |a_j|^2,

with rho_g = max(1, `Misfit.ratio`) of every run-group tested (with the records' term of the
shape the data chose, `_record_shape.mixed_record_term`) and 1 for the rows of none. The
standard error becomes max(se, sqrt(rho_j) se_0), se_0 the standard error without the model
discrepancy's term (`_discrepancy.py`, which estimates the same misfit's stationary part:
taking the larger of the two never counts it twice), and the 95 % interval widens by the same
factor about the estimate (an element on watch stays so only if the wider interval still lies
outside its band).
"""

import dataclasses
import math

import numpy as np

from ._goodness import GoodnessOfFit
from ._verdict import Verdict, interval_outside


def _group_rows(space, run: int, channels) -> np.ndarray:
    """The rows of run `run`'s `channels` (names) in the residual vector."""
    p, runs = space.program.problem, space.runs()
    names = list(p.measurements[run].channels)
    sl = runs.slices[run]
    rows = np.arange(sl.start, sl.stop).reshape(-1, runs.n_channels)
    return rows[:, [names.index(c) for c in channels]].ravel()


def misfit_scales(space, fit, goodness: GoodnessOfFit, n_coords: int) -> np.ndarray:
    """(n_coords,) rho_j of the judged coordinates (module docstring)."""
    a = np.linalg.pinv(np.asarray(fit.jac, dtype=float))[:n_coords] ** 2  # (n, m)
    total = a.sum(axis=1)
    rho = np.ones(n_coords)
    for t in goodness.tests:
        share = a[:, _group_rows(space, t.run, t.channels)].sum(axis=1)
        rho += (max(1.0, t.ratio) - 1.0) * share / np.where(total > 0, total, 1.0)
    return rho


def scaled_for_misfit(verdict: Verdict, rho: float) -> Verdict:
    """`verdict` with its standard error and interval scaled for the misfit `rho` (module
    docstring); the factor and the unscaled error in its evidence (`misfit_scale`,
    `std_error_before_misfit_scale`)."""
    se, ev = verdict.std_error, verdict.evidence
    if not math.isfinite(se) or se <= 0:
        return verdict
    se_0 = math.hypot(ev.get("std_error_residuals", se), ev.get("std_error_track_record", 0.0))
    factor = max(1.0, math.sqrt(rho) * se_0 / se)
    lo, hi = verdict.ci95
    est = verdict.estimate
    ci95 = (est - (est - lo) * factor, est + (hi - est) * factor)
    evidence = dict(ev, misfit_scale=float(rho), std_error_before_misfit_scale=float(se))
    if "watch" in evidence:  # an interval outside the band: still outside once widened?
        side = interval_outside(ci95, verdict.band.healthy)
        evidence.pop("watch") if side is None else evidence.update(watch=side)
    return dataclasses.replace(verdict, std_error=se * factor, ci95=ci95, evidence=evidence)
