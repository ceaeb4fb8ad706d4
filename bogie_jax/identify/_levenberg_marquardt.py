"""Levenberg-Marquardt on the host for a batch of fits, each evaluation one call of the caller's
compiled residual-Jacobian program.

Every fit minimises 1/2 |r(phi)|^2. `evaluate(points, members) -> (r, J, free)` gives the
residuals (k, m), their Jacobians (k, m, n) and optionally (k, n) flags of the parameters that
count as free (`None`: all) at the k points of a batch, in one call of one compiled program:
`identify` vmaps its residual Jacobian over its fits (`_lm_fits.py`), `monitor` evaluates its
joint program in reparametrised coordinates. No optimiser loop is compiled beside that program
(a second simulation program of the same size: measured in docs/history.md). A batch of N fits
runs `width` at a time; a fit that ends hands its place to the next start (a queue: no fit waits
for a slower one to end, only each evaluation for its slowest member).

**Step.** The damped normal equations

    (J^T J + lambda diag(J^T J)) delta = -J^T r

(Marquardt 1963, "An algorithm for least-squares estimation of nonlinear parameters", SIAM J.
Appl. Math. 11, 431-441), solved as least squares on the stacked system [J; sqrt(lambda) D],
over the free parameters (the others stay where they are), the step's largest component at
most `max_step`. The gain ratio rho = (actual decrease) / (decrease the linear model
predicts) accepts the step when rho > 0 and updates lambda by Nielsen's rule:
lambda max(1/3, 1 - (2 rho - 1)^3) on acceptance, else lambda nu with nu doubling (Madsen,
Nielsen & Tingleff, "Methods for non-linear least squares problems", 2004, sec. 3.2). A trial
point whose residuals or Jacobian are not finite is a rejected step.

**Stopping** (`LevenbergMarquardt`; a tolerance of 0 turns its rule off). A fit has converged
when, at its current point,

- the Bates-Watts **relative offset** is below `offset_tol`: with the Gauss-Newton step d from
  here over the free parameters (k of them, m residuals),

      RO = sqrt(|J d|^2 / k) / sqrt((|r|^2 - |J d|^2) / (m - k))

  (Bates & Watts 1981, "A relative offset orthogonality convergence criterion for nonlinear
  least squares", Technometrics 23, 179-183; Bates & Watts 1988, *Nonlinear Regression Analysis
  and Its Applications*, 2.2.3). `|J d|^2 / (|r|^2 - |J d|^2) (m - k)` compares the decrease
  still to gain with the noise variance s^2 the residuals estimate, so RO sqrt(k) is the
  remaining step in joint standard errors of the estimates: RO < 0.01 means the estimate would
  move by less than 0.01 sqrt(k) of them. It is scale-free. A parameter held on a bound (the
  evaluation's `free` flag) is left out, as a constrained optimum's first-order conditions
  leave it out: a logistic transform flattens there and the residual keeps a component along
  its vanishing column, so the offset over all columns would not fall while the fit crawls
  towards the bound;
- the Gauss-Newton step promises a decrease below `cost_tol` (in residuals scaled by the
  sensors' noise, 1e-4 puts the estimates within about 0.015 standard errors of the optimum);
- it is **stalled** at its objective's own error: `stall_steps` steps in a row were rejected at
  an offset below `stall_offset`. Near the optimum of a smooth problem the Gauss-Newton model
  predicts the decrease well and its steps are accepted; repeated rejections there mean that
  the objective's error (an ODE solver's adaptive steps move with the parameters) is larger
  than the decrease the model promises, and the fit ends within `stall_offset` sqrt(k)
  standard errors of the optimum;
- the last step's largest component was below `xtol`, an accepted step decreased the cost by
  at most `ftol` times the cost, or a rejected step promised a decrease below `cost_tol`.

It ends with `max_steps` after that many steps (accepted and rejected) and `failed` where the
residuals or Jacobian at its start are not finite.
"""

import dataclasses
import math
from collections.abc import Callable

import equinox as eqx
import numpy as np

from .._validation import check_number, check_positive_int


DAMPING = 1e-3  # the initial lambda: the damping matrix is lambda diag(J^T J) (Marquardt)


class LevenbergMarquardt(eqx.Module):
    """The Levenberg-Marquardt method and its stopping rules (module docstring), for
    `bogie_jax.identify`'s fits and `monitor`'s.

    - `offset_tol`, `stall_offset`, `stall_steps`: the relative-offset and stall rules;
    - `cost_tol`: the Gauss-Newton decrease rule (absolute: residuals scaled by their noise);
    - `xtol`, `ftol`: the step and relative-decrease rules;
    - `max_step`: the largest component of a step (`None`: unbounded); in log or logit
      coordinates 1 is a factor e, and it keeps a Gauss-Newton step from an ill-determined
      start from throwing a parameter onto the flat end of a logistic map;
    - `bound_tol`: a parameter within this fraction of its box width of a bound is held there
      (left out of the step and the offset) by `identify`'s evaluation.

    **Raises:** `ValueError` naming a field outside its range."""

    offset_tol: float = 1e-2
    cost_tol: float = 0.0
    xtol: float = 1e-10
    ftol: float = 1e-12
    stall_offset: float = 0.1
    stall_steps: int = 5
    max_step: float | None = 1.0
    bound_tol: float = 1e-6

    def __check_init__(self):
        for name in ("offset_tol", "cost_tol", "xtol", "ftol", "stall_offset"):
            check_number(name, getattr(self, name), 0.0, math.inf)
        check_positive_int("stall_steps", self.stall_steps)
        if self.max_step is not None:
            check_number("max_step", self.max_step, 0.0, math.inf, open_lo=True)
        check_number("bound_tol", self.bound_tol, 0.0, 0.5)


@dataclasses.dataclass(frozen=True)
class HostFit:
    """Outcome of one Levenberg-Marquardt fit: `phi`, residuals `r` and Jacobian `jac` at
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


@dataclasses.dataclass(frozen=True)
class _Member:
    """One fit between evaluations: the start's `index`, its point `phi` with `r`, `jac`,
    `cost` there, the `point` to evaluate next (the start, or phi + the damped step `delta`
    that promises `predicted`), Nielsen's `lam` and `nu`, the counts and the `status`."""

    index: int
    phi: np.ndarray
    point: np.ndarray
    r: np.ndarray | None = None
    jac: np.ndarray | None = None
    cost: float = math.inf
    delta: np.ndarray | None = None
    predicted: float = 0.0
    lam: float = DAMPING
    nu: float = 2.0
    steps: int = 0
    rejected: int = 0  # steps rejected in a row
    evaluations: int = 0
    costs: tuple[float, ...] = ()
    status: str = "running"


def levenberg_marquardt_batch(
    evaluate: Callable,
    starts,
    method: LevenbergMarquardt = LevenbergMarquardt(),
    *,
    max_steps: int = 100,
    width: int | None = None,
) -> list[HostFit]:
    """Fit from each of `starts` (N, n) with `evaluate(points, members) -> (r, J, free)`
    (module docstring; `points` (width, n), `members` (width,) the starts' indices, a slot
    without a fit repeating another's point), `width` fits at a time (default all).

    **Returns:** one `HostFit` per start, in order."""
    starts = np.atleast_2d(np.asarray(starts, dtype=float))
    n_starts = starts.shape[0]
    width = n_starts if width is None else max(1, min(int(width), n_starts))
    check_positive_int("max_steps", max_steps, lo=0)
    queue = iter(range(width, n_starts))
    slots = [_Member(i, starts[i], starts[i]) for i in range(width)]
    fits: list[HostFit | None] = [None] * n_starts
    while any(s is not None for s in slots):
        live = next(s for s in slots if s is not None)
        points = np.stack([(s or live).point for s in slots])
        members = np.array([(s or live).index for s in slots])
        r, jac, free = evaluate(points, members)
        for k, member in enumerate(slots):
            if member is None:
                continue
            free_k = None if free is None else np.asarray(free[k], bool)
            member = _absorb(member, np.asarray(r[k]), np.asarray(jac[k]), free_k, method)
            if member.status == "running":
                member = _plan(member, free_k, method, max_steps)
            if member.status != "running":
                fits[member.index] = _host_fit(member)
                i = next(queue, None)
                member = None if i is None else _Member(i, starts[i], starts[i])
            slots[k] = member
    return fits


def levenberg_marquardt(
    evaluate: Callable,
    phi0,
    *,
    max_steps: int = 30,
    xtol: float = 1e-8,
    ftol: float = 1e-12,
    cost_tol: float = 1e-4,
    offset_tol: float = 1e-2,
    max_step: float | None = 1.0,
) -> HostFit:
    """One fit from `phi0` with `evaluate(phi) -> (r, J)` (numpy arrays): a batch of one of
    `levenberg_marquardt_batch` with these tolerances and no stall rule (`monitor`'s fits;
    `max_step`: a factor e in ln p)."""
    method = LevenbergMarquardt(
        offset_tol=offset_tol, cost_tol=cost_tol, xtol=xtol, ftol=ftol, stall_offset=0.0,
        max_step=max_step,
    )  # fmt: skip

    def batch(points, members):
        del members
        r, jac = evaluate(points[0])
        return np.asarray(r)[None], np.asarray(jac)[None], None

    return levenberg_marquardt_batch(batch, [phi0], method, max_steps=max_steps)[0]


def _finite(r, jac) -> bool:
    return bool(np.all(np.isfinite(r)) and np.all(np.isfinite(jac)))


def _absorb(m: _Member, r, jac, free, method: LevenbergMarquardt) -> _Member:
    """`m` after the evaluation of its `point`: the start taken (or failed), or the step
    accepted or rejected (Nielsen's update) and the step rules applied."""
    count = dict(evaluations=m.evaluations + 1)
    cost = 0.5 * float(r @ r) if np.all(np.isfinite(r)) else math.inf
    if m.evaluations == 0:
        status = "running" if _finite(r, jac) else "failed"
        costs = (cost,) if status == "running" else ()
        return dataclasses.replace(m, r=r, jac=jac, cost=cost, costs=costs, status=status, **count)
    small = float(np.max(np.abs(m.delta))) < method.xtol
    rho = (m.cost - cost) / m.predicted if m.predicted > 0 else -1.0
    if _finite(r, jac) and rho > 0:
        decrease = m.cost - cost
        lam = m.lam * max(1 / 3, 1 - (2 * rho - 1) ** 3)
        done = small or decrease <= method.ftol * cost
        return dataclasses.replace(
            m, phi=m.point, r=r, jac=jac, cost=cost, costs=m.costs + (cost,), lam=lam, nu=2.0,
            steps=m.steps + 1, rejected=0, status="converged" if done else "running", **count,
        )  # fmt: skip
    done = small or m.predicted < method.cost_tol
    return dataclasses.replace(
        m, lam=m.lam * m.nu, nu=2.0 * m.nu, steps=m.steps + 1, rejected=m.rejected + 1,
        status="converged" if done else "running", **count,
    )  # fmt: skip


def _plan(m: _Member, free, method: LevenbergMarquardt, max_steps: int) -> _Member:
    """`m` converged by a Gauss-Newton rule (the offset, stall or cost rule) at its point, out of
    steps, or with its next trial point (the damped step)."""
    explained = _explained(m.jac, m.r, free)
    k = m.jac.shape[1] if free is None else int(np.sum(free))
    offset = _offset(explained, 2.0 * m.cost, m.r.size, k)
    stalled = m.rejected >= method.stall_steps and offset < method.stall_offset
    if offset < method.offset_tol or 0.5 * explained < method.cost_tol or stalled:
        return dataclasses.replace(m, status="converged")
    if m.steps >= max_steps:
        return dataclasses.replace(m, status="max_steps")
    delta, predicted = _damped_step(m.r, m.jac, m.lam, method.max_step, free)
    return dataclasses.replace(m, point=m.phi + delta, delta=delta, predicted=predicted)


def _host_fit(m: _Member) -> HostFit:
    r = np.full(0, np.nan) if m.r is None else m.r
    jac = np.full((r.size, m.phi.size), np.nan) if m.jac is None else m.jac
    return HostFit(m.phi, r, jac, m.cost, m.steps, m.evaluations, m.status, m.costs)


def _explained(jac, r, free) -> float:
    """|J d|^2 = |Q1^T r|^2 for the Gauss-Newton step d over the `free` columns."""
    columns = jac if free is None else jac[:, free]
    if columns.shape[1] == 0:
        return 0.0
    step = np.linalg.lstsq(columns, -r, rcond=None)[0]
    return float(np.sum((columns @ step) ** 2))


def _offset(explained: float, total: float, m: int, k: int) -> float:
    """sqrt(explained / k) / sqrt((total - explained) / (m - k)); 0 without a free parameter,
    inf where no residual is left outside the tangent plane (or m <= k)."""
    if k == 0:
        return 0.0
    rest = total - explained
    if m <= k or not rest > 0:
        return math.inf
    return math.sqrt((explained / k) / (rest / (m - k)))


def relative_offset(jac, residual, free=None) -> float:
    """The Bates-Watts relative offset (module docstring) of residuals `residual` (m,) with
    Jacobian `jac` (m, n), over the columns marked `free` (n,) (default: all)."""
    jac = np.asarray(jac, dtype=float)
    r = np.ravel(np.asarray(residual, dtype=float))
    free = None if free is None else np.asarray(free, bool)
    k = jac.shape[1] if free is None else int(np.sum(free))
    return _offset(_explained(jac, r, free), float(r @ r), r.size, k)


def _damped_step(r, jac, lam, max_step, free=None):
    """The damped step (least squares on the stacked system) in the `free` columns (default
    all; the others stay), its largest component at most `max_step` (`None`: unbounded), and
    the decrease its linear model predicts."""
    if free is not None and not free.all():
        step, predicted = _damped_step(r, jac[:, free], lam, max_step)
        delta = np.zeros(jac.shape[1])
        delta[free] = step
        return delta, predicted
    d = np.sqrt(np.maximum(np.diag(jac.T @ jac), 1e-300))
    aug = np.vstack([jac, np.sqrt(lam) * np.diag(d)])
    delta = np.linalg.lstsq(aug, np.concatenate([-r, np.zeros(d.size)]), rcond=None)[0]
    biggest = float(np.max(np.abs(delta), initial=0.0))
    if max_step is not None and biggest > max_step:
        delta *= max_step / biggest
    return delta, 0.5 * float(delta @ (lam * d**2 * delta - jac.T @ r))
