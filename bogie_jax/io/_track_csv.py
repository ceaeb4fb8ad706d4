"""Track irregularities <-> CSV.

Format (UTF-8 text, one sample per row):

```
# optional comment lines start with '#', anywhere; blank lines are ignored
distance_m,alignment_m,vertical_m,cross_level_rad
0.0,0.0,0.0,0.0
0.25,1.2e-05,-3.1e-06,4.0e-06
...
```

- The first line that is not a comment or blank is the header, exactly these four names.
- Then at least 2 rows of 4 finite numbers: distance [m] (strictly increasing, uniformly spaced
  within a relative tolerance of 1e-6), lateral alignment `d_y` [m], vertical level `d_z` [m],
  cross-level angle `gamma_d` [rad] (positive = left rail higher).

Errors are `ValueError`s naming the file, the line (1-based) and, where relevant, the column.
"""

import os

import numpy as np

from ..track import TrackIrregularity, TrackReference, TrackSampleError


HEADER = ("distance_m", "alignment_m", "vertical_m", "cross_level_rad")


def save_track_csv(path: str | os.PathLike, track: TrackIrregularity) -> None:
    """Write `track` to `path` in the format of this module (17 significant digits)."""
    distance = np.asarray(track.distance(), dtype=float)
    values = np.asarray(track.values, dtype=float)
    table = np.column_stack([distance, values])
    with open(path, "w", encoding="utf-8") as f:
        f.write("# bogie_jax track irregularity; SI units, cross level as an angle\n")
        f.write(",".join(HEADER) + "\n")
        np.savetxt(f, table, fmt="%.17g", delimiter=",")


def load_track_csv(path: str | os.PathLike) -> TrackIrregularity:
    """Read a track written in the format of this module.

    **Raises:** `ValueError` naming the file, line and column of the first problem.
    """
    rows, line_numbers = _read_rows(path)
    table = np.asarray(rows, dtype=float)
    try:
        return TrackIrregularity.from_samples(table[:, 0], table[:, 1:])
    except TrackSampleError as e:
        where = f"line {line_numbers[e.row]}: " if e.row is not None else ""
        raise ValueError(f"{os.fspath(path)}: {where}{e}") from None


def _read_rows(path) -> tuple[list[list[float]], list[int]]:
    """Parse header and numeric rows; return the rows and their 1-based line numbers."""
    name = os.fspath(path)
    rows, line_numbers, header_seen = [], [], False
    with open(path, encoding="utf-8") as f:
        for number, line in enumerate(f, start=1):
            text = line.strip()
            if not text or text.startswith("#"):
                continue
            cells = [c.strip() for c in text.split(",")]
            if not header_seen:
                if tuple(cells) != HEADER:
                    raise ValueError(
                        f"{name}: line {number}: expected the header {','.join(HEADER)!r}; "
                        f"got {text!r}"
                    )
                header_seen = True
                continue
            rows.append(_parse_row(name, number, cells))
            line_numbers.append(number)
    if not header_seen:
        raise ValueError(f"{name}: expected the header {','.join(HEADER)!r}; found no data")
    if len(rows) < 2:
        raise ValueError(f"{name}: expected at least 2 data rows after the header; got {len(rows)}")
    return rows, line_numbers


def _parse_row(name: str, number: int, cells: list[str]) -> list[float]:
    if len(cells) != len(HEADER):
        raise ValueError(
            f"{name}: line {number}: expected {len(HEADER)} columns ({','.join(HEADER)}); "
            f"got {len(cells)}"
        )
    row = []
    for column, (cell, label) in enumerate(zip(cells, HEADER), start=1):
        try:
            value = float(cell)
        except ValueError:
            value = None
        if value is None or not np.isfinite(value):
            raise ValueError(
                f"{name}: line {number}, column {column} ({label}): expected a finite number; "
                f"got {cell!r}"
            )
        row.append(value)
    return row


def load_track(reference: TrackReference) -> TrackIrregularity:
    """The track of `reference`: its CSV file, or the synthetic track it describes."""
    if reference.file is None:
        return reference.build()
    if not os.path.isfile(reference.file):
        raise ValueError(f"`track` file {reference.file!r} does not exist")
    return load_track_csv(reference.file)


def load_run_tracks(data_files, measurements, track_files=None) -> list[TrackIrregularity]:
    """One track per measured run: `track_files` (CSV; one for all runs or one per run), or else
    each measurement's own track reference (`data_files` name the runs in the errors).

    **Raises:** `ValueError` for a wrong number of track files, a run without a track
    reference, and what `load_track_csv` raises."""
    if track_files:
        if len(track_files) not in (1, len(measurements)):
            raise ValueError(
                f"{len(track_files)} track files for {len(measurements)} runs: give one for all "
                "runs or one per run"
            )
        files = list(track_files) * len(measurements) if len(track_files) == 1 else track_files
        return [load_track_csv(f) for f in files]
    tracks = []
    for f, m in zip(data_files, measurements):
        if m.track is None:
            raise ValueError(f"{f!r} stores no track reference: give its track file")
        tracks.append(load_track(m.track))
    return tracks
