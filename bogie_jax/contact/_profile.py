"""Wheel and rail profiles read from files: SIMPACK `.prw`/`.prr` and plain CSV of y, z in mm.

A `Profile` holds the points of one cross-section in the file's own frame after the file's
processing flags are applied: y lateral, z **downward** (the SIMPACK and CONTACT convention), both
in metres, sorted by increasing y. Where a profile sits in the track is set apart, by
`ProfileSetup` in `_search.py` (gauge, flange-back spacing, cant, nominal rolling radius).

SIMPACK profile format (as described in the README of `shared/data/profiles`, and in the files'
own headers): `!` starts a comment; `header.begin ... header.end` holds `type` (0 rail, 1
wheel); `spline.begin ... spline.end` holds processing flags (`mirror.y`, `mirror.z`,
`units.len.f` = file length units per metre) and the points between `point.begin` and
`point.end`, one `y z [weight]` per line.
"""

import dataclasses
import pathlib

import numpy as np


WHEEL, RAIL = "wheel", "rail"


class ProfileError(ValueError):
    """A file that is not a usable profile; the message names the file and, where it can, the
    line and the value."""


@dataclasses.dataclass(frozen=True)
class Profile:
    """One wheel or rail cross-section.

    - `y` [m]: lateral coordinates, strictly increasing.
    - `z` [m]: vertical coordinates, positive **downward** (SIMPACK/CONTACT convention).
    - `kind`: `"wheel"` or `"rail"`.
    - `source`: where it came from (a path or a description), for messages.
    """

    y: np.ndarray
    z: np.ndarray
    kind: str
    source: str = "<memory>"

    def __post_init__(self):
        if self.kind not in (WHEEL, RAIL):
            raise ProfileError(f"{self.source}: kind must be 'wheel' or 'rail', got {self.kind!r}")
        y, z = np.asarray(self.y, float), np.asarray(self.z, float)
        if y.ndim != 1 or y.shape != z.shape or y.size < 4:
            raise ProfileError(f"{self.source}: need at least 4 points (y, z), got {y.size}")
        if not (np.all(np.isfinite(y)) and np.all(np.isfinite(z))):
            raise ProfileError(f"{self.source}: a point is not a finite number")
        if np.any(np.diff(y) <= 0):
            i = int(np.argmax(np.diff(y) <= 0))
            raise ProfileError(
                f"{self.source}: y must be strictly monotone along the profile; point {i + 2} "
                f"(y = {1e3 * y[i + 1]:.6g} mm) does not follow point {i + 1} "
                f"(y = {1e3 * y[i]:.6g} mm)"
            )
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "z", z)


def read_profile(path, kind: str | None = None) -> Profile:
    """Read a profile file: `.prw` (wheel), `.prr` (rail), or `.csv` (y, z in mm; `kind` needed).

    **Raises:** `ProfileError` naming the file, and the line or value, for a file that is not a
    profile (no points, a non-numeric value, y not monotone, a wrong or missing type or unit).
    """
    path = pathlib.Path(path)
    suffix = path.suffix.lower()
    if not path.is_file():
        raise ProfileError(f"{path}: no such profile file")
    if suffix in (".prw", ".prr"):
        profile = _read_simpack(path)
        expected = WHEEL if suffix == ".prw" else RAIL
        if profile.kind != expected:
            raise ProfileError(f"{path}: a {suffix} file must hold a {expected} profile")
    elif suffix == ".csv":
        if kind is None:
            raise ProfileError(f"{path}: a CSV profile needs its kind ('wheel' or 'rail')")
        profile = _read_csv(path, kind)
    else:
        raise ProfileError(f"{path}: unknown profile format {suffix!r} (use .prw, .prr or .csv)")
    if kind is not None and profile.kind != kind:
        raise ProfileError(f"{path}: expected a {kind} profile, the file holds a {profile.kind}")
    return profile


def _numbers(text: str, path, lineno: int, count: int) -> list[float]:
    fields = text.replace(",", " ").split()
    if len(fields) < count:
        raise ProfileError(f"{path}, line {lineno}: expected {count} numbers, got {text.strip()!r}")
    try:
        return [float(f) for f in fields[:count]]
    except ValueError:
        raise ProfileError(f"{path}, line {lineno}: not a number in {text.strip()!r}") from None


def _read_simpack(path: pathlib.Path) -> Profile:
    keys: dict[str, tuple[str, int]] = {}
    points, point_lines, inside, section = [], [], False, ""
    for lineno, raw in enumerate(path.read_text(errors="replace").splitlines(), start=1):
        line = raw.split("!", 1)[0].strip()
        if not line:
            continue
        if line.endswith(".begin") and not line.startswith("point."):
            section = line[: -len(".begin")]
        elif line.startswith("point.begin"):
            inside = True
        elif line.startswith("point.end"):
            inside = False
        elif inside:
            points.append(_numbers(line, path, lineno, 2))
            point_lines.append(lineno)
        elif "=" in line:
            key, value = (s.strip() for s in line.split("=", 1))
            if key == "type" and section != "header":
                continue  # `spline.type` is the type of the original data file
            keys[key] = (value.strip("'\""), lineno)
    if not points:
        raise ProfileError(f"{path}: no points between `point.begin` and `point.end`")
    if "type" not in keys:
        raise ProfileError(f"{path}: no `type` in the header (0 = rail, 1 = wheel)")
    kind = {"0": RAIL, "1": WHEEL}.get(keys["type"][0])
    if kind is None:
        raise ProfileError(f"{path}, line {keys['type'][1]}: `type` must be 0 or 1")
    if "units.len.f" not in keys:
        raise ProfileError(f"{path}: no length unit (`units.len.f`, file units per metre)")
    value, lineno = keys["units.len.f"]
    per_metre = _numbers(value, path, lineno, 1)[0]
    if not 0 < per_metre < 1e7:
        raise ProfileError(f"{path}, line {lineno}: `units.len.f` = {value} is not a length unit")
    pts = np.asarray(points) / per_metre
    y, z = pts[:, 0], pts[:, 1]
    if _flag(keys, "mirror.y", path):
        y = -y
    if _flag(keys, "mirror.z", path):
        z = -z
    return _sorted(y, z, kind, path, point_lines)


def _flag(keys, name, path) -> bool:
    if name not in keys:
        return False
    value, lineno = keys[name]
    if value not in ("0", "1"):
        raise ProfileError(f"{path}, line {lineno}: `{name}` must be 0 or 1, got {value!r}")
    return value == "1"


def _sorted(y, z, kind, path, lines) -> Profile:
    """Points ordered by increasing y; the file's order must be monotone (either way)."""
    d = np.diff(y)
    if np.all(d < 0):
        y, z, lines = y[::-1], z[::-1], lines[::-1]
    elif not np.all(d > 0):
        bad = int(np.argmax(d <= 0)) if d[0] > 0 else int(np.argmax(d >= 0))
        raise ProfileError(
            f"{path}, line {lines[bad + 1]}: y = {1e3 * y[bad + 1]:.6g} mm breaks the monotone "
            f"order of the points (previous y = {1e3 * y[bad]:.6g} mm)"
        )
    return Profile(y=y, z=z, kind=kind, source=str(path))


def _read_csv(path: pathlib.Path, kind: str) -> Profile:
    """Plain CSV: optional header line(s) (any non-numeric first field), then `y, z` in mm, z
    downward. A header that names a unit must say mm."""
    points, lines = [], []
    for lineno, raw in enumerate(path.read_text(errors="replace").splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        first = line.replace(";", ",").split(",")[0].strip()
        try:
            float(first)
        except ValueError:
            if points:
                raise ProfileError(f"{path}, line {lineno}: not a number in {line!r}") from None
            lower = line.lower()
            if ("[m]" in lower or "(m)" in lower) and "mm" not in lower:
                raise ProfileError(
                    f"{path}, line {lineno}: CSV profiles are in mm, header {line!r}"
                )
            continue
        points.append(_numbers(line.replace(";", ","), path, lineno, 2))
        lines.append(lineno)
    if not points:
        raise ProfileError(f"{path}: no points (expected lines `y, z` in mm)")
    pts = np.asarray(points) * 1e-3
    return _sorted(pts[:, 0], pts[:, 1], kind, path, lines)


def write_csv(profile: Profile, path) -> None:
    """Write `profile` as a CSV of y, z in mm (z downward), readable by `read_profile`."""
    rows = "\n".join(f"{1e3 * a:.9f},{1e3 * b:.9f}" for a, b in zip(profile.y, profile.z))
    pathlib.Path(path).write_text(f"y [mm],z [mm] (downward)\n{rows}\n")
