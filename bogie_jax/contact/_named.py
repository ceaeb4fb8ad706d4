"""Named wheel/rail profile pairs shipped with the package, each with its set-up.

- `"s1002-uic60"`: new S1002 wheel on new UIC60 rail inclined 1:40 (the file is already
  inclined), gauge 1435 mm at 14 mm, flange-back spacing 1360 mm, r0 = 0.46 m: the Manchester
  Contact Benchmark (Shackleton and Iwnicki, VSD 46, 2008).
- `"worn-uic60"`: the measured worn wheel of `profiles/` on the same rail and track; its y
  origin is taken as the flange back (its first point lies 3.9 mm from it, on the flange root).
- `"half-worn-uic60"`: a wheel halfway between the two on the same rail and track: at every
  distance from the flange back, its height relative to the running circle is the mean of the
  new and the worn wheel's (on the worn wheel's points, the S1002 interpolated by its cubic
  spline). The profiles are averaged, not their contact tables: the contact geometry is not
  linear in the profile, so this wheel lies outside the family that blending the two tables
  spans (`WheelWear`), a wheel whose wear that family does not hold exactly.

A measured wheel (`measured_wheel(path, flange_back)`: a profile file, e.g. from a depot's
profilometer) runs on the same UIC60 1:40 rail and track as the pairs above; its contact name
carries the flange back's position in the file's frame, a digest of the file's bytes and its
absolute path, so that every process builds the same table from it and a program compiled for
one measurement is never reused for another.

The files are unchanged copies from the CONTACT package (Apache-2.0), see `profiles/README.md`.
"""

import dataclasses
import functools
import hashlib
import importlib.resources
import pathlib

import numpy as np
from scipy.interpolate import CubicSpline

from ..params import MEASURED_WHEEL as MEASURED
from ._placement import RUNNING_CIRCLE_OFFSET, ProfileSetup, place_profiles
from ._profile import WHEEL, Profile, ProfileError, read_profile
from ._search import ContactTable, contact_table


_FILES = {
    "s1002-uic60": ("MBench_S1002_v3.prw", "MBench_UIC60_v3.prr", ProfileSetup()),
    "worn-uic60": ("worn_high_mileage.prw", "MBench_UIC60_v3.prr", ProfileSetup(flange_back=0.0)),
}
_HALFWAY = {"half-worn-uic60": ("s1002-uic60", "worn-uic60")}
PROFILE_PAIRS = (*_FILES, *_HALFWAY)
"""Names of the shipped profile pairs."""


def measured_wheel(path, flange_back: float = -0.070) -> str:
    """The contact name of a measured wheel profile on the shipped UIC60 1:40 rail (gauge
    1435 mm, flange-back spacing 1360 mm, r0 = 0.46 m), for `BogieParams.contact_geometry`
    (`manchester_benchmark(contact=...)`).

    - `path`: a wheel profile file (`.prw`, or `.csv` of y, z in mm; `read_profile`).
    - `flange_back` [m], in [-0.5, 0.5]: y of the flange back in the file's frame (-0.070 for
      the S1002 file; 0 where the file's origin is the flange back).

    **Raises:** `ProfileError` (a `ValueError`) for a file that is not a wheel profile or a
    `flange_back` outside its range, before any table is built."""
    path = pathlib.Path(path).resolve()
    read_profile(path, kind=WHEEL)
    ProfileSetup(flange_back=flange_back)  # checks the range
    return f"{MEASURED}{float(flange_back)!r}:{_digest(path)}:{path}"


def _digest(path: pathlib.Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]


def _measured_pair(name: str) -> tuple[Profile, Profile, ProfileSetup]:
    flange_back, digest, path = name[len(MEASURED) :].split(":", 2)
    if not pathlib.Path(path).is_file() or _digest(pathlib.Path(path)) != digest:
        raise ProfileError(f"{path}: missing or changed since `measured_wheel` read it")
    rail = read_profile(shipped_profile(_FILES["s1002-uic60"][1]))
    setup = dataclasses.replace(_FILES["s1002-uic60"][2], flange_back=float(flange_back))
    return read_profile(path, kind=WHEEL), rail, setup


def shipped_profile(filename: str):
    """Path of a profile file shipped in `bogie_jax/contact/profiles/`."""
    return importlib.resources.files(__package__) / "profiles" / filename


def profile_pair(name: str) -> tuple[Profile, Profile, ProfileSetup]:
    """The wheel, the rail and the set-up of a named pair (`PROFILE_PAIRS`) or of a measured
    wheel (`measured_wheel`)."""
    if name.startswith(MEASURED):
        return _measured_pair(name)
    if name in _HALFWAY:
        return _halfway_pair(*_HALFWAY[name])
    if name not in _FILES:
        raise ValueError(f"unknown profile pair {name!r}; choose one of {', '.join(PROFILE_PAIRS)}")
    wheel, rail, setup = _FILES[name]
    return read_profile(shipped_profile(wheel)), read_profile(shipped_profile(rail)), setup


def _halfway_pair(first: str, second: str) -> tuple[Profile, Profile, ProfileSetup]:
    """The wheel halfway between the wheels of two pairs on one rail (module docstring), on the
    second wheel's points within both profiles' span; set up with its flange back at y = 0."""
    (wheel_a, rail, setup), (wheel_b, _, setup_b) = profile_pair(first), profile_pair(second)
    u_a, z_a = _from_flange_back(wheel_a, setup)
    u_b, z_b = _from_flange_back(wheel_b, setup_b)
    inside = (u_b >= u_a[0]) & (u_b <= u_a[-1])
    spline_a = CubicSpline(u_a, z_a)
    z = 0.5 * (spline_a(u_b[inside]) + z_b[inside])
    wheel = Profile(y=u_b[inside], z=z, kind=WHEEL, source=f"halfway between {first}, {second}")
    return wheel, rail, dataclasses.replace(setup, flange_back=0.0)


def _from_flange_back(wheel: Profile, setup: ProfileSetup) -> tuple[np.ndarray, np.ndarray]:
    """Distance from the flange back [m] and height below the running circle [m] (z down)."""
    u = wheel.y - setup.flange_back
    return u, wheel.z - float(np.interp(RUNNING_CIRCLE_OFFSET, u, wheel.z))


@functools.lru_cache(maxsize=8)
def named_contact_table(name: str, max_lateral: float = 0.012, step: float = 1e-4) -> ContactTable:
    """The contact table of a named pair or a measured wheel (computed once per process, a
    few seconds)."""
    wheel, rail, setup = profile_pair(name)
    return contact_table(place_profiles(wheel, rail, setup), max_lateral=max_lateral, step=step)
