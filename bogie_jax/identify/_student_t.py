"""Student's t distribution (tail probability and quantile) and Welch-Satterthwaite degrees of
freedom, in plain Python (no scipy at run time): the one t quantile of the fits' intervals
(`fit_statistics`) and of the monitor's verdict and trend rules.

A standard error whose square is a sum of variance estimates, each with its own degrees of
freedom nu_i, is treated as that of a Student's t statistic with the effective degrees of freedom

    nu = (sum_i v_i)^2 / sum_i (v_i^2 / nu_i)

(Satterthwaite, Biometrics Bulletin 2 (1946) 110-114; Welch, Biometrika 34 (1947) 28-35), e.g.
a residual variance with m - n degrees of freedom plus a Monte Carlo variance from `draws`
realisations.
"""

import math
from statistics import NormalDist


def two_sided_p_value(statistic: float, dof: float | None) -> float:
    """P(|X| > statistic) for X standard normal (`dof` None) or Student's t with `dof`."""
    if dof is None:
        return 2 * (1 - NormalDist().cdf(statistic))
    # Student's t tail by the regularised incomplete beta function, I_x(dof/2, 1/2)
    # with x = dof / (dof + t^2) (Abramowitz & Stegun 26.7.1 and 26.5.27)
    return _regularised_beta(dof / (dof + statistic**2), dof / 2, 0.5)


def _regularised_beta(x: float, a: float, b: float) -> float:
    """I_x(a, b) by its continued fraction (Numerical Recipes, 3rd ed., 6.4), 0 <= x <= 1."""
    if x <= 0:
        return 0.0
    if x >= 1:
        return 1.0
    log_front = (
        math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x) + b * math.log1p(-x)
    )
    if x > (a + 1) / (a + b + 2):
        return 1.0 - _regularised_beta(1 - x, b, a)
    # modified Lentz evaluation of the continued fraction
    tiny, c, d = 1e-300, 1.0, 1.0 - (a + b) * x / (a + 1)
    d = 1 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 300):
        for numerator in (
            m * (b - m) * x / ((a + 2 * m - 1) * (a + 2 * m)),
            -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1)),
        ):
            d = 1 + numerator * d
            d = 1 / (d if abs(d) > tiny else tiny)
            c = 1 + numerator / c
            c = c if abs(c) > tiny else tiny
            h *= d * c
        if abs(d * c - 1) < 1e-15:
            break
    return math.exp(log_front) * h / a


def t_quantile(probability: float, dof: float) -> float:
    """The `probability` quantile of Student's t with `dof` > 0 degrees of freedom (real;
    `inf`: the standard normal), for `probability` in (0, 1), to about 1e-12 relative.

    Newton's method on the distribution function from the normal quantile, which lies below
    the t quantile for `probability` > 0.5; the density falls beyond it, so every step stays
    below the root and the iterates rise to it monotonically. From `dof` = 1e6 on (where the
    tail's beta function loses digits) the first term of the expansion in 1 / `dof`."""
    if not 0.0 < probability < 1.0:
        raise ValueError(f"`probability` = {probability!r} must lie in (0, 1)")
    if not dof > 0:
        raise ValueError(f"`dof` = {dof!r} must be > 0")
    if probability <= 0.5:
        return 0.0 if probability == 0.5 else -t_quantile(1.0 - probability, dof)
    q = NormalDist().inv_cdf(probability)
    if dof >= 1e6:  # the first term of the expansion in 1 / dof (Abramowitz & Stegun 26.7.5)
        return q + (q**3 + q) / (4.0 * dof)
    tail = 2.0 * (1.0 - probability)  # two-sided
    log_norm = math.lgamma((dof + 1) / 2) - math.lgamma(dof / 2) - 0.5 * math.log(dof * math.pi)
    for _ in range(500):
        density = math.exp(log_norm - (dof + 1) / 2 * math.log1p(q * q / dof))
        step = (two_sided_p_value(q, dof) - tail) / (2.0 * density)
        q += step
        if abs(step) <= 1e-13 * q:
            break
    return q


def satterthwaite_dof(variances, dofs) -> float:
    """The effective degrees of freedom of a sum of variance estimates `variances` with degrees
    of freedom `dofs` (module docstring; `inf` for an exactly known term); `inf` where every
    term is exact or the sum is zero (or not finite).

    **Raises:** `ValueError` for a degree of freedom that is not > 0."""
    if not all(float(d) > 0 for d in dofs):
        raise ValueError(f"`dofs` = {tuple(dofs)!r} must all be > 0")
    v = [float(x) for x in variances]
    total = sum(v)
    if not (math.isfinite(total) and total > 0):
        return math.inf
    terms = sum(x * x / float(d) for x, d in zip(v, dofs) if x > 0 and not math.isinf(float(d)))
    return total * total / terms if terms > 0 else math.inf
