# long: Fisher information and profile likelihood are one analysis (shared names, bounds, helpers).
"""Local and profile identifiability of a least-squares problem (paper section 4.2).

With residuals weighted by 1/sigma (the default weights of `bogie_jax.cost`), J = 1/2 |r|^2 is the
negative log-likelihood up to a constant and the Fisher information is F = J_r^T J_r, J_r the
residual Jacobian. It is reported in physical units (dr/dp) and in relative scaling
(dr/d ln p, so that parameters of different units compare), with its eigen-decomposition, the
covariance F^+ (pseudo-inverse by `bogie_jax.cost.covariance_from_jacobian`, the computation
fits use; unidentifiable directions reported, not inverted), correlations and the collinearity
indices of Brun, Reichert and Kuensch (2001), "Practical identifiability analysis of large
environmental simulation models", Water Resources Research 37(4), 1015-1030:
gamma_K = 1 / sqrt(min eig(S_K^T S_K)) for the
column-normalised sensitivity sub-matrix S_K of each parameter subset K (gamma > 10-15: poorly
identifiable subset; infinite: exactly collinear).

Profile likelihood (Raue et al. 2009): for each parameter, fix it on a grid over its bounds and
re-fit the others (Levenberg-Marquardt, warm-started at the estimate); the 95 % interval is
where Delta J <= chi2_1(0.95) / 2 = 1.92, interpolated on the signed root
sign(p - p_min) sqrt(Delta J), which is exactly linear for a linear-Gaussian problem.
"""

import itertools
import math
from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from ..cost import Covariance, covariance_from_jacobian, residual_jacobian
from ..identify import LeastSquaresProblem, LevenbergMarquardt, LMFits, as_problem


CHI2_1_95 = 3.841458820694124  # chi2 quantile, 1 degree of freedom, 0.95
PROFILE_THRESHOLD = 0.5 * CHI2_1_95  # Delta J for a 95 % interval with J = 1/2 |r|^2


# --------------------------------------------------------------------------------------------
# Fisher information
# --------------------------------------------------------------------------------------------


class CollinearityIndices(eqx.Module):
    """Brun et al. (2001) collinearity indices of parameter subsets.

    **Fields:**
    - `names`: all parameter names.
    - `subsets`: the subsets (tuples of names), by size then order of `names`.
    - `index`: `(n_subsets,)` gamma_K (inf for exactly collinear columns).
    - `importance`: `(n,)` delta_msqr = |s_j| / sqrt(m) of each relative-sensitivity column.
    """

    names: tuple[str, ...] = eqx.field(static=True)
    subsets: tuple[tuple[str, ...], ...] = eqx.field(static=True)
    index: Float[Array, " k"]
    importance: Float[Array, " n"]

    def worst(self, size: int | None = None, count: int = 5) -> list[tuple[tuple[str, ...], float]]:
        """The `count` subsets (of `size` parameters, default any) with the largest index."""
        gamma = np.asarray(self.index)
        rows = [
            (s, float(g)) for s, g in zip(self.subsets, gamma) if size is None or len(s) == size
        ]
        return sorted(rows, key=lambda t: -t[1])[:count]


class ParameterCombination(eqx.Module):
    """A direction in relative parameter space (d ln p) that the data barely constrain.

    - `eigenvalue`: its Fisher information (relative scaling);
    - `relative_std`: 1 / sqrt(eigenvalue), the standard deviation of the combination
      sum_i v_i ln p_i (0.1 = about 10 %; inf for an exact collinearity);
    - `vector`: `(n,)` unit eigenvector;
    - `names`: the parameters (static: the labels of `vector`);
    - `dominant` (property): names of the parameters that make up most of it (largest |v_i|,
      covering 90 % of |v|^2); `description` (property): e.g.
      `+0.71 ln primary.kz -0.70 ln primary.ky (relative std 35 %)`.
    """

    eigenvalue: Float[Array, ""]
    relative_std: Float[Array, ""]
    vector: Float[Array, " n"]
    names: tuple[str, ...] = eqx.field(static=True)

    @property
    def dominant(self) -> tuple[str, ...]:
        return _describe(self.vector, self.names, float(self.eigenvalue))[0]

    @property
    def description(self) -> str:
        return _describe(self.vector, self.names, float(self.eigenvalue))[2]


class FisherInformation(eqx.Module):
    """Local identifiability at one parameter point.

    **Fields:**
    - `names`, `units`: parameters; `values`: `(n,)` physical values at the point.
    - `fim`: `(n, n)` F = J_p^T J_p in physical units (dr/dp).
    - `fim_relative`: `(n, n)` F_rel = diag(p) F diag(p) (dr/d ln p, dimensionless).
    - `eigenvalues`, `eigenvectors`: of `fim_relative`, eigenvalues ascending, vectors in columns.
    - `covariance`: `(n, n)` F^+ in physical units (the Cramer-Rao bound with 1/sigma^2
      weights; pseudo-inverse taken in relative scaling); `std_errors` (inf for a parameter in
      the null space of F), `relative_std_errors` (std / |p|); `correlation`.
    - `condition_number`: largest / smallest eigenvalue of `fim_relative` (inf if singular).
    - `uncertainty`: the `Covariance` (in relative scaling: `rank`, `null` directions).
    - `collinearity`: `CollinearityIndices`.
    - `max_relative_std`: the threshold of `inseparable` (property): the
      `ParameterCombination`s whose relative std exceeds it (eigenvalues counted as zero by
      `uncertainty.null` have infinite relative std).

    Every field is fixed in structure by the parameter names: results at different points share
    one tree structure (no recompilation of a function that takes them).
    """

    names: tuple[str, ...] = eqx.field(static=True)
    units: tuple[str, ...] = eqx.field(static=True)
    values: Float[Array, " n"]
    fim: Float[Array, "n n"]
    fim_relative: Float[Array, "n n"]
    eigenvalues: Float[Array, " n"]
    eigenvectors: Float[Array, "n n"]
    covariance: Float[Array, "n n"]
    std_errors: Float[Array, " n"]
    relative_std_errors: Float[Array, " n"]
    correlation: Float[Array, "n n"]
    condition_number: Float[Array, ""]
    uncertainty: Covariance
    collinearity: CollinearityIndices
    max_relative_std: Float[Array, ""]

    @property
    def inseparable(self) -> tuple[ParameterCombination, ...]:
        w, v = np.asarray(self.eigenvalues), np.asarray(self.eigenvectors)
        zero = np.asarray(self.uncertainty.null)
        out = []
        for k in range(w.size):
            lam = 0.0 if zero[k] else float(w[k])
            _, rstd, _ = _describe(v[:, k], self.names, lam)
            if rstd > float(self.max_relative_std):
                out.append(
                    ParameterCombination(np.asarray(lam), np.asarray(rstd), v[:, k], self.names)
                )
        return tuple(out)

    def summary(self) -> list[str]:
        """Readable lines: the combinations the measurements cannot separate."""
        if not self.inseparable:
            return ["every parameter combination is identifiable at this point"]
        return [c.description for c in self.inseparable]


def collinearity_indices(
    sensitivity, names: Sequence[str], max_size: int | None = 3
) -> CollinearityIndices:
    """Brun et al. (2001) indices for every subset of 2 .. `max_size` columns of `sensitivity`
    `(m, n)` (the columns are normalised to unit length first, so any column scaling cancels).
    A zero column counts as collinear with everything (infinite index)."""
    s = np.asarray(sensitivity, dtype=float)
    m, n = s.shape
    names = tuple(names)
    norms = np.linalg.norm(s, axis=0)
    unit = s / np.where(norms > 0, norms, 1.0)
    gram = unit.T @ unit
    max_size = n if max_size is None else min(int(max_size), n)
    subsets, gammas = [], []
    eps = 1e3 * np.finfo(float).eps
    for k in range(2, max_size + 1):
        for idx in itertools.combinations(range(n), k):
            idx = list(idx)
            if np.any(norms[idx] == 0):
                gamma = math.inf
            else:
                lam = float(np.linalg.eigvalsh(gram[np.ix_(idx, idx)])[0])
                gamma = math.inf if lam <= eps else 1.0 / math.sqrt(lam)
            subsets.append(tuple(names[i] for i in idx))
            gammas.append(gamma)
    return CollinearityIndices(
        names=names,
        subsets=tuple(subsets),
        index=np.asarray(gammas, dtype=float),
        importance=norms / math.sqrt(m),
    )


def _describe(vector, names, eigenvalue) -> tuple[tuple[str, ...], float, str]:
    v = np.asarray(vector, dtype=float)
    order = np.argsort(-np.abs(v))
    if v[order[0]] < 0:
        v = -v
    cum = np.cumsum(v[order] ** 2)
    k = int(np.searchsorted(cum, 0.9) + 1)
    dominant = tuple(names[i] for i in order[:k])
    std = math.inf if eigenvalue <= 0 else 1.0 / math.sqrt(eigenvalue)
    terms = " ".join(f"{v[i]:+.2f} ln {names[i]}" for i in order[:k])
    std_text = "inf (exactly collinear)" if not np.isfinite(std) else f"{100 * std:.3g} %"
    return dominant, std, f"{terms} (relative std {std_text})"


def fisher_from_jacobian(
    jacobian,
    values,
    names: Sequence[str] | None = None,
    units: Sequence[str] | None = None,
    *,
    max_subset_size: int | None = 3,
    max_relative_std: float = 0.1,
    rcond: float = 1e-12,
) -> FisherInformation:
    """`FisherInformation` from the weighted residual Jacobian `(m, n)` with respect to the
    physical parameters (dr/dp) at physical `values` `(n,)` (non-zero for the relative scaling).

    **Arguments:** `max_subset_size`: largest subset for the collinearity indices;
    `max_relative_std`: a combination with a larger relative std (1 / sqrt(eigenvalue)) is listed
    as inseparable; `rcond`: eigenvalues below `rcond` * largest are treated as zero in the
    pseudo-inverse.
    """
    jac = np.asarray(jacobian, dtype=float)
    p = np.asarray(values, dtype=float)
    if jac.ndim != 2 or p.shape != (jac.shape[1],):
        raise ValueError(f"need a (m, n) Jacobian and (n,) values, got {jac.shape} and {p.shape}")
    n = p.size
    names = tuple(names) if names is not None else tuple(f"p{i}" for i in range(n))
    units = tuple(units) if units is not None else ("",) * n
    if not np.all(np.isfinite(jac)):
        raise ValueError("the residual Jacobian is not finite (did the solve fail?)")
    fim = jac.T @ jac
    rel_jac = jac * p[None, :]
    fim_rel = rel_jac.T @ rel_jac
    # Covariance in relative scaling (d ln p; d p where p = 0), so that units of very different
    # size (N/m against N s/m) do not decide which eigenvalues count as zero; then physical.
    scale = np.where(p != 0, p, 1.0)
    unc = covariance_from_jacobian(jac * scale[None, :], rcond=rcond, scale=scale)
    w, v = np.asarray(unc.eigenvalues), np.asarray(unc.directions)
    cov, std, corr = (np.asarray(a) for a in (unc.covariance, unc.std_errors, unc.correlation))
    return FisherInformation(
        names=names,
        units=units,
        values=p,
        fim=fim,
        fim_relative=fim_rel,
        eigenvalues=w,
        eigenvectors=v,
        covariance=cov,
        std_errors=std,
        relative_std_errors=np.where(p != 0, std / np.where(p != 0, np.abs(p), 1.0), np.inf),
        correlation=corr,
        condition_number=np.asarray(unc.condition_number),
        uncertainty=unc,
        collinearity=collinearity_indices(rel_jac, names, max_subset_size),
        max_relative_std=np.asarray(float(max_relative_std)),
    )


@eqx.filter_jit
def physical_jacobian(problem, theta):
    """`(J, p)`: the residual Jacobian with respect to the physical parameters (m, n) and their
    values p (n,) at `theta`, for a `LeastSquaresProblem` (`bogie_jax.identify.as_problem`)."""
    _, jac_theta = residual_jacobian(problem, theta, problem.args)
    # The transforms are element-wise: dp/dtheta is diagonal.
    values, d = jax.jvp(problem.transform.to_physical, (theta,), (jnp.ones_like(theta),))
    return jac_theta / d[None, :], values


def fisher_information(
    problem,
    theta=None,
    *,
    physical=None,
    max_subset_size: int | None = 3,
    max_relative_std: float = 0.1,
    rcond: float = 1e-12,
) -> FisherInformation:
    """Fisher information of `problem` (an `Objective` or a `LeastSquaresProblem`) at `theta`
    (unconstrained coordinates) or at `physical` values (default: the selection's nominal values,
    i.e. theta = 0 for an `Objective`).

    The Jacobian is `bogie_jax.cost.residual_jacobian` (forward mode, switched on by itself for
    an `Objective`). The FIM equals the inverse covariance only with 1/sigma^2 weights (the
    default of `make_objective`). Other arguments as `fisher_from_jacobian`.
    """
    lsq = as_problem(problem)
    transform = lsq.transform
    names = getattr(transform, "names", None)
    units = getattr(transform, "units", None)
    if theta is None:
        if physical is None:
            physical = getattr(transform, "nominal")
        theta = transform.to_theta(jnp.asarray(physical, dtype=float))
    theta = jnp.atleast_1d(jnp.asarray(theta, dtype=float))
    jac, values = physical_jacobian(lsq, theta)
    return fisher_from_jacobian(
        jac,
        values,
        names,
        units,
        max_subset_size=max_subset_size,
        max_relative_std=max_relative_std,
        rcond=rcond,
    )


# --------------------------------------------------------------------------------------------
# Profile likelihood
# --------------------------------------------------------------------------------------------


class ProfileLikelihood(eqx.Module):
    """Profiles of J = 1/2 |r|^2, one row per parameter (physical units).

    **Fields:**
    - `names`, `units`: the profiled parameters; `indices`: their positions among all `n`;
      `estimate`: `(n,)` the best fit (all parameters); `cost_min`: its J (the reference of
      Delta J: the smallest of the fit and every profile point).
    - `values`: `(n, k)` grid of each parameter; `cost`: `(n, k)` re-fitted J (NaN where failed);
      `others`: `(n, k, n)` physical values of all parameters at each profile point;
      `failed`: `(n, k)` fits that did not converge or gave a non-finite cost.
    - `interval`: `(n, 2)` where Delta J <= `threshold` (interpolated; NaN on a side where the
      profile does not reach the threshold within the grid).
    - `status`: per parameter `"identifiable"` (closed interval), `"one-sided"` (practically
      non-identifiable: open on one side), `"flat"` (Delta J below the threshold over the whole
      grid: unidentifiable) or `"unresolved"` (no grid point below the threshold: failed fits).
    - `threshold`: chi2_1(0.95) / 2 = 1.92 for a 95 % interval.
    """

    names: tuple[str, ...] = eqx.field(static=True)
    units: tuple[str, ...] = eqx.field(static=True)
    indices: tuple[int, ...] = eqx.field(static=True)
    estimate: Float[Array, " n"]
    cost_min: Float[Array, ""]
    values: Float[Array, "n k"]
    cost: Float[Array, "n k"]
    others: Float[Array, "n k n"]
    failed: Bool[Array, "n k"]
    interval: Float[Array, "n 2"]
    status: tuple[str, ...] = eqx.field(static=True)  # labels: strings cannot be traced
    threshold: Float[Array, ""]

    @property
    def delta_cost(self):
        return np.asarray(self.cost) - self.cost_min

    @property
    def identifiable(self) -> tuple[bool, ...]:
        return tuple(s == "identifiable" for s in self.status)


class _ProfileMember(eqx.Module):
    fixed: Bool[Array, " n"]
    theta_fixed: Float[Array, ""]


def profile_interval(values, delta_cost, threshold: float = PROFILE_THRESHOLD):
    """`(lower, upper, status)` of one profile: where `delta_cost <= threshold`, by linear
    interpolation of the signed root sign(v - v_min) sqrt(Delta J) (exact for a quadratic
    profile). NaN on a side that never reaches the threshold."""
    v = np.asarray(values, dtype=float)
    d = np.asarray(delta_cost, dtype=float)
    ok = np.isfinite(d)
    if ok.sum() < 2:
        return math.nan, math.nan, "flat"
    v, d = v[ok], np.maximum(d[ok], 0.0)
    i0 = int(np.argmin(d))
    root = np.sqrt(d)
    level = math.sqrt(threshold)
    if root[i0] >= level:
        return math.nan, math.nan, "unresolved"

    def crossing(indices):
        prev = i0
        for j in indices:
            if root[j] >= level:
                a, b = root[prev], root[j]
                t = (level - a) / (b - a) if b > a else 0.0
                return v[prev] + t * (v[j] - v[prev])
            prev = j
        return math.nan

    lo = crossing(range(i0 - 1, -1, -1))
    hi = crossing(range(i0 + 1, v.size))
    if np.isnan(lo) and np.isnan(hi):
        status = "flat"
    elif np.isnan(lo) or np.isnan(hi):
        status = "one-sided"
    else:
        status = "identifiable"
    return lo, hi, status


def profile_likelihood(
    problem,
    estimate=None,
    *,
    params: Sequence[str] | None = None,
    n_points: int = 21,
    lower=None,
    upper=None,
    max_steps: int = 100,
    rtol: float = 1e-8,
    atol: float = 1e-8,
    threshold: float = PROFILE_THRESHOLD,
    chunk_size: int | None = None,
    devices=None,
) -> ProfileLikelihood:
    """Profile likelihood of each parameter of `problem` (an `Objective` or a
    `LeastSquaresProblem`) about the best fit `estimate` (physical values; default the
    transform's nominal values, e.g. the truth of a synthetic objective: pass
    `bogie_jax.identify.fit(problem).estimates` for real data).

    Each profile point fixes one parameter on a grid of `n_points` values (`n_points - 1` evenly
    spaced values and the estimate) between its bounds
    (`lower`, `upper` physical `(n,)`, default the transform's; a log-scale parameter without
    finite bounds uses [estimate / 2, 2 estimate]) and re-fits the others with identify's
    Levenberg-Marquardt (`bogie_jax.identify.LevenbergMarquardt`: `atol` its step rule, `rtol`
    its relative-decrease rule, no statistical rule; `max_steps`), warm-started at the
    estimate. The `len(params) * n_points` fits run as one batch (`bogie_jax.identify.LMFits`,
    `chunk_size` fits in flight per device, default all).

    **Raises:** `ValueError` for an unknown parameter, bounds with lower >= upper or an estimate
    outside them, or `n_points < 3`, before any fit.
    """
    from ._validation import check_positive_int, resolve_names

    lsq = as_problem(problem)  # switches an objective to forward mode: LM linearises
    transform = lsq.transform
    lo_t = np.atleast_1d(np.asarray(transform.lower, dtype=float))
    hi_t = np.atleast_1d(np.asarray(transform.upper, dtype=float))
    n = lo_t.size
    names = tuple(getattr(transform, "names", None) or (f"p{i}" for i in range(n)))
    units = tuple(getattr(transform, "units", None) or ("",) * n)
    est = np.asarray(transform.nominal if estimate is None else estimate, dtype=float).reshape(-1)
    if est.shape != (n,):
        raise ValueError(f"`estimate` must have shape ({n},), got {est.shape}")
    lo = np.where(np.isfinite(hi_t), lo_t, 0.5 * est)
    hi = np.where(np.isfinite(hi_t), hi_t, 2.0 * est)
    lo = lo if lower is None else np.asarray(lower, dtype=float)
    hi = hi if upper is None else np.asarray(upper, dtype=float)
    idx = resolve_names(params if params is not None else names, names)
    n_points = check_positive_int("n_points", n_points, lo=3)
    for i in idx:
        if not (np.isfinite(lo[i]) and np.isfinite(hi[i]) and lo[i] < hi[i]):
            raise ValueError(
                f"profile bounds of `{names[i]}` need finite lower < upper, got "
                f"[{lo[i]:g}, {hi[i]:g}]"
            )
        if not lo_t[i] <= lo[i] or not hi[i] <= hi_t[i]:
            raise ValueError(
                f"profile bounds of `{names[i]}` [{lo[i]:g}, {hi[i]:g}] leave the parameter's "
                f"bounds [{lo_t[i]:g}, {hi_t[i]:g}]"
            )
        if not lo_t[i] < est[i] < hi_t[i]:
            raise ValueError(f"`estimate` of `{names[i]}` = {est[i]:g} is outside its bounds")
    theta_hat = jnp.asarray(transform.to_theta(jnp.asarray(est)))
    # Grid strictly inside the transform's open bounds (the end points map to +-inf).
    grid = []
    for i in idx:
        # the estimate itself is a grid point: the profile's minimum is always resolved
        g = np.sort(np.append(np.linspace(lo[i], hi[i], n_points - 1), est[i]))
        span = hi_t[i] - lo_t[i] if np.isfinite(hi_t[i]) else hi[i] - lo[i]
        g = np.clip(
            g, lo_t[i] + 1e-6 * span, hi_t[i] - 1e-6 * span if np.isfinite(hi_t[i]) else np.inf
        )
        grid.append(g)
    grid = np.asarray(grid)
    full = np.broadcast_to(est, (len(idx), n_points, n)).copy()
    for row, i in enumerate(idx):
        full[row, :, i] = grid[row]
    theta_grid = np.asarray(jax.vmap(transform.to_theta)(jnp.asarray(full.reshape(-1, n))))
    fixed = np.zeros((len(idx), n_points, n), dtype=bool)
    for row, i in enumerate(idx):
        fixed[row, :, i] = True
    fixed = fixed.reshape(-1, n)
    members = _ProfileMember(fixed=fixed, theta_fixed=theta_grid[fixed])
    method = LevenbergMarquardt(offset_tol=0.0, stall_offset=0.0, xtol=atol, ftol=rtol)

    def held(member: _ProfileMember):
        embed = lambda x: jnp.where(member.fixed, member.theta_fixed, x)
        residuals = lambda x, args: lsq.residuals(embed(x), args)
        return LeastSquaresProblem(residuals, transform, lsq.args)

    fits = LMFits(method, held, max_steps, lanes=chunk_size, devices=devices)
    result = fits((np.broadcast_to(np.asarray(theta_hat), fixed.shape), members))
    out, cost = result.outputs
    theta = np.where(fixed, members.theta_fixed[:, None], np.asarray(out.theta))
    phys = np.asarray(jax.vmap(transform.to_physical)(jnp.asarray(theta)))
    ok = ~np.asarray(result.failed)
    cost = np.where(ok, np.asarray(cost), np.nan).reshape(len(idx), n_points)
    fit_cost = float(eqx.filter_jit(lsq.cost)(theta_hat))
    cost_min = float(np.nanmin(np.concatenate([[fit_cost], cost.ravel()])))
    intervals, status = [], []
    for row in range(len(idx)):
        a, b, s = profile_interval(grid[row], cost[row] - cost_min, threshold)
        intervals.append((a, b))
        status.append(s)
    return ProfileLikelihood(
        names=tuple(names[i] for i in idx),
        units=tuple(units[i] for i in idx),
        indices=tuple(idx),
        estimate=est,
        cost_min=np.asarray(cost_min),
        values=grid,
        cost=cost,
        others=np.asarray(phys).reshape(len(idx), n_points, n),
        failed=~ok.reshape(len(idx), n_points),
        interval=np.asarray(intervals, dtype=float),
        status=tuple(status),
        threshold=np.asarray(float(threshold)),
    )
