"""Where the wheel and rail profiles sit: track gauge and its measuring height, flange-back
spacing, rail cant, nominal rolling radius (outside `jit`, numpy and scipy).

Frames. Track: y to the left, z up, origin on the track centreline at the height of the rail top
(the docs/model.md track axes). Wheelset: the same axes carried by the wheelset centre, before
its roll. Profiles are given for the **right** side of the track in their files' frame (y towards
the field side, z downward: SIMPACK/CONTACT convention); the left side is their mirror image
(the wheelset and track are symmetric).

Set-up of the Manchester Contact Benchmark (Shackleton and Iwnicki, Vehicle System Dynamics 46,
2008; the README of `shared/data/profiles`): gauge 1435 mm measured 14 mm below the rail top,
flange-back spacing 1360 mm, rolling radius 460 mm, S1002 on UIC60 inclined 1:40. The S1002 file
holds the flange back at y = -70 mm after its `mirror.y` flag (the running circle 70 mm from the
flange back at y = 0, EN 13715's running-circle position).
"""

import bisect
import dataclasses

import numpy as np
from scipy.interpolate import CubicSpline

from ._profile import Profile, ProfileError


RUNNING_CIRCLE_OFFSET = 0.070
"""Distance of the running (nominal rolling) circle from the flange back [m] (EN 13715)."""


@dataclasses.dataclass(frozen=True)
class ProfileSetup:
    """Track and wheelset geometry that places the profiles (SI units).

    - `gauge` [m], in (1.0, 2.0): distance between the rails' gauge points.
    - `gauge_height` [m], in [0, 0.03]: depth of the gauge points below the rail top.
    - `flange_back_spacing` [m], in (0.9, 1.9): distance between the wheels' flange backs.
    - `rail_cant` [rad], in [-0.1, 0.1]: rotation applied to the rail profile, positive turning
      its top towards the track centre (atan(1/40) for an upright 1:40 rail; 0 for a file that
      is already inclined, as the Manchester UIC60).
    - `wheel_radius` [m], in (0.1, 2.0): rolling radius at the running circle.
    - `flange_back` [m]: y of the flange back in the wheel file's frame (-0.070 for S1002).
    - `max_rail_slope` [-]: rail points steeper than this (the gauge and field faces) are left
      out of the contact search (a wheel does not touch them from above within the table).
    """

    gauge: float = 1.435
    gauge_height: float = 0.014
    flange_back_spacing: float = 1.360
    rail_cant: float = 0.0
    wheel_radius: float = 0.46
    flange_back: float = -0.070
    max_rail_slope: float = 10.0

    def __post_init__(self):
        checks = {
            "gauge": (1.0, 2.0),
            "gauge_height": (0.0, 0.03),
            "flange_back_spacing": (0.9, 1.9),
            "rail_cant": (-0.1, 0.1),
            "wheel_radius": (0.1, 2.0),
            "flange_back": (-0.5, 0.5),
            "max_rail_slope": (1.0, 100.0),
        }
        for name, (lo, hi) in checks.items():
            value = getattr(self, name)
            if not lo <= value <= hi:
                raise ProfileError(f"`ProfileSetup.{name}` = {value:g} is outside [{lo:g}, {hi:g}]")
        if self.flange_back_spacing >= self.gauge:
            raise ProfileError(
                f"`ProfileSetup.flange_back_spacing` = {self.flange_back_spacing:g} m must be "
                f"smaller than the gauge {self.gauge:g} m"
            )


class Spline:
    """A C2 cubic interpolating spline Z(Y) (scipy's `CubicSpline`, not-a-knot ends), evaluated by
    Horner's rule with less call overhead than scipy's, value or derivative `nu` = 0, 1, 2."""

    def __init__(self, y, z):
        pp = CubicSpline(y, z)
        self.breaks = np.asarray(pp.x)
        self.coefficients = np.asarray(pp.c)  # (4, n - 1), highest power first
        self._breaks_list = self.breaks.tolist()
        self._rows = self.coefficients.T.tolist()

    def __call__(self, x, nu: int = 0):
        if np.ndim(x) == 0:  # scalar fast path (the refinement loops)
            x = float(x)
            i = min(max(bisect.bisect_right(self._breaks_list, x) - 1, 0), len(self._rows) - 1)
            t = x - self._breaks_list[i]
            a, b, c, d = self._rows[i]
        else:
            x = np.asarray(x, float)
            i = np.searchsorted(self.breaks, x) - 1
            i = np.minimum(np.maximum(i, 0), self.breaks.size - 2)
            t = x - self.breaks[i]
            a, b, c, d = self.coefficients[:, i]
        if nu == 0:
            return ((a * t + b) * t + c) * t + d
        if nu == 1:
            return (3 * a * t + 2 * b) * t + c
        return 6 * a * t + 2 * b


@dataclasses.dataclass(frozen=True)
class PlacedProfiles:
    """Left wheel (wheelset frame) and left rail (track frame) as C2 cubic splines, z up.

    - `wheel`: Z(Y) of the wheel surface relative to the wheelset centre, Y from the centre [m].
    - `rail`: Z(Y) of the rail surface in track axes [m].
    - `wheel_span`, `rail_span`: the Y range of each spline [m].
    """

    wheel: Spline
    rail: Spline
    wheel_span: tuple[float, float]
    rail_span: tuple[float, float]
    setup: ProfileSetup


def place_profiles(wheel: Profile, rail: Profile, setup: ProfileSetup) -> PlacedProfiles:
    """Splines of the left wheel and rail in the wheelset and track frames (see module doc)."""
    if wheel.kind != "wheel" or rail.kind != "rail":
        raise ProfileError(
            f"need a wheel and a rail profile, got {wheel.kind} ({wheel.source}) and "
            f"{rail.kind} ({rail.source})"
        )
    wheel_spline, wheel_span = _place_wheel(wheel, setup)
    rail_spline, rail_span = _place_rail(rail, setup)
    return PlacedProfiles(wheel_spline, rail_spline, wheel_span, rail_span, setup)


def _place_wheel(wheel: Profile, setup: ProfileSetup):
    nominal = setup.flange_back + RUNNING_CIRCLE_OFFSET
    if not wheel.y[0] <= nominal <= wheel.y[-1]:
        raise ProfileError(
            f"{wheel.source}: the running circle y = {1e3 * nominal:g} mm (flange back "
            f"{1e3 * setup.flange_back:g} mm + 70 mm) is outside the profile "
            f"[{1e3 * wheel.y[0]:g}, {1e3 * wheel.y[-1]:g}] mm"
        )
    z_nominal = float(np.interp(nominal, wheel.y, wheel.z))
    big_y = 0.5 * setup.flange_back_spacing + (wheel.y - setup.flange_back)
    big_z = -(wheel.z - z_nominal) - setup.wheel_radius
    return Spline(big_y, big_z), (float(big_y[0]), float(big_y[-1]))


def _place_rail(rail: Profile, setup: ProfileSetup):
    c, s = np.cos(setup.rail_cant), np.sin(setup.rail_cant)
    y = c * rail.y + s * rail.z  # rotation turning the top's upward normal to the centre (-y)
    z = -s * rail.y + c * rail.z
    if np.any(np.diff(y) <= 0):
        raise ProfileError(f"{rail.source}: y is not monotone after the cant {setup.rail_cant:g}")
    top = int(np.argmin(z))
    depth = z[top] + setup.gauge_height
    inner = np.nonzero(z[: top + 1] >= depth)[0]
    if inner.size == 0:
        raise ProfileError(
            f"{rail.source}: the rail does not reach {1e3 * setup.gauge_height:g} mm below its "
            "top on the gauge side (y below the top): no gauge point"
        )
    i = int(inner[-1])
    y_gauge = y[i] + (depth - z[i]) * (y[i + 1] - y[i]) / (z[i + 1] - z[i])
    slope = np.abs(np.gradient(z, y))
    lo, hi = top, top
    while lo > 0 and slope[lo - 1] <= setup.max_rail_slope:
        lo -= 1
    while hi < y.size - 1 and slope[hi + 1] <= setup.max_rail_slope:
        hi += 1
    if hi - lo < 4:
        raise ProfileError(f"{rail.source}: fewer than 5 points on the rail head near its top")
    big_y = 0.5 * setup.gauge + (y[lo : hi + 1] - y_gauge)
    big_z = -(z[lo : hi + 1] - z[top])
    return Spline(big_y, big_z), (float(big_y[0]), float(big_y[-1]))
