"""Gradients of the least-squares objective (paper sections 5.2-5.3) and their checks.

- `gradient`, `jacobian_by_mode`, `scalar_product_test`, `reference_gradient`: every method,
  reverse and forward AD, the continuous adjoint, `DirectAdjoint`, finite differences.
- `gradient_report`, `report_table`: timing, accuracy and memory of each method on an objective
  (`bogie-jax gradcheck`).
"""

from ..runtime.solve_settings import full_checkpoints
from ._check import gradient_report, median_time, report_table, timed
from ._methods import (
    AD_METHODS,
    FD_METHODS,
    METHODS,
    GradientResult,
    ScalarProductTest,
    compiled_jacobian,
    compiled_residuals,
    default_jacobian_mode,
    default_rel_noise,
    fd_steps,
    gradient,
    jacobian_by_mode,
    reference_gradient,
    residuals_and_pullback,
    resolve_method,
    scalar_product_test,
    seminorm_backsolve,
)


__all__ = [
    "AD_METHODS",
    "FD_METHODS",
    "METHODS",
    "GradientResult",
    "ScalarProductTest",
    "compiled_jacobian",
    "compiled_residuals",
    "default_jacobian_mode",
    "default_rel_noise",
    "fd_steps",
    "full_checkpoints",
    "gradient",
    "gradient_report",
    "jacobian_by_mode",
    "median_time",
    "reference_gradient",
    "report_table",
    "residuals_and_pullback",
    "resolve_method",
    "scalar_product_test",
    "seminorm_backsolve",
    "timed",
]
