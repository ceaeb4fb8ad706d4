"""Named synthetic identification scenarios: data from known ("true") parameters.

The truth is the Manchester benchmark bogie with some parameters offset by known factors; the
objective starts from the unmodified Manchester values (the nominal values) and searches each
selected parameter inside its tolerance band `nominal * (1 -+ band)` (scaled-logistic
coordinates, so no estimate ever leaves the band). Used by `bogie-jax identify`, the
identification benchmark and the tests.
"""

import dataclasses

import diffrax as dfx
import equinox as eqx
import jax.random as jr
import numpy as np

from ..cost import fixed_rest_state, get_parameter, make_objective, select_parameters
from ..params import PARAMETER_SETS, ModelOptions, parameter_specs, set_parameters
from ..simulation import SolveSettings
from ..track import TrackReference


@dataclasses.dataclass(frozen=True)
class Scenario:
    """A synthetic run with known true parameters.

    - `offsets`: `{name: factor}`: true value = factor * nominal; these are also the parameters
      identified by default (in this order).
    - `speed` [m/s], `duration` [s], `sample_rate` [Hz], `track` (spectrum name), `seed` (track).
    - `channels`: sensor names of the default layout (`None`: all 13 channels).
    - `band`: relative tolerance band of the search around the nominal value.
    """

    name: str
    description: str
    offsets: dict
    speed: float = 50.0
    duration: float = 2.0
    sample_rate: float = 100.0
    track: str = "erri-low"
    seed: int = 0
    channels: tuple[str, ...] | None = None
    band: float = 0.5


_P3 = {"primary.kz": 1.15, "primary.cz": 0.9, "yaw_dampers.c": 1.1}
_P6 = {**_P3, "primary.ky": 0.9, "primary.cy": 1.1, "secondary.cy": 1.1}
_P10 = {
    **_P6,
    "primary.kx": 0.9,
    "secondary.ky": 1.1,
    "secondary.kz": 0.9,
    "secondary.cz": 1.1,
}

SCENARIOS = {
    s.name: s
    for s in (
        Scenario("default", "3 parameters (primary kz, cz, yaw damper c), 2 s at 50 m/s", _P3),
        Scenario("primary3", "primary.kz, primary.cz, yaw_dampers.c, 2 s at 50 m/s", _P3),
        Scenario("primary6", "6 primary/secondary/yaw parameters, 2 s at 50 m/s", _P6),
        Scenario("all10", "10 stiffness and damping parameters, 3 s at 50 m/s", _P10, duration=3.0),
    )
}


def tolerance_bounds(params, names, band: float) -> dict:
    """`{name: (lo, hi)}`: the band `nominal * (1 -+ band)`, clipped into each valid range."""
    if not 0 < band < 1:
        raise ValueError(f"`band` must be in (0, 1), got {band:g}")
    specs = parameter_specs(params, elements=True)
    out = {}
    for name in names:
        if name not in specs:
            continue  # select_parameters reports the unknown name
        p0 = float(np.asarray(get_parameter(params, name)))
        vlo, vhi = specs[name].valid
        lo, hi = sorted((p0 * (1 - band), p0 * (1 + band)))
        out[name] = (max(lo, vlo), min(hi, vhi))
    return out


class SyntheticProblem(eqx.Module):
    """An objective with known true values (`truth`, physical, in selection order), its
    `scenario` and the `track` it ran over (`TrackReference`, `None` for a track passed in)."""

    objective: object
    truth: np.ndarray
    scenario: Scenario = eqx.field(static=True)
    track: TrackReference | None = eqx.field(static=True, default=None)


def true_params(nominal, offsets: dict):
    names = tuple(offsets)
    values = {n: float(np.asarray(get_parameter(nominal, n))) * float(offsets[n]) for n in names}
    return set_parameters(nominal, values)


def as_scenario(scenario) -> Scenario:
    if isinstance(scenario, Scenario):
        return scenario
    try:
        return SCENARIOS[scenario]
    except (KeyError, TypeError):
        raise ValueError(
            f"unknown scenario {scenario!r}; choose one of {', '.join(SCENARIOS)}"
        ) from None


def scenario_problem(
    scenario="default",
    names=None,
    *,
    key=None,
    noise_scale: float = 1.0,
    relative_noise: float | None = None,
    duration: float | None = None,
    sample_rate: float | None = None,
    rtol: float = 1e-8,
    vehicle: str = "manchester",
    adjoint=None,
    track=None,
) -> SyntheticProblem:
    """The objective of a named scenario over `names` (default: the scenario's parameters).

    **Arguments:**
    - `key`: PRNG key of the measurement noise (`None`: noise-free); `noise_scale` multiplies
      every sensor's noise standard deviation.
    - `relative_noise`: instead, noise of standard deviation `relative_noise` times each
      channel's RMS (e.g. 0.02 for "2 % noise"), weighted by the inverse of that variance.
    - `duration`, `sample_rate`: override the scenario's.
    - `rtol`: solver tolerance of the data and the fit (`atol = 1e-3 rtol`). The default 1e-8
      is tighter than `SolveSettings`' 1e-6 on purpose: this function makes the noise-free runs
      of the tests (estimates checked to 1e-5 of the truth) and of the benchmarks, and without
      noise the solver's own error is what is left. Against sensor noise of 1-3 % the 1e-6
      error is negligible: `bogie-jax identify` passes its `--rtol`, default 1e-6.
    - `adjoint`: the objective's adjoint (default: that of `SolveSettings.for_objective()`,
      reverse mode for `jax.grad`; fits switch to forward mode by themselves).
    - `track`: a `TrackIrregularity` to use instead of the scenario's (then `track` of the
      result is `None`); by default the scenario's `TrackReference.for_run(...)`.

    **Raises:** `ValueError` for an unknown scenario or parameter name or an empty selection.
    """
    from ..measure import default_sensor_layout, synthetic_measurement

    sc = as_scenario(scenario)
    if duration is not None or sample_rate is not None:
        sc = dataclasses.replace(
            sc,
            duration=sc.duration if duration is None else float(duration),
            sample_rate=sc.sample_rate if sample_rate is None else float(sample_rate),
        )
    nominal = PARAMETER_SETS[vehicle]()
    names = (
        tuple(sc.offsets) if names is None else (names,) if isinstance(names, str) else tuple(names)
    )
    bounds = tolerance_bounds(nominal, names, sc.band)
    select_parameters(nominal, names, bounds=bounds)  # names checked before anything is simulated
    truth_params = true_params(nominal, sc.offsets)
    reference = None
    if track is None:
        wheelbase = 2 * float(nominal.geometry.semi_wheelbase)
        reference = TrackReference.for_run(
            sc.track, seed=sc.seed, speed=sc.speed, duration=sc.duration, wheelbase=wheelbase
        )
        track = reference.build()
    sensors = default_sensor_layout(nominal)
    if sc.channels is not None:
        sensors = tuple(s for s in sensors if s.name in sc.channels)
    controller = dfx.PIDController(rtol=rtol, atol=1e-3 * rtol)
    settings = SolveSettings(stepsize_controller=controller)
    # The truth departs from the nominal bogie in the scenario's parameters only: where those
    # cannot move the rest state (the objective's own test), the truth rests at zero and the
    # data program has no equilibrium solve.
    offset = select_parameters(nominal, tuple(sc.offsets))
    measurement = synthetic_measurement(
        truth_params,
        track,
        speed=sc.speed,
        duration=sc.duration,
        sample_rate=sc.sample_rate,
        sensors=sensors,
        key=None if relative_noise is not None else key,
        noise_scale=noise_scale,
        track_reference=reference,
        settings=settings,
        y0=fixed_rest_state(nominal, offset, ModelOptions()),
    )
    weights = None
    if relative_noise is not None:
        data = np.asarray(measurement.data)
        std = relative_noise * np.sqrt(np.mean((data - data.mean(0)) ** 2, axis=0))
        std = np.maximum(std, 1e-12)
        if key is not None:
            data = data + std * np.asarray(jr.normal(key, data.shape))
        measurement = eqx.tree_at(lambda m: m.data, measurement, data)
        weights = 1.0 / std**2
    objective = make_objective(
        measurement,
        nominal,
        track,
        names,
        sensors=sensors,
        bounds=bounds,
        weights=weights,
        settings=SolveSettings.for_objective(stepsize_controller=controller, adjoint=adjoint),
    )
    truth = np.array([float(np.asarray(get_parameter(truth_params, n))) for n in names])
    return SyntheticProblem(objective, truth, sc, reference)


def relative_errors(estimates, truth) -> np.ndarray:
    truth = np.asarray(truth, dtype=float)
    return np.abs(np.asarray(estimates, dtype=float) - truth) / np.where(
        truth == 0, 1.0, np.abs(truth)
    )
