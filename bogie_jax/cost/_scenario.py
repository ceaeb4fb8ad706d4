"""A synthetic identification problem: data from known parameters, the objective, a start."""

import jax.numpy as jnp
import numpy as np

from ..measure import synthetic_measurement
from ..params import BogieParams, ModelOptions
from ..runtime.solve_settings import SOLVE_OPTIONS, resolve_settings
from ..simulation import SolveSettings
from ..track import TrackIrregularity, TrackReference
from ._make import make_objective
from ._objective import Objective
from ._rest_state import fixed_rest_state
from ._selection import select_parameters


def synthetic_objective(
    params: BogieParams,
    track: TrackIrregularity,
    names,
    *,
    speed: float,
    duration: float,
    sample_rate: float = 200.0,
    sensors=None,
    key=None,
    offset: float = 0.1,
    track_reference: TrackReference | None = None,
    options: ModelOptions = ModelOptions(),
    settings: SolveSettings | None = None,
    y0=None,
    **objective_kwargs,
) -> tuple[Objective, jnp.ndarray]:
    """Measure the bogie `params` (the truth) with `synthetic_measurement` and return the
    objective over `names` (nominal = truth) and a start theta0 with every selected parameter
    scaled by (1 + `offset`) (clipped into its bounds). J(0) is the noise level; J(theta0) > 0.

    `key`: PRNG key for the measurement noise (None: noise-free); `track_reference`: stored in
    the measurement. `settings` (and single `SolveSettings` fields as keywords) and `y0` go to
    `make_objective`; the data are simulated with the same solver, controller, `dt0` and start
    (`max_steps=100_000`): `y0`, else the truth's static equilibrium, which is zero where the
    selected parameters cannot move it (`fixed_rest_state`; the objective then starts there too,
    and neither program has an equilibrium solve). Other keyword arguments (bounds, weights) go
    to `make_objective`.
    """
    solve_options = {k: objective_kwargs.pop(k) for k in SOLVE_OPTIONS if k in objective_kwargs}
    settings = resolve_settings(settings, SolveSettings.for_objective(), **solve_options)
    data_settings = SolveSettings(
        settings.solver, settings.stepsize_controller, max_steps=100_000, dt0=settings.dt0
    )
    if y0 is None:  # the truth is theta = 0 of the selection
        selection = select_parameters(params, names, bounds=objective_kwargs.get("bounds"))
        y0 = fixed_rest_state(params, selection, options)
    measurement = synthetic_measurement(
        params,
        track,
        speed=speed,
        duration=duration,
        sample_rate=sample_rate,
        sensors=sensors,
        key=key,
        track_reference=track_reference,
        options=options,
        settings=data_settings,
        y0=y0,
    )
    objective = make_objective(
        measurement, params, track, names, sensors=sensors, options=options, settings=settings,
        y0=y0, **objective_kwargs,
    )  # fmt: skip
    sel = objective.selection
    start = np.asarray(sel.nominal) * (1.0 + offset)
    lo, hi = np.asarray(sel.lower), np.asarray(sel.upper)
    boxed = np.isfinite(hi)
    margin = 0.01 * (np.where(boxed, hi, lo) - lo)
    inside = np.clip(start, lo + margin, np.where(boxed, hi, np.inf) - margin)
    return objective, sel.to_theta(jnp.asarray(np.where(boxed, inside, start)))
