"""The model refitted where the data call for it: a fit that does not explain the data repeated
with the nonlinear model (`MonitorOptions.refit_model`).

The linear model's creep and damper laws are exact only for small motions; in service the creep
forces saturate at the friction limit (Shen-Hedrick-Elkins) and anti-yaw dampers blow off above
their relief velocity. A linear fit of such data reads an equivalent damping and leaves a
structured misfit: on the detection benchmark's `nonlinear` mode (two 2 s runs, 50 cases) the
goodness-of-fit test (`_goodness.py`) failed in 43 cases, the left anti-yaw damper's intervals
held the truth in 43 of 50, and 3 of 9 half-worn dampers were withheld as not explained.

Where the test fails (or a run is left out as not explained), `monitor` judges the problem
again from the first Jacobian on with `refit_model` in place of `model`, and keeps that
judgement where its own goodness-of-fit test passes and it uses every run: a model chosen by the
data only where the first one is rejected, so on data that the first model explains (a goodness
test's false alarm rate, <= 5 %) nothing changes. The candidates, bands and options are the
same; the nuisance parameters gain the laws' own (`LAW_PARAMETERS`: the friction coefficient,
the dampers' relief velocity and their damping above it), which no one knows in service
(friction 0.1-0.5 from wet to dry rail): on data whose laws were 0.5-1.5 times the nominal
friction and 0.6-1.6 and 0.5-2 times the nominal relief (`nonlinear-laws`), a refit at the
nominal laws explained 3 of 50 cases. Their effect vanishes at rest, where the small-motion
model is linearised, so the refit takes every Jacobian from the equations of motion
(`MonitorOptions.jacobian="full"`). Where the refit does not explain the data either (an
element outside the candidates changed, a profile the cone cannot follow), the first model's
judgement stands, screened for suspects (`_suspects.py`); the refit does not decide between two
models that both fail.
"""

import dataclasses

import numpy as np

from ..params import ModelOptions, get_parameter
from ._nuisance import check_nuisance


LAW_PARAMETERS = {  # a `ModelOptions` switch: the parameters of its law, fitted in a refit
    "creep_saturation": ("contact.friction",),
    "nonlinear_dampers": ("yaw_dampers.blowoff_velocity", "yaw_dampers.c_blowoff"),
}


def law_parameters(model: ModelOptions) -> tuple[str, ...]:
    """The parameters of the nonlinear laws `model` switches on (`LAW_PARAMETERS`)."""
    return tuple(n for flag, names in LAW_PARAMETERS.items() if getattr(model, flag) for n in names)


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
    """`problem` (a `MonitorProblem`) with its options' `refit_model` as the model fitted, its
    laws' parameters among the nuisance, every Jacobian the equations of motion's and no further
    refit (module docstring); `None` where the options set no `refit_model` or it is the model
    itself."""
    options = problem.options
    refit = options.refit_model
    if refit is None or model_name(refit) == model_name(options.model):
        return None
    laws = [
        n
        for n in law_parameters(refit)
        if n not in problem.nuisance + problem.candidates
        and float(np.asarray(get_parameter(problem.params, n))) > 0  # fitted on log scale
    ]
    nuisance = check_nuisance(problem.params, problem.nuisance + tuple(laws), problem.candidates)
    options = dataclasses.replace(
        options, model=refit, refit_model=None, nuisance=nuisance, jacobian="full"
    )
    return dataclasses.replace(
        problem, nuisance=nuisance, options=options, settings=options.solve_settings()
    )
