"""Levenberg-Marquardt on the host, driven by one compiled residual-Jacobian program.

`monitor` evaluates the Fisher information and fits with the same compiled program (residuals
and their forward-mode Jacobian with respect to ln p of every candidate), so a monitoring run
compiles one simulation program instead of two (the Fisher information's Jacobian and a fit's
LM loop; about 50 s of compile each on 2 CPU cores). The fitted coordinates phi are linear
combinations of the candidates' ln p (theta = A phi: an element alone, or a group moving by one
factor), and their Jacobian is J A. Each step solves the damped normal equations

    (A^T J^T J A + lambda diag(A^T J^T J A)) delta = -A^T J^T r

(Marquardt 1963) by least squares on the stacked system, with Nielsen's update of lambda
(Madsen, Nielsen & Tingleff, "Methods for non-linear least squares problems", 2004, sec. 3.2).

Convergence is statistical as well as numerical: the fit stops when the Gauss-Newton step from
the current point, or a rejected damped step, promises a cost decrease below `cost_tol` (1e-4,
in the units of residuals scaled by the sensors' noise: the estimates are then within about
0.015 standard errors of the optimum when the model explains the data to that noise), or when
the Bates-Watts relative offset

    RO = sqrt(|J delta_GN|^2 / n) / sqrt((|r|^2 - |J delta_GN|^2) / (m - n))

falls below `offset_tol` (1e-2: the step still to take is under 0.01 sqrt(n) standard errors of
the estimates as the residuals themselves measure them; Bates & Watts, Technometrics 23 (1981)
179; the rule of `bogie_jax.identify.LevenbergMarquardt`). The second rule keeps the first's
meaning where the misfit is many times the sensors' noise (an imperfect track record), and
both keep the jitter of
the cost that the ODE solver's own tolerance causes (rtol 1e-6) from costing a series of
rejected steps.
"""

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class HostFit:
    """Outcome of `levenberg_marquardt`: `phi`, residuals `r` and Jacobian `jac` (in phi) at
    `phi`, `cost` = 1/2 |r|^2, `steps` (accepted and rejected), `evaluations`, `status`
    (`converged`, `max_steps` or `failed`), `costs`: the cost after each accepted step."""

    phi: np.ndarray
    r: np.ndarray
    jac: np.ndarray
    cost: float
    steps: int
    evaluations: int
    status: str
    costs: tuple[float, ...] = ()


DAMPING = 1e-3  # the initial lambda: the damping matrix is lambda diag(J^T J) (Marquardt)


def levenberg_marquardt(
    evaluate,
    phi0,
    *,
    max_steps: int = 30,
    xtol: float = 1e-8,
    ftol: float = 1e-12,
    cost_tol: float = 1e-4,
    offset_tol: float = 1e-2,
    max_step: float = 1.0,
) -> HostFit:
    """Minimise 1/2 |r(phi)|^2 with `evaluate(phi) -> (r, J)` (numpy arrays).

    Stops when the largest step component is below `xtol` (in ln p: 1e-8 relative), the cost
    falls by less than `ftol` times itself, or the Gauss-Newton step promises a decrease below
    `cost_tol` or has a relative offset below `offset_tol` (module docstring; 0 turns a rule
    off); `max_step` bounds each step's largest component (ln p: a factor e). A non-finite
    cost at a trial point counts as a rejected step.
    """
    phi = np.asarray(phi0, dtype=float)
    r, jac = evaluate(phi)
    evaluations, cost = 1, 0.5 * float(r @ r)
    if not np.isfinite(cost) or not np.all(np.isfinite(jac)):
        return HostFit(phi, r, jac, cost, 0, evaluations, "failed")
    lam, nu, costs = DAMPING, 2.0, [cost]
    done = lambda step, status: HostFit(phi, r, jac, cost, step, evaluations, status, tuple(costs))
    for step in range(1, max_steps + 1):
        if _gauss_newton_done(r, jac, cost, cost_tol, offset_tol):
            return done(step - 1, "converged")
        delta, predicted = _damped_step(r, jac, lam, max_step)
        r_new, jac_new = evaluate(phi + delta)
        evaluations += 1
        cost_new = 0.5 * float(r_new @ r_new)
        rho = (cost - cost_new) / predicted if predicted > 0 else -1.0
        if np.isfinite(cost_new) and np.all(np.isfinite(jac_new)) and rho > 0:
            decrease = cost - cost_new
            phi, r, jac, cost = phi + delta, r_new, jac_new, cost_new
            costs.append(cost)
            lam, nu = lam * max(1 / 3, 1 - (2 * rho - 1) ** 3), 2.0
            if float(np.max(np.abs(delta))) < xtol or decrease <= ftol * cost:
                return done(step, "converged")
        else:
            lam, nu = lam * nu, nu * 2.0
            if float(np.max(np.abs(delta))) < xtol or predicted < cost_tol:
                return done(step, "converged")
    return done(max_steps, "max_steps")


def _gauss_newton_done(r, jac, cost, cost_tol, offset_tol) -> bool:
    """Whether the Gauss-Newton step from here promises a decrease below `cost_tol` or has a
    relative offset below `offset_tol`."""
    gauss_newton = np.linalg.lstsq(jac, -r, rcond=None)[0]
    explained = float(np.sum((jac @ gauss_newton) ** 2))  # |Q1^T r|^2
    offset = _relative_offset(explained, 2 * cost, r.size, jac.shape[1])
    return 0.5 * explained < cost_tol or offset < offset_tol


def _damped_step(r, jac, lam, max_step):
    """The damped step (least squares on the stacked system), its largest component at most
    `max_step`, and the decrease its linear model predicts."""
    d = np.sqrt(np.maximum(np.diag(jac.T @ jac), 1e-300))
    aug = np.vstack([jac, np.sqrt(lam) * np.diag(d)])
    delta = np.linalg.lstsq(aug, np.concatenate([-r, np.zeros(d.size)]), rcond=None)[0]
    biggest = float(np.max(np.abs(delta)))
    if biggest > max_step:
        delta *= max_step / biggest
    return delta, 0.5 * float(delta @ (lam * d**2 * delta - jac.T @ r))


def _relative_offset(explained: float, total: float, m: int, n: int) -> float:
    """sqrt(explained / n) / sqrt((total - explained) / (m - n)); inf where undefined."""
    rest = total - explained
    if m <= n or n == 0 or not rest > 0:
        return float("inf")
    return float(np.sqrt((explained / n) / (rest / (m - n))))
