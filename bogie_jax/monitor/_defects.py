"""Named defect scenarios (changes of single suspension elements from the nominal bogie) and
synthetic measurement runs of them through the public measurement path
(`bogie_jax.measure.synthetic_measurement`).

A scenario multiplies the nominal value of each named element by its factor. A "0 %" element
uses `FAILED_FLOOR` = 1 % of nominal instead of 0: the fits work in ln p (log scale keeps every
estimate positive and relative errors comparable), which cannot reach 0, and a damper at 1 % of
its nominal damping has no practical effect (`yaw_dampers.left.c` 4 kN s/m against 400 kN s/m).
Scenarios name elements (`primary.1L.kz`, `yaw_dampers.left.c`) or tied groups
(`yaw_dampers.c`: every element of the group by the same factor).
"""

import dataclasses
import inspect
import math
import types
from collections.abc import Mapping, Sequence

import jax.random as jr
import numpy as np

from .._validation import nonempty_tuple
from ..measure import (
    Measurement,
    default_sensor_layout,
    layout_description,
    synthetic_measurement,
)
from ..params import (
    BogieParams,
    ModelOptions,
    get_parameter,
    manchester_benchmark,
    resolve_parameter,
    set_parameters,
)
from ..simulation import SolveSettings, sample_times
from ..track import SPECTRA, TrackReference


FAILED_FLOOR = 0.01
"""Factor used for an element at "0 %" (see the module docstring)."""
RUN_MARGIN = 50.0  # [m] track beyond the longest run (as `TrackReference.for_run`)
MAX_SPEED = 150.0  # [m/s], as `simulate`


def _element_values(params: BogieParams, name: str) -> dict[str, float]:
    """`{element name: value}` of `name`: itself, or every element of a tied group."""
    where = resolve_parameter(params, name)
    if not where.is_tied_group:
        return {name: float(np.asarray(get_parameter(params, name)))}
    group, field = where.tied_name.rsplit(".", 1)
    return {
        f"{group}.{label}.{field}": float(
            np.asarray(get_parameter(params, f"{group}.{label}.{field}"))
        )
        for label in where.spec.elements
    }


@dataclasses.dataclass(frozen=True)
class DefectScenario:
    """A bogie whose named elements differ from nominal by a factor.

    - `name`, `description`: for people;
    - `factors`: `{parameter name: factor}`, true value = factor * nominal value (element
      names such as `primary.1L.kz`, or a tied name such as `yaw_dampers.c` for all of its
      elements); empty for a healthy bogie.

    **Raises** (on construction, before anything is simulated): `ValueError` for an unknown
    parameter name (naming the valid ones), a tied group given together with one of its
    elements, or a factor that is not finite and > 0.
    """

    name: str
    description: str = ""
    factors: Mapping[str, float] = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        if not isinstance(self.factors, Mapping):
            raise TypeError(
                f"`factors` of scenario {self.name!r} must be a mapping {{element name: factor}}, "
                f"got {type(self.factors).__name__}"
            )
        factors = {str(k): float(v) for k, v in self.factors.items()}
        reference = manchester_benchmark()  # names are the same for every parameter set
        covered: dict[str, str] = {}
        for name, f in factors.items():
            for element in _element_values(reference, name):  # unknown name: ValueError
                if element in covered:
                    raise ValueError(
                        f"scenario {self.name!r} sets `{element}` twice (through "
                        f"`{covered[element]}` and `{name}`): give the tied group or its elements"
                    )
                covered[element] = name
            if not (math.isfinite(f) and f > 0):
                raise ValueError(
                    f"scenario {self.name!r}: factor of `{name}` = {f!r} must be finite and > 0 "
                    f"(an element at 0 % is written as {FAILED_FLOOR}, see FAILED_FLOOR)"
                )
        object.__setattr__(self, "factors", types.MappingProxyType(factors))

    @property
    def elements(self) -> tuple[str, ...]:
        """The changed element names (tied groups expanded)."""
        reference = manchester_benchmark()
        return tuple(e for n in self.factors for e in _element_values(reference, n))

    def true_params(self, base: BogieParams | None = None) -> BogieParams:
        """`base` (default: the Manchester benchmark bogie) with the factors applied by
        `bogie_jax.params.set_parameters` (each element's own value times its factor)."""
        base = manchester_benchmark() if base is None else base
        values = {
            element: value * f
            for name, f in self.factors.items()
            for element, value in _element_values(base, name).items()
        }
        return set_parameters(base, values)

    def to_dict(self) -> dict:
        return {"name": self.name, "description": self.description, "factors": dict(self.factors)}


def _scenarios(*items) -> dict[str, DefectScenario]:
    return {s.name: s for s in items}


DEFECT_SCENARIOS = _scenarios(
    DefectScenario("healthy", "a healthy bogie: every element nominal"),
    DefectScenario(
        "yaw-damper-left-50",
        "left anti-yaw damper at 50 % of its damping",
        {"yaw_dampers.left.c": 0.5},
    ),
    DefectScenario(
        "yaw-damper-left-0",
        f"left anti-yaw damper lost (0 %: {FAILED_FLOOR:.0%} of nominal, see FAILED_FLOOR)",
        {"yaw_dampers.left.c": FAILED_FLOOR},
    ),
    DefectScenario(
        "primary-damper-1L-failed",
        "primary vertical damper of axlebox 1L failed (10 %)",
        {"primary.1L.cz": 0.1},
    ),
    DefectScenario(
        "primary-spring-1L-hard",
        "primary rubber spring of axlebox 1L hardened +30 % (vertical and lateral)",
        {"primary.1L.kz": 1.3, "primary.1L.ky": 1.3},
    ),
    DefectScenario(
        "primary-spring-1L-soft",
        "primary rubber spring of axlebox 1L softened -30 % (vertical and lateral)",
        {"primary.1L.kz": 0.7, "primary.1L.ky": 0.7},
    ),
    DefectScenario(
        "secondary-lateral-damper-left-failed",
        "secondary lateral damper of the left side failed (10 %)",
        {"secondary.left.cy": 0.1},
    ),
    DefectScenario(
        "yaw-dampers-worn-60",
        "both anti-yaw dampers worn to 60 %",
        {"yaw_dampers.left.c": 0.6, "yaw_dampers.right.c": 0.6},
    ),
)
"""The named defect scenarios, by name (see the module docstring for "0 %")."""


def as_defect_scenario(scenario) -> DefectScenario:
    """A `DefectScenario`, a name of `DEFECT_SCENARIOS`, or a mapping `{element: factor}` (a
    user-defined scenario named `custom`)."""
    if isinstance(scenario, DefectScenario):
        return scenario
    if isinstance(scenario, Mapping):
        return DefectScenario("custom", "user-defined", scenario)
    if isinstance(scenario, str) and scenario in DEFECT_SCENARIOS:
        return DEFECT_SCENARIOS[scenario]
    raise ValueError(
        f"unknown defect scenario {scenario!r}; choose one of {', '.join(DEFECT_SCENARIOS)}, or "
        "pass a DefectScenario or a mapping {element name: factor}"
    )


@dataclasses.dataclass(frozen=True)
class RunSpec:
    """One measurement run.

    - `speed` [m/s] in (0, 150]; `duration` [s] > 0; `sample_rate` [Hz] > 0;
    - `track`: spectrum name (`bogie_jax.track.SPECTRA`) and `seed`: the random track
      realisation (`TrackReference`);
    - `noise_scale`: sensor noise as a multiple of each sensor's `noise_std` (0: noise-free);
    - `start_position` [m]: track position of the window's first sample. The bogie ran from
      rest at track position 0 (simulated, not recorded), so a window at `start_position` > 0
      starts while the bogie is moving; the measurement records `start_position` (needs
      `synthetic_measurement` with mid-run windows).
    """

    speed: float
    duration: float = 1.0
    sample_rate: float = 100.0
    track: str = "erri-low"
    seed: int = 0
    noise_scale: float = 1.0
    start_position: float = 0.0

    def __post_init__(self):
        checks = (
            ("speed", self.speed, 0 < self.speed <= MAX_SPEED, f"in (0, {MAX_SPEED:g}] m/s"),
            ("duration", self.duration, 0 < self.duration < math.inf, "finite and > 0 s"),
            ("sample_rate", self.sample_rate, 0 < self.sample_rate < math.inf, "> 0 Hz"),
            ("noise_scale", self.noise_scale, 0 <= self.noise_scale < math.inf, ">= 0"),
        )
        for name, value, ok, valid in checks:
            if not ok:
                raise ValueError(f"RunSpec `{name}` = {value!r} must be {valid}")
        if self.track not in SPECTRA:
            raise ValueError(
                f"RunSpec `track` = {self.track!r} is not a spectrum; valid: {', '.join(SPECTRA)}"
            )
        if not (0 <= self.start_position < math.inf):
            raise ValueError(
                f"RunSpec `start_position` = {self.start_position!r} m must be finite and >= 0"
            )

    @property
    def distance(self) -> float:
        """Distance the run covers [m]."""
        return self.start_position + self.speed * self.duration


def _check_key(runs: tuple[RunSpec, ...], key) -> None:
    """A `key` where one of `runs` is noisy."""
    noisy = [k for k, run in enumerate(runs) if run.noise_scale > 0]
    if noisy and key is None:
        raise ValueError(
            f"`key` is None but run {noisy[0]} has noise_scale = {runs[noisy[0]].noise_scale!r}: "
            "pass a PRNG key (jax.random.PRNGKey(seed)) or set noise_scale=0"
        )


def _check_runs(runs) -> tuple[RunSpec, ...]:
    """`runs` as a non-empty tuple of `RunSpec`s."""
    runs = nonempty_tuple("runs", runs, RunSpec, "give at least one RunSpec")
    mid_run = [k for k, run in enumerate(runs) if run.start_position > 0]
    if mid_run and "start_position" not in inspect.signature(synthetic_measurement).parameters:
        raise ValueError(
            f"run {mid_run[0]} has start_position = {runs[mid_run[0]].start_position!r} m: this "
            "version of synthetic_measurement has no mid-run windows; use 0"
        )
    return runs


def scenario_measurements(
    scenario,
    runs: Sequence[RunSpec],
    *,
    params: BogieParams | None = None,
    key=None,
    sensors=None,
    options: ModelOptions = ModelOptions(),
    settings: SolveSettings | None = None,
) -> tuple[Measurement, ...]:
    """Measurements of the bogie of `scenario` (a `DefectScenario`, a name of
    `DEFECT_SCENARIOS` or a mapping `{element: factor}`) for each of `runs`, simulated from the
    hidden true parameters `scenario.true_params(params)` by `synthetic_measurement`.

    A run with `start_position` > 0 is simulated from rest at track position 0 (lead-in =
    `start_position`) and recorded from `start_position` on.

    Every run's track is synthesised with one common length (the longest run plus the
    wheelbase and a 50 m margin), so that every run has track arrays of one shape (one compiled
    simulation, and one vmapped joint objective); each `Measurement.track` records its
    `TrackReference` (rebuild with `.build()`). Noise of run k uses `jax.random.fold_in(key, k)`.

    **Arguments:** `params`: the nominal bogie (default Manchester benchmark); `key`: PRNG key
    of the noise (required when a run has `noise_scale > 0`); `sensors`: default
    `default_sensor_layout(params)`; `options`, `settings`: as `synthetic_measurement`.

    **Raises:** `ValueError` for no runs, a run that is not a `RunSpec`, a missing `key`, or a
    bad scenario, before anything is simulated.
    """
    scenario = as_defect_scenario(scenario)
    runs = _check_runs(runs)
    _check_key(runs, key)
    params = manchester_benchmark() if params is None else params
    truth = scenario.true_params(params)
    out = []
    for k, (run, reference) in enumerate(zip(runs, _references(runs, params))):
        window = (
            {"start_position": run.start_position, "lead_in": run.start_position}
            if run.start_position > 0
            else {}
        )
        out.append(
            synthetic_measurement(
                truth,
                reference.build(),
                speed=run.speed,
                duration=run.duration,
                sample_rate=run.sample_rate,
                sensors=sensors,
                key=jr.fold_in(key, k) if run.noise_scale > 0 else None,
                noise_scale=run.noise_scale,
                track_reference=reference,
                options=options,
                settings=settings,
                **window,
            )
        )
    return tuple(out)


def _references(runs, params) -> list[TrackReference]:
    """Each run's `TrackReference`: its spectrum and seed, one common length (the longest run
    plus the wheelbase and `RUN_MARGIN`)."""
    wheelbase = 2.0 * float(np.asarray(params.geometry.semi_wheelbase))
    length = max(run.distance for run in runs) + wheelbase + RUN_MARGIN
    return [TrackReference(spectrum=run.track, seed=run.seed, length=length) for run in runs]


def scenario_layout(runs: Sequence[RunSpec], *, params: BogieParams | None = None, sensors=None):
    """Measurements of the shapes and metadata that `scenario_measurements` gives for `runs`
    (sample times, channels, speeds, track references), their data zero: for compiling
    `monitor`'s programs while the data are simulated (`compile_programs`). **Raises:** as
    `scenario_measurements` for bad `runs`."""
    runs = _check_runs(runs)
    params = manchester_benchmark() if params is None else params
    sensors = default_sensor_layout(params) if sensors is None else tuple(sensors)

    def blank(run: RunSpec, reference: TrackReference) -> Measurement:
        times = run.start_position / run.speed + sample_times(run.duration, run.sample_rate)
        return Measurement(
            times=times,
            data=np.zeros((times.size, len(sensors))),
            channels=tuple(s.name for s in sensors),
            units=tuple(s.unit for s in sensors),
            speed=run.speed,
            track=reference,
            layout=layout_description(sensors),
            start_position=run.start_position,
        )

    return tuple(blank(run, ref) for run, ref in zip(runs, _references(runs, params)))
