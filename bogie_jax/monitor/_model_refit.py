"""The model refitted where the data call for it: a fit that does not explain the data repeated
with the nonlinear model (`MonitorOptions.refit_model`).

The linear model's creep and damper laws are exact only for small motions; in service the creep
forces saturate at the friction limit (Shen-Hedrick-Elkins) and anti-yaw dampers blow off above
their relief velocity. A linear fit of such data reads an equivalent damping and leaves a
structured misfit: on the detection benchmark's `nonlinear` mode (two 2 s runs, 50 cases) the
goodness-of-fit test (`_goodness.py`) failed in 43 cases, the left anti-yaw damper's intervals
held the truth in 43 of 50, and 3 of 9 half-worn dampers were withheld as not explained.

Where the test fails, `monitor` judges the problem again from the first Jacobian on with
`refit_model` in place of `model` (the candidates, nuisance parameters, bands and options
otherwise the same), and keeps that judgement where its own goodness-of-fit test passes: a model
chosen by the data only where the first one is rejected, so on data that the first model
explains (a goodness test's false alarm rate, <= 5 %) nothing changes. Where the refit does not
explain the data either (an element outside the candidates changed, a profile the cone cannot
follow), the first model's judgement stands, screened for suspects (`_suspects.py`); the refit
does not decide between two models that both fail.
"""

import dataclasses

from ..params import ModelOptions


def model_name(model: ModelOptions) -> str:
    """The model's nonlinear options in words (`ModelOptions`), or "linear" with none on."""
    parts = [
        name
        for name, on in (
            ("creep saturation", model.creep_saturation),
            ("blow-off anti-yaw dampers", model.nonlinear_dampers),
            ("flange contact", model.flange_contact),
        )
        if on
    ]
    return ", ".join(parts) if parts else "linear"


def refit_problem(problem):
    """`problem` (a `MonitorProblem`) with its options' `refit_model` as the model fitted and no
    further refit; `None` where the options set no `refit_model` or it is the model itself."""
    options = problem.options
    refit = options.refit_model
    if refit is None or model_name(refit) == model_name(options.model):
        return None
    options = dataclasses.replace(options, model=refit, refit_model=None)
    return dataclasses.replace(problem, options=options, settings=options.solve_settings())
