"""Named wheel/rail profile pairs shipped with the package, each with its set-up.

- `"s1002-uic60"`: new S1002 wheel on new UIC60 rail inclined 1:40 (the file is already
  inclined), gauge 1435 mm at 14 mm, flange-back spacing 1360 mm, r0 = 0.46 m: the Manchester
  Contact Benchmark (Shackleton and Iwnicki, VSD 46, 2008).
- `"worn-uic60"`: the measured worn wheel of `profiles/` on the same rail and track; its y
  origin is taken as the flange back (its first point lies 3.9 mm from it, on the flange root).

The files are unchanged copies from the CONTACT package (Apache-2.0), see `profiles/README.md`.
"""

import functools
import importlib.resources

from ._placement import ProfileSetup, place_profiles
from ._profile import Profile, read_profile
from ._search import ContactTable, contact_table


_FILES = {
    "s1002-uic60": ("MBench_S1002_v3.prw", "MBench_UIC60_v3.prr", ProfileSetup()),
    "worn-uic60": ("worn_high_mileage.prw", "MBench_UIC60_v3.prr", ProfileSetup(flange_back=0.0)),
}
PROFILE_PAIRS = tuple(_FILES)
"""Names of the shipped profile pairs."""


def shipped_profile(filename: str):
    """Path of a profile file shipped in `bogie_jax/contact/profiles/`."""
    return importlib.resources.files(__package__) / "profiles" / filename


def profile_pair(name: str) -> tuple[Profile, Profile, ProfileSetup]:
    """The wheel, the rail and the set-up of a named pair (`PROFILE_PAIRS`)."""
    if name not in _FILES:
        raise ValueError(f"unknown profile pair {name!r}; choose one of {', '.join(_FILES)}")
    wheel, rail, setup = _FILES[name]
    return read_profile(shipped_profile(wheel)), read_profile(shipped_profile(rail)), setup


@functools.lru_cache(maxsize=8)
def named_contact_table(name: str, max_lateral: float = 0.012, step: float = 1e-4) -> ContactTable:
    """The contact table of a named pair (computed once per process, a few seconds)."""
    wheel, rail, setup = profile_pair(name)
    return contact_table(place_profiles(wheel, rail, setup), max_lateral=max_lateral, step=step)
