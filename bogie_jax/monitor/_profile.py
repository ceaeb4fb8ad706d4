"""The profile likelihood-ratio test of one element at a limit of its band.

A Wald interval (estimate +- z standard errors) depends on the coordinate it is drawn in: in p
a damper estimated near zero gets a tight interval, in ln p (the fitted coordinate) a huge one,
and an element estimated far outside its band with a wide interval cannot be judged by it at
all. The likelihood-ratio test does not depend on the coordinate: the fit is repeated with the
element held at the limit (every other coordinate, nuisance included, fitted again), and

    LR = 2 (S_limit - S_min) / sigma^2,        S = 1/2 |r|^2 in the fit's weights,

is chi^2 with one degree of freedom when the element's true value is the limit (Wilks 1938;
Bates & Watts, "Nonlinear regression analysis and its applications", 1988, sec. 6.1). Where
the misfit is autocorrelated in time or differs between channels, the statistic is divided by
c = var_sandwich / var_Gauss-Newton of the element (Kent, Biometrika 69 (1982) 19, for one
parameter of interest), so that it is as long-tailed as the sandwich covariance says. The
signed root sqrt(LR / c) is compared with the decision z (`_verdict.judge`): the element lies
beyond the limit, at the level the false-alarm rate sets, when it exceeds z.

Cost: one Levenberg-Marquardt fit from the unconstrained optimum (moved along the linearised
profile to the limit), on the same compiled program: no compile, a few Jacobian evaluations.
"""

import dataclasses
import math

import numpy as np

from ..identify import HostFit, levenberg_marquardt


@dataclasses.dataclass(frozen=True)
class ProfilePoint:
    """The fit with coordinate `index` held at `phi_limit` (ln of limit / nominal): its
    `cost` (1/2 |r|^2 in the unconstrained fit's weights), LM `status` and `steps`, and the
    signed root `statistic` sqrt(max(LR / c, 0)) (NaN when the fit failed)."""

    index: int
    phi_limit: float
    cost: float
    status: str
    steps: int
    statistic: float

    def to_dict(self) -> dict:
        return {
            "statistic": self.statistic,
            "cost": self.cost,
            "status": self.status,
            "steps": self.steps,
        }


def profile_point(
    evaluate, fit, index: int, phi_limit: float, *, sigma2: float, variance_ratio: float,
    max_steps: int = 30,
) -> ProfilePoint:  # fmt: skip
    """The profile test of coordinate `index` of `fit` (a `HostFit` of `evaluate`) at
    `phi_limit` (module docstring). `sigma2`: the residual variance of the fit's weighted
    residuals; `variance_ratio` c >= 1: the element's sandwich over Gauss-Newton variance
    (1 for the Gauss-Newton covariance)."""
    phi_limit = float(phi_limit)
    keep = np.delete(np.arange(fit.phi.size), index)
    shift = phi_limit - fit.phi[index]
    j_other, j_held = fit.jac[:, keep], fit.jac[:, index]
    # start on the linearised profile: the others' Gauss-Newton response to the held shift
    start = fit.phi[keep] - np.linalg.lstsq(j_other, j_held * shift, rcond=None)[0]

    def held(u):
        r, jac = evaluate(np.insert(u, index, phi_limit))
        return r, jac[:, keep]

    if keep.size == 0:  # the element is the only fitted coordinate
        r, _ = evaluate(np.array([phi_limit]))
        cost = 0.5 * float(r @ r)
        refit = HostFit(start, r, np.zeros((r.size, 0)), cost, 0, 1, "converged")
    else:
        refit = levenberg_marquardt(held, start, max_steps=max_steps)
    if refit.status == "failed" or not math.isfinite(refit.cost):
        statistic = float("nan")
    else:
        lr = 2.0 * (refit.cost - fit.cost) / (sigma2 * max(variance_ratio, 1.0))
        statistic = math.sqrt(max(lr, 0.0))
    return ProfilePoint(index, phi_limit, refit.cost, refit.status, refit.steps, statistic)
