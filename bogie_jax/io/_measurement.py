"""`Measurement` <-> `.npz` / `.csv`.

CSV format (UTF-8 text, one sample per row):

```
# bogie_jax measurement, format 3
# speed_m_s: 50
# sample_rate_hz: 200
# start_position_m: 0
# track: {"spectrum": "erri-low", "seed": 0, "length_m": 200.0, "band_m": [3.0, 70.0], "file": null}
# note: free text
# layout: [{"type":"Accelerometer","name":"frame_1L_y",...}]
time_s,frame_1L_y[m/s^2],frame_1L_z[m/s^2],frame_yaw_rate[rad/s]
0,0.0123,-0.0456,1.2e-05
0.005,nan,-0.0412,1.1e-05
```

- Lines `# key: value` before the header carry the metadata: `speed_m_s` [m/s] and
  `sample_rate_hz` [Hz] are required; `start_position_m` [m] (track position of the first
  sample, `Measurement.start_position`; format 3) is optional, 0 when absent (files of formats
  1 and 2: their records start where the run started); `track` (one line of JSON,
  `TrackReference.to_dict`), `layout` (one line of JSON, see
  `bogie_jax.measure.layout_description`) and `note` (free text) are optional. Other `#`
  lines and blank lines are ignored.
- Files of format 1 carried the track as free text (e.g. `erri-low seed=0`). It is never parsed:
  such a file loads with `track=None` and the text kept in `note` as `track: <text>`.
- The header is `time_s` followed by one `name[unit]` column per channel.
- Each row: the time [s] and one value per channel; `nan` or an empty cell is a missing sample.
- Times must be strictly increasing and uniformly spaced at `sample_rate_hz`.

The `.npz` holds `times`, `data`, `channels`, `units`, `speed`, `start_position` (format 3;
read as 0 when absent), `track` (the JSON text, or ""), `layout`, `note`, `sample_rate_hz` and
`format`. Loading either rejects wrong shapes, unknown
channels (not in the layout, or not among `sensors`), non-monotone times and mismatched sample
rates with a `MeasurementError` (a `ValueError`) naming the file and the problem.
"""

import json
import math
import os
import re
from pathlib import Path

import numpy as np

from ..measure import Measurement, MeasurementError
from ..measure._layout import layout_description
from ..measure._measurement import check_channels_in_layout, check_times
from ..track import TrackReference


FORMAT = "bogie_jax.measurement/3"
_COLUMN = re.compile(r"^([^\[\],]+)\[([^\[\]]*)\]$")
_REQUIRED_NPZ = ("times", "data", "channels", "units", "speed")
_CSV_KEYS = ("speed_m_s", "sample_rate_hz", "start_position_m", "track", "layout", "note")


def save_measurement(path, measurement: Measurement) -> Path:
    """Write `measurement` to `path` (`.npz` or `.csv` by suffix); returns the path."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".npz", ".csv"):
        raise ValueError(f"`path` must end in .npz or .csv, got {str(path)!r}")
    path.parent.mkdir(parents=True, exist_ok=True)
    m = measurement
    times, data = np.asarray(m.times, dtype=float), np.asarray(m.data, dtype=float)
    if suffix == ".npz":
        np.savez(
            path,
            times=times,
            data=data,
            channels=np.array(m.channels),
            units=np.array(m.units),
            speed=np.asarray(m.speed, dtype=float),
            start_position=np.asarray(m.start_position, dtype=float),
            track=np.array(_track_json(m.track)),
            layout=np.array(m.layout),
            note=np.array(m.note),
            sample_rate_hz=np.array(m.sample_rate),
            format=np.array(FORMAT),
        )
        return path
    with open(path, "w", encoding="utf-8") as f:
        f.write(f"# bogie_jax measurement, format 3\n# speed_m_s: {float(np.asarray(m.speed))!r}\n")
        f.write(f"# sample_rate_hz: {m.sample_rate!r}\n")
        f.write(f"# start_position_m: {float(np.asarray(m.start_position))!r}\n")
        if m.track is not None:
            f.write(f"# track: {_track_json(m.track)}\n")
        if m.layout:
            f.write(f"# layout: {m.layout}\n")
        if m.note:
            f.write(f"# note: {' '.join(m.note.splitlines())}\n")
        f.write(",".join(["time_s"] + [f"{c}[{u}]" for c, u in zip(m.channels, m.units)]) + "\n")
        np.savetxt(f, np.column_stack([times, data]), fmt="%.17g", delimiter=",")
    return path


def load_measurement(path, *, sensors=None, sample_rate: float | None = None) -> Measurement:
    """Read a measurement written by `save_measurement` (or by hand in the CSV format above).

    **Arguments:**
    - `sensors`: optional expected sensors: every channel must be one of them (name and unit);
      a file without a layout gets the layout of these sensors.
    - `sample_rate`: optional expected sample rate [Hz].

    **Raises:** `MeasurementError` naming the file (and line) and the problem.
    """
    name = os.fspath(path)
    suffix = Path(name).suffix.lower()
    if suffix not in (".npz", ".csv"):
        raise MeasurementError(f"{name}: expected a .npz or .csv file")
    try:
        fields, declared_rate = _read_npz(name) if suffix == ".npz" else _read_csv(name)
        check_times(np.asarray(fields["times"], dtype=float), declared_rate)
        if sample_rate is not None:
            check_times(np.asarray(fields["times"], dtype=float), float(sample_rate))
        if sensors is not None:
            sensors = tuple(sensors)
            check_channels_in_layout(fields["channels"], fields["units"], sensors)
            if not fields.get("layout"):
                by_name = {s.name: s for s in sensors}
                fields["layout"] = layout_description([by_name[c] for c in fields["channels"]])
        return Measurement(**fields)
    except MeasurementError as e:
        raise MeasurementError(f"{name}: {e}") from None


def _read_npz(name):
    with np.load(name, allow_pickle=False) as z:
        missing = [k for k in _REQUIRED_NPZ if k not in z.files]
        if missing:
            raise MeasurementError(
                f"missing arrays {', '.join(missing)} (have {', '.join(z.files)})"
            )
        channels, units = z["channels"], z["units"]
        for label, a in (("channels", channels), ("units", units)):
            if a.ndim != 1:
                raise MeasurementError(f"`{label}` must be 1-D, got shape {a.shape}")
        speed = z["speed"]
        if speed.shape != ():
            raise MeasurementError(f"`speed` must be a scalar, got shape {speed.shape}")
        fields = dict(
            times=z["times"].astype(float),
            data=z["data"].astype(float),
            channels=tuple(str(c) for c in channels),
            units=tuple(str(u) for u in units),
            speed=float(speed),
            start_position=_npz_start_position(z),
            layout=str(z["layout"]) if "layout" in z.files else "",
        )
        fields.update(
            _track_fields(
                str(z["track"]) if "track" in z.files else "",
                str(z["note"]) if "note" in z.files else "",
            )
        )
        rate = float(z["sample_rate_hz"]) if "sample_rate_hz" in z.files else None
    if fields["times"].ndim != 1:
        raise MeasurementError(f"`times` must be 1-D, got shape {fields['times'].shape}")
    return fields, rate


def _read_csv(name):
    meta, header, rows, lines = {}, None, [], []
    with open(name, encoding="utf-8") as f:
        for number, line in enumerate(f, start=1):
            text = line.strip()
            if not text:
                continue
            if text.startswith("#"):
                key, sep, value = text[1:].partition(":")
                if header is None and sep and key.strip() in _CSV_KEYS:
                    meta[key.strip()] = value.strip()
                continue
            if header is None:
                header = _parse_header(text, number)
                continue
            rows.append(_parse_row(text, number, len(header) + 1))
            lines.append(number)
    if header is None:
        raise MeasurementError("no header line `time_s,<name>[<unit>],...` found")
    if len(rows) < 2:
        raise MeasurementError(f"expected at least 2 data rows after the header, got {len(rows)}")
    for key in ("speed_m_s", "sample_rate_hz"):
        if key not in meta:
            raise MeasurementError(f"missing metadata line `# {key}: <value>` before the header")
    table = np.asarray(rows)
    fields = dict(
        times=table[:, 0],
        data=table[:, 1:],
        channels=tuple(c for c, _ in header),
        units=tuple(u for _, u in header),
        speed=_number(meta["speed_m_s"], "speed_m_s"),
        start_position=_number(meta.get("start_position_m", "0"), "start_position_m"),
        layout=meta.get("layout", ""),
        **_track_fields(meta.get("track", ""), meta.get("note", "")),
    )
    if not np.all(np.isfinite(fields["times"])):
        i = int(np.flatnonzero(~np.isfinite(fields["times"]))[0])
        raise MeasurementError(f"line {lines[i]}: the time must be a finite number")
    return fields, _number(meta["sample_rate_hz"], "sample_rate_hz")


def _npz_start_position(z) -> float:
    """`start_position` [m] of a format-3 file; 0 for older files (records from the start)."""
    if "start_position" not in z.files:
        return 0.0
    value = z["start_position"]
    if value.shape != ():
        raise MeasurementError(f"`start_position` must be a scalar, got shape {value.shape}")
    return float(value)


def _track_json(track: TrackReference | None) -> str:
    return "" if track is None else json.dumps(track.to_dict())


def _track_fields(text: str, note: str) -> dict:
    """`track` and `note` from the stored track text: JSON of a `TrackReference`, "" (none), or
    the free text of a format-1 file (never parsed: kept in `note`, `track=None`)."""
    text = text.strip()
    if not text:
        return dict(track=None, note=note)
    if text.startswith("{"):
        try:
            return dict(track=TrackReference.from_dict(json.loads(text)), note=note)
        except (json.JSONDecodeError, TypeError, ValueError) as e:
            raise MeasurementError(f"metadata `track` is not a track reference: {e}") from None
    old = f"track: {text}"
    return dict(track=None, note=f"{old}; {note}" if note else old)


def _number(text, key) -> float:
    try:
        return float(text)
    except ValueError:
        raise MeasurementError(f"metadata `{key}` must be a number, got {text!r}") from None


def _parse_header(text, number):
    cells = [c.strip() for c in text.split(",")]
    if cells[0] != "time_s":
        raise MeasurementError(
            f"line {number}: the header must start with `time_s`, got {cells[0]!r}"
        )
    if len(cells) < 2:
        raise MeasurementError(f"line {number}: the header has no channel columns")
    out = []
    for column, cell in enumerate(cells[1:], start=2):
        match = _COLUMN.match(cell)
        if not match:
            raise MeasurementError(
                f"line {number}, column {column}: expected `name[unit]`, got {cell!r}"
            )
        out.append((match.group(1).strip(), match.group(2).strip()))
    return out


def _parse_row(text, number, width):
    cells = [c.strip() for c in text.split(",")]
    if len(cells) != width:
        raise MeasurementError(
            f"line {number}: wrong shape: {len(cells)} columns, the header has {width}"
        )
    row = []
    for column, cell in enumerate(cells, start=1):
        if cell == "" or cell.lower() == "nan":
            row.append(math.nan)
            continue
        try:
            row.append(float(cell))
        except ValueError:
            raise MeasurementError(
                f"line {number}, column {column}: expected a number, got {cell!r}"
            ) from None
    return row
