"""Judge one bogie on one date from its measurement files: the fleet's one call of
`bogie_jax.monitor.monitor`. Returns the `verdicts.json` record (`bogie_jax.io`), the same
object `bogie-jax monitor --data` writes and `fleet import` reads."""

from ..io import load_measurement, load_run_tracks, verdicts_record
from ..monitor import MonitorOptions, monitor
from ..sensitivity import sensor_layouts
from ._task import JudgeTask


def _monitor_options(s) -> MonitorOptions:
    """`monitor`'s options for the fleet's settings."""
    return MonitorOptions(
        candidates=s.candidates or None,
        band=s.band,
        false_alarm_rate=s.false_alarm_rate,
        track_error=1e-3 * s.track_error_mm,
    )


def judge_visit(task: JudgeTask) -> dict:
    """The `verdicts.json` record of `task`'s bogie and date (with `bogie_id`, `vehicle`,
    `layout`, `data` and `contact`). **Raises:** what reading the files and `monitor` raise."""
    params = task.params()
    sensors = sensor_layouts(params)[task.layout]
    measurements = [load_measurement(f, sensors=sensors) for f in task.files]
    tracks = load_run_tracks(task.files, measurements, task.tracks)
    result = monitor(measurements, tracks, params=params, options=_monitor_options(task.settings))
    source = f"bogie-jax fleet run: {task.bogie_id} on {task.date}"
    return verdicts_record(
        result, date=task.date, source=source, bogie_id=task.bogie_id, vehicle=task.vehicle,
        layout=task.layout, data=list(task.files), contact=task.contact,
    )  # fmt: skip
