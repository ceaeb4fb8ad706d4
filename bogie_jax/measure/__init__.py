"""Sensors on the bogie and measurements (paper section 4.1): accelerations from the equations of
motion, noise and bias with an explicit PRNG key, the default monitoring layout."""

from ._layout import (
    default_sensor_layout as default_sensor_layout,
    layout_description as layout_description,
    sensors_from_layout as sensors_from_layout,
)
from ._locations import (
    AbstractLocation as AbstractLocation,
    Axlebox as Axlebox,
    FramePoint as FramePoint,
    SampleState as SampleState,
    point_motion as point_motion,
    sample_state as sample_state,
)
from ._measurement import (
    Measurement as Measurement,
    MeasurementError as MeasurementError,
    check_measurement as check_measurement,
)
from ._sensors import (
    AbstractSensor as AbstractSensor,
    Accelerometer as Accelerometer,
    DisplacementSensor as DisplacementSensor,
    RateGyro as RateGyro,
)
from ._synthetic import (
    measure as measure,
    readings_from_states as readings_from_states,
    sensor_readings as sensor_readings,
    synthetic_measurement as synthetic_measurement,
)
