"""The lead-in of a measurement window: how far before its first sample the objective starts
simulating, so that the wrong initial state has been forgotten by the first sample.

A measured record is a window cut out of a run that was already moving. The objective cannot
know the state at the window's first sample, so it starts earlier, at rest in the static
equilibrium, and runs over the known track before the window (the lead-in). The difference
between that start and the true state is a free motion of the linearised bogie about its rest
state, a sum of modes exp(lambda_i t) (docs/model.md, "Measurement windows and the lead-in"):
after a lead-in time T every mode has decayed by at least exp(-sigma T), sigma the slowest
decay rate

    sigma = min_i -Re(lambda_i)    over the eigenvalues of `bogie_jax.model.system_matrix`
                                   at the run's speed (rigid-body eigenvalues, |lambda| below
                                   1e-8 of the largest, excluded: they carry no transient),

so the default lead-in time is T = ln(1 / decay) / sigma and the distance `speed * T`. The
default `decay` = 1e-3 keeps the transient three orders of magnitude below the motion it came
from, far below the sensor noise of the default layout (the noise is a few per cent of the
typical signal on an ERRI low-level track). For the Manchester benchmark bogie the slowest
mode is the lightly damped kinematic (hunting) mode: sigma = 0.95 1/s at 30 m/s and 1.15 1/s at
60 m/s, so the default lead-in is about 7 s: 217 m at 30 m/s, 360 m at 60 m/s. Above the
critical speed sigma <= 0 and no lead-in is long enough (infinite).

`window_lead_in` applies the rule of `make_objective`: a window at the start of the track
(`start_position` = 0) gets no lead-in (the run really starts at rest there); a window starting
mid-run gets the default clipped to the known track before it, `min(default, start_position)`.
"""

import math

import jax.numpy as jnp
import numpy as np

from .._validation import check_range
from ..model import eigenvalues
from ..params import BogieParams, ModelOptions
from ..simulation import MAX_SPEED, check_window


DEFAULT_DECAY = 1e-3  # the factor by which the start transient must decay within the lead-in
RIGID_BODY_RTOL = 1e-8  # |lambda| below this fraction of the largest: a rigid-body eigenvalue


def slowest_decay_rate(
    params: BogieParams, speed, *, options: ModelOptions = ModelOptions()
) -> float:
    """sigma = min -Re(lambda) [1/s] over the eigenvalues of the bogie linearised at its static
    equilibrium on a perfect track at `speed` [m/s] (`bogie_jax.model.eigenvalues`), rigid-body
    eigenvalues (|lambda| < 1e-8 max |lambda|) excluded. <= 0 above the critical speed.

    **Raises:** `ValueError` for a speed outside (0, 150] m/s.
    """
    check_range("speed", speed, 0.0, MAX_SPEED, "m/s", open_lo=True)
    eig = np.asarray(eigenvalues(params, jnp.asarray(speed, dtype=float), options))
    if not np.all(np.isfinite(eig)):
        raise ValueError("the linearised bogie has non-finite eigenvalues; check `params`")
    scale = float(np.max(np.abs(eig)))
    moving = eig[np.abs(eig) > RIGID_BODY_RTOL * scale]
    return float(np.min(-moving.real))


def default_lead_in(
    params: BogieParams,
    speed,
    *,
    decay: float = DEFAULT_DECAY,
    options: ModelOptions = ModelOptions(),
) -> float:
    """The lead-in distance [m] after which a start transient has decayed by `decay`:
    `speed * ln(1 / decay) / sigma`, sigma = `slowest_decay_rate(params, speed)` (module
    docstring). Not clipped to the track: see `window_lead_in`.

    **Arguments:** `params`: the bogie (its rest state is the linearisation point); `speed`
    [m/s] in (0, 150]; `decay`: the factor in (0, 1) (default 1e-3); `options`: `ModelOptions`.

    **Returns:** the distance [m] (a float), `inf` if the bogie is unstable at `speed`
    (sigma <= 0: no lead-in lets the transient decay).

    **Raises:** `ValueError` naming `speed` or `decay` and the valid range.
    """
    check_range("decay", decay, 0.0, 1.0, open_lo=True)
    if not float(decay) < 1.0:
        raise ValueError(f"`decay` = {float(decay):g} is outside the valid range (0, 1)")
    sigma = slowest_decay_rate(params, speed, options=options)
    if not sigma > 0:
        return math.inf
    return float(speed) * math.log(1.0 / float(decay)) / sigma


def window_lead_in(
    lead_in,
    params: BogieParams,
    speed,
    start_position,
    *,
    decay: float = DEFAULT_DECAY,
    options: ModelOptions = ModelOptions(),
) -> float:
    """The lead-in [m] of a window whose first sample is at track position `start_position`
    [m]: `lead_in` itself if given (checked: finite, in [0, start_position]); for `None`, 0 at
    `start_position` = 0 (the run starts at rest at the window) and otherwise
    `min(default_lead_in(params, speed), start_position)` (the known track before the window).

    **Raises:** `ValueError` naming `lead_in` or `start_position`, the value and the valid range.
    """
    check_window(start_position, 0.0 if lead_in is None else lead_in)
    start = float(np.asarray(start_position))
    if lead_in is not None:
        return float(np.asarray(lead_in))
    if start == 0.0:
        return 0.0
    return min(default_lead_in(params, speed, decay=decay, options=options), start)
