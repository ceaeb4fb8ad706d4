"""Sensors: accelerometers, displacement sensors and a rate gyro on the bogie.

Each sensor reads one scalar channel from a `SampleState` (q, q_dot, q_ddot and the track inputs
at one time). The reading is the exact kinematic quantity plus the sensor's constant `bias`;
random noise of standard deviation `noise_std` is added only when a synthetic measurement is drawn
with an explicit PRNG key (`synthetic_measurement`). `noise_std` also sets the default weight
1 / noise_std^2 of the channel in the least-squares cost (paper eq. 12).

Default noise levels are typical of in-service bogie instrumentation: 0.02 m/s^2 (about 2 mg RMS)
for accelerometers, 0.1 mm for displacement transducers and 1e-3 rad/s (0.06 deg/s) for a MEMS
rate gyro.
"""

import abc
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from equinox import AbstractClassVar, AbstractVar
from jaxtyping import Array, Float

from ..model import BogieModel, _kinematics as kin
from ._locations import AbstractLocation, SampleState, location_from_description, point_motion


AXES = ("x", "y", "z")


def _as_float(x):
    return x if isinstance(x, jnp.ndarray) or hasattr(x, "aval") else np.asarray(x, dtype=float)


class AbstractSensor(eqx.Module):
    """One measurement channel. `name` is the channel name, `unit` its SI unit."""

    name: AbstractVar[str]
    noise_std: AbstractVar[Float[Array, ""]]
    bias: AbstractVar[Float[Array, ""]]
    unit: AbstractClassVar[str]

    @abc.abstractmethod
    def read(self, model: BogieModel, state: SampleState) -> Float[Array, ""]:
        """The noise-free reading without bias, in `unit`."""

    @abc.abstractmethod
    def _describe(self) -> dict:
        """Type-specific fields of `describe`."""

    def describe(self) -> dict:
        """JSON-ready description (inverse of `sensor_from_description`)."""
        return {
            "type": type(self).__name__,
            "name": self.name,
            "unit": self.unit,
            **self._describe(),
            "noise_std": float(self.noise_std),
            "bias": float(self.bias),
        }

    def __check_init__(self):
        if not isinstance(self.name, str) or not self.name or "," in self.name or "[" in self.name:
            raise ValueError(
                f"sensor `name` must be a non-empty string without ',' or '[', got {self.name!r}"
            )
        axis = getattr(self, "axis", "x")
        if axis not in AXES:
            raise ValueError(f"sensor {self.name!r}: `axis` must be one of {AXES}, got {axis!r}")
        if not hasattr(self.noise_std, "aval"):
            std = float(self.noise_std)
            if not (np.isfinite(std) and std > 0):
                raise ValueError(
                    f"sensor {self.name!r}: `noise_std` must be > 0 [{self.unit}], got {std!r}"
                )


class Accelerometer(AbstractSensor):
    """Acceleration [m/s^2] of a point along a track axis (gravity not included: an ideal
    gravity-compensated accelerometer aligned with the track axes)."""

    name: str = eqx.field(static=True)
    location: AbstractLocation
    axis: str = eqx.field(static=True)
    noise_std: Float[Array, ""] = eqx.field(default=0.02, converter=_as_float)
    bias: Float[Array, ""] = eqx.field(default=0.0, converter=_as_float)
    unit: ClassVar[str] = "m/s^2"

    def read(self, model, state):
        return point_motion(self.location, model, state)[2][AXES.index(self.axis)]

    def _describe(self):
        return {"location": self.location.describe(), "axis": self.axis}


class DisplacementSensor(AbstractSensor):
    """Displacement [m] of a point from its static-equilibrium position along a track axis, or,
    with `reference`, of the point relative to the reference point (e.g. a frame point over an
    axlebox: the primary suspension deflection)."""

    name: str = eqx.field(static=True)
    location: AbstractLocation
    axis: str = eqx.field(static=True)
    reference: AbstractLocation | None = None
    noise_std: Float[Array, ""] = eqx.field(default=1e-4, converter=_as_float)
    bias: Float[Array, ""] = eqx.field(default=0.0, converter=_as_float)
    unit: ClassVar[str] = "m"

    def _offset(self, location, model, state):
        rest = location.position(jnp.zeros_like(state.q), jnp.zeros_like(state.w), model)
        return location.position(state.q, state.w, model) - rest

    def read(self, model, state):
        d = self._offset(self.location, model, state)
        if self.reference is not None:
            d = d - self._offset(self.reference, model, state)
        return d[AXES.index(self.axis)]

    def _describe(self):
        ref = None if self.reference is None else self.reference.describe()
        return {"location": self.location.describe(), "axis": self.axis, "reference": ref}


class RateGyro(AbstractSensor):
    """Angular velocity [rad/s] of the bogie frame about a frame (body) axis; `axis="z"` is the
    yaw-rate gyro of a bogie monitoring unit."""

    name: str = eqx.field(static=True)
    axis: str = eqx.field(default="z", static=True)
    noise_std: Float[Array, ""] = eqx.field(default=1e-3, converter=_as_float)
    bias: Float[Array, ""] = eqx.field(default=0.0, converter=_as_float)
    unit: ClassVar[str] = "rad/s"

    def read(self, model, state):
        del model
        omega = kin.frame_body_rates_matrix(state.q[3:6]) @ state.qd[3:6]
        return omega[AXES.index(self.axis)]

    def _describe(self):
        return {"axis": self.axis}


SENSOR_TYPES = {cls.__name__: cls for cls in (Accelerometer, DisplacementSensor, RateGyro)}


def sensor_from_description(d: dict) -> AbstractSensor:
    """Inverse of `AbstractSensor.describe`. **Raises:** `ValueError` naming the problem."""
    if not isinstance(d, dict) or d.get("type") not in SENSOR_TYPES:
        kind = d.get("type") if isinstance(d, dict) else d
        raise ValueError(f"unknown sensor type {kind!r}; valid: {', '.join(SENSOR_TYPES)}")
    cls = SENSOR_TYPES[d["type"]]
    kwargs = {k: v for k, v in d.items() if k not in ("type", "unit")}
    for key in ("location", "reference"):
        if kwargs.get(key) is not None:
            kwargs[key] = location_from_description(kwargs[key])
    if d.get("unit", cls.unit) != cls.unit:
        raise ValueError(
            f"sensor {d.get('name')!r}: unit {d['unit']!r} does not match "
            f"{cls.__name__} ({cls.unit})"
        )
    try:
        return cls(**kwargs)
    except TypeError as e:
        raise ValueError(f"bad description of sensor {d.get('name')!r}: {e}") from None
