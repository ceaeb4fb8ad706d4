"""A synthetic identification problem: data from known parameters, the objective, a start."""

import jax.numpy as jnp
import numpy as np

from ..measure import synthetic_measurement
from ..params import BogieParams, ModelOptions
from ..track import TrackIrregularity
from ._make import make_objective
from ._objective import Objective


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
    track_name: str = "",
    options: ModelOptions = ModelOptions(),
    **objective_kwargs,
) -> tuple[Objective, jnp.ndarray]:
    """Measure the bogie `params` (the truth) with `synthetic_measurement` and return the
    objective over `names` (nominal = truth) and a start theta0 with every selected parameter
    scaled by (1 + `offset`) (clipped into its bounds). J(0) is the noise level; J(theta0) > 0.

    `key`: PRNG key for the measurement noise (None: noise-free). Other keyword arguments go to
    `make_objective` (bounds, weights, solver settings) and, for `solver`,
    `stepsize_controller`, `dt0` and `y0`, also to the simulation of the data.
    """
    sim_kwargs = {
        k: objective_kwargs[k]
        for k in ("solver", "stepsize_controller", "dt0", "y0")
        if k in objective_kwargs
    }
    measurement = synthetic_measurement(
        params,
        track,
        speed=speed,
        duration=duration,
        sample_rate=sample_rate,
        sensors=sensors,
        key=key,
        track_name=track_name,
        options=options,
        **sim_kwargs,
    )
    objective = make_objective(
        measurement, params, track, names, sensors=sensors, options=options, **objective_kwargs
    )
    sel = objective.selection
    start = np.asarray(sel.nominal) * (1.0 + offset)
    lo, hi = np.asarray(sel.lower), np.asarray(sel.upper)
    boxed = np.isfinite(hi)
    margin = 0.01 * (np.where(boxed, hi, lo) - lo)
    inside = np.clip(start, lo + margin, np.where(boxed, hi, np.inf) - margin)
    return objective, sel.to_theta(jnp.asarray(np.where(boxed, inside, start)))
