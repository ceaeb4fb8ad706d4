"""The default sensor layout of a bogie monitoring system, and layouts <-> JSON text."""

import json

from .._validation import nonempty_tuple
from ..params import BogieParams
from ._locations import Axlebox, FramePoint
from ._sensors import AbstractSensor, Accelerometer, RateGyro, sensor_from_description


def default_sensor_layout(params: BogieParams) -> tuple[AbstractSensor, ...]:
    """13 channels, as a typical on-board bogie monitoring unit has them:

    - `frame_{1,2}{L,R}_{y,z}`: frame lateral (y) and vertical (z) accelerometers on the side
      frames directly above each axlebox (x = +-a, y = +-b_p, at the frame CG height);
    - `frame_yaw_rate`: a yaw-rate gyro on the frame;
    - `axlebox_{1,2}{L,R}_y`: lateral accelerometers on the four axleboxes.

    Wheelset 1 leads; L is the left (+y) side. Positions use the geometry of `params`.
    """
    g = params.geometry
    a, b = float(g.semi_wheelbase), float(g.primary_semi_spacing)
    sensors: list[AbstractSensor] = []
    for ws, x in ((1, a), (2, -a)):
        for side, sign in (("L", 1.0), ("R", -1.0)):
            point = FramePoint(x, sign * b, 0.0)
            sensors += [
                Accelerometer(f"frame_{ws}{side}_{axis}", point, axis) for axis in ("y", "z")
            ]
    sensors.append(RateGyro("frame_yaw_rate", "z"))
    for ws in (1, 2):
        for side, name in (("L", "left"), ("R", "right")):
            sensors.append(Accelerometer(f"axlebox_{ws}{side}_y", Axlebox(ws, name), "y"))
    return tuple(sensors)


def layout_description(sensors) -> str:
    """The layout as one line of JSON (a list of sensor descriptions)."""
    check_sensor_names(sensors)
    return json.dumps([s.describe() for s in sensors], separators=(",", ":"))


def sensors_from_layout(text: str) -> tuple[AbstractSensor, ...]:
    """Inverse of `layout_description`. **Raises:** `ValueError` naming the problem."""
    try:
        items = json.loads(text)
    except json.JSONDecodeError as e:
        raise ValueError(f"sensor layout is not valid JSON: {e}") from None
    if not isinstance(items, list) or not items:
        raise ValueError("sensor layout must be a non-empty JSON list of sensor descriptions")
    sensors = tuple(sensor_from_description(d) for d in items)
    check_sensor_names(sensors)
    return sensors


def check_sensor_names(sensors) -> None:
    """Sensors must be `AbstractSensor`s with unique names."""
    sensors = nonempty_tuple("sensors", sensors, AbstractSensor, "give at least one sensor")
    names = [s.name for s in sensors]
    dups = sorted({n for n in names if names.count(n) > 1})
    if dups:
        raise ValueError(f"sensor names must be unique; repeated: {', '.join(dups)}")
