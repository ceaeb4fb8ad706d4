"""The fleet inventory: a TOML file naming every bogie, its vehicle parameter set, its sensor
layout and its measurement files by date (`docs/fleet.md` has the format).

TOML, not CSV: one bogie has several dated measurements, each of several files and track
records; TOML holds that nesting (arrays of tables) with comments and real date literals, and
Python reads it with the standard library (`tomllib`). A CSV would need one row per file and
a convention for grouping rows.

`read_inventory` checks everything that can be checked without a fit (missing files, repeated
ids or dates, unparsable dates, unknown vehicles, layouts and element names, a track count
that fits neither one-for-all nor one-per-file, a wheel profile that is not one) and raises
`InventoryError` naming the file, the bogie and the value.
"""

import dataclasses
import datetime
import math
import re
import tomllib
from pathlib import Path

from ..contact import measured_wheel
from ..params import PARAMETER_SETS, PROFILE_SET, resolve_parameter
from ..sensitivity import LAYOUTS
from ._values import BogieEntry, Inventory, MonitorSettings, Visit


INVENTORY_FORMAT = "bogie_jax.fleet/1"
_ISO_DATE = re.compile(r"\d{4}-\d{2}-\d{2}")


class InventoryError(ValueError):
    """A fleet inventory that cannot be run (one line naming the file and the problem)."""


def read_inventory(path) -> Inventory:
    """Read and check the inventory TOML at `path` (relative file names are relative to it).

    **Raises:** `InventoryError` (one line, naming the file and the problem)."""
    path = Path(path)
    if not path.is_file():
        raise InventoryError(f"inventory {str(path)!r} does not exist")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise InventoryError(f"{path}: not a TOML file ({e})") from None
    fmt = data.get("format")
    if fmt != INVENTORY_FORMAT:
        raise InventoryError(f"{path}: `format` = {fmt!r} must be {INVENTORY_FORMAT!r}")
    _check_keys(
        f"{path}: unknown top-level key(s)", data, ("format", "defaults", "monitor", "bogie")
    )
    defaults = _table(path, data, "defaults")
    settings = _settings(path, _table(path, data, "monitor"), defaults.get("vehicle"))
    rows = data.get("bogie")
    if not isinstance(rows, list) or not rows:
        raise InventoryError(f"{path}: no `[[bogie]]` tables: the inventory names no bogie")
    bogies = tuple(_bogie(path, k, row, defaults) for k, row in enumerate(rows))
    _check_unique(path, [b.id for b in bogies], "bogie id")
    return Inventory(str(path.resolve()), settings, bogies)


def _table(path, data, key) -> dict:
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise InventoryError(f"{path}: `{key}` must be a table ([{key}])")
    return value


def _check_unique(path, values, what) -> None:
    seen = set()
    for v in values:
        if v in seen:
            raise InventoryError(f"{path}: {what} {v!r} appears twice: each must be unique")
        seen.add(v)


def _check_keys(what: str, table: dict, valid) -> None:
    """`InventoryError` "`what` K1, K2; valid: ..." when `table` has keys outside `valid`."""
    extra = set(table) - set(valid)
    if extra:
        raise InventoryError(f"{what} {', '.join(sorted(extra))}; valid: {', '.join(valid)}")


def _settings(path, table, vehicle) -> MonitorSettings:
    known = sorted(f.name for f in dataclasses.fields(MonitorSettings))
    _check_keys(f"{path}: unknown key(s) in [monitor]:", table, known)
    where = f"{path}: [monitor]"
    alpha = _number(where, table, "false_alarm_rate", 0.05, 0.0, 0.5, "in (0, 0.5)", open_lo=True)
    track = _number(where, table, "track_error_mm", 0.0, 0.0, 10.0, "in [0, 10] mm")
    band = table.get("band")
    if band is not None:
        band = _number(where, table, "band", None, 0.0, 1.0, "in (0, 1)", open_lo=True)
    candidates = table.get("candidates", [])
    if not isinstance(candidates, list) or not all(isinstance(c, str) for c in candidates):
        raise InventoryError(f"{path}: [monitor] `candidates` must be a list of element names")
    params = PARAMETER_SETS[vehicle if vehicle in PARAMETER_SETS else "manchester"]()
    for name in candidates:
        try:
            resolve_parameter(params, name)
        except ValueError as e:
            raise InventoryError(f"{path}: [monitor] `candidates`: {e}") from None
    _check_unique(path, candidates, "candidate")
    return MonitorSettings(alpha, track, band, tuple(candidates))


def _number(where, table, key, default, lo, hi, valid, *, open_lo=False) -> float:
    value = table.get(key, default)
    ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    ok = ok and math.isfinite(value) and (lo < value if open_lo else lo <= value) and value < hi
    if not ok:
        raise InventoryError(f"{where}: `{key}` = {value!r} must be a number {valid}")
    return float(value)


def _bogie(path, k, row, defaults) -> BogieEntry:
    where = f"{path}: bogie {k + 1}"
    if not isinstance(row, dict):
        raise InventoryError(f"{where}: must be a table [[bogie]]")
    _check_keys(f"{where}: unknown key(s)", row, ("id", "vehicle", "layout", "measurement"))
    bogie_id = row.get("id")
    if not isinstance(bogie_id, str) or not bogie_id.strip():
        raise InventoryError(f"{where}: `id` = {bogie_id!r} must be a non-empty string")
    where = f"{path}: bogie {bogie_id!r}"
    vehicle = row.get("vehicle", defaults.get("vehicle", "manchester"))
    if vehicle not in PARAMETER_SETS:
        raise InventoryError(
            f"{where}: `vehicle` = {vehicle!r} must be one of {', '.join(PARAMETER_SETS)}"
        )
    layout = row.get("layout", defaults.get("layout", "default"))
    if layout not in LAYOUTS:
        raise InventoryError(f"{where}: `layout` = {layout!r} must be one of {', '.join(LAYOUTS)}")
    items = row.get("measurement")
    if not isinstance(items, list) or not items:
        raise InventoryError(f"{where}: no `[[bogie.measurement]]`: give at least one")
    visits = [_visit(path, where, j, item, vehicle) for j, item in enumerate(items)]
    _check_unique(path, [v.date for v in visits], f"bogie {bogie_id!r}: measurement date")
    visits.sort(key=lambda v: v.date)
    return BogieEntry(bogie_id, vehicle, layout, tuple(visits))


def _visit(path, where, j, item, vehicle) -> Visit:
    where = f"{where}, measurement {j + 1}"
    if not isinstance(item, dict):
        raise InventoryError(f"{where}: must be a table [[bogie.measurement]]")
    keys = ("date", "files", "tracks", "wheel_profile", "flange_back_mm")
    _check_keys(f"{where}: unknown key(s)", item, keys)
    date = _date(where, item.get("date"))
    files = _paths(path, where, item.get("files"), "files", required=True)
    tracks = _paths(path, where, item.get("tracks", []), "tracks", required=False)
    if len(tracks) not in (0, 1, len(files)):
        raise InventoryError(
            f"{where}: {len(tracks)} `tracks` for {len(files)} `files`: give none (each file's "
            "track reference), one for all, or one per file"
        )
    return Visit(date, files, tracks, _contact(path, where, item, vehicle))


def _contact(path, where, item, vehicle) -> str:
    """The visit's contact: `"cone"`, or the contact name of its `wheel_profile` file with its
    flange back at `flange_back_mm` [mm] in the file's frame (default -70, as the S1002 file)."""
    if "wheel_profile" not in item:
        if "flange_back_mm" in item:
            raise InventoryError(f"{where}: `flange_back_mm` goes with `wheel_profile`")
        return "cone"
    if vehicle != PROFILE_SET:
        raise InventoryError(
            f"{where}: `wheel_profile` needs vehicle = {PROFILE_SET!r} (the set whose "
            f"wheels the rail profiles fit), got {vehicle!r}"
        )
    if not isinstance(item["wheel_profile"], str):
        raise InventoryError(f"{where}: `wheel_profile` must be a file name")
    (wheel,) = _paths(path, where, [item["wheel_profile"]], "wheel_profile", required=True)
    flange_back = _number(where, item, "flange_back_mm", -70.0, -500.0, 500.0, "in [-500, 500)")
    try:
        return measured_wheel(wheel, 1e-3 * flange_back)
    except ValueError as e:  # ProfileError: not a wheel profile
        raise InventoryError(f"{where}: `wheel_profile`: {e}") from None


def _date(where, value) -> str:
    """A TOML date (YYYY-MM-DD) or the same as quoted text, as ISO text."""
    if isinstance(value, datetime.datetime):
        return value.date().isoformat()
    if isinstance(value, datetime.date):
        return value.isoformat()
    if isinstance(value, str) and _ISO_DATE.fullmatch(value):
        try:
            return datetime.date.fromisoformat(value).isoformat()
        except ValueError:
            pass
    raise InventoryError(f"{where}: `date` = {value!r} is not a date YYYY-MM-DD")


def _paths(path, where, value, key, *, required) -> tuple[str, ...]:
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise InventoryError(f"{where}: `{key}` must be a list of file names")
    if required and not value:
        raise InventoryError(f"{where}: `{key}` is empty: give at least one measurement file")
    out = []
    for name in value:
        full = (path.parent / name).resolve()
        if not full.is_file():
            raise InventoryError(f"{where}: `{key}` file {name!r} does not exist ({full})")
        out.append(str(full))
    return tuple(out)
