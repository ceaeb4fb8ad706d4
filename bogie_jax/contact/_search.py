"""Contact search over the wheelset's lateral displacement: the contact table (outside `jit`).

For a rigid wheelset on rigid rails (no penetration) the contact point of each wheel is where
the vertical gap between the wheel and the rail surfaces is smallest; there the two surfaces
have the same slope (a common tangent), so the minimum-vertical-gap search is exact for rigid
profiles, not an approximation (the classic 2-D contact-geometry tabulation, e.g. Shackleton and
Iwnicki, VSD 46 (2008), the Manchester Contact Benchmark, part 1).

For a lateral displacement y the wheelset's roll phi and centre height h follow from both wheels
touching: with d(y, phi) the smallest vertical gap of the left wheel at h = 0, the right side's
is d(-y, -phi) (mirror symmetry), and phi solves d(y, phi) = d(-y, -phi); then h = -d(y, phi).
The gap is first minimised on a grid over the rail head (global: it finds a jump of the contact
point to another part of the profile, e.g. the flange root), then refined by a root of its
derivative on the splines (C2), so positions are exact to rounding.
"""

import dataclasses

import numpy as np
from scipy.optimize import brentq

from ._placement import PlacedProfiles
from ._profile import ProfileError


GRID_STEP = 5e-5
"""Spacing of the global minimum search over the rail head [m]."""

COLUMNS = (
    ("rolling_radius", "m", "rolling radius of each wheel at its contact point"),
    ("contact_angle", "rad", "contact angle in the track plane, positive leaning to the centre"),
    ("wheel_contact_y", "m", "contact point on the wheel: lateral, wheelset frame"),
    ("rail_contact_y", "m", "contact point on the rail: lateral, track frame"),
    ("rail_contact_z", "m", "contact point on the rail: height below the rail top, track frame"),
    ("wheel_lateral_curvature", "1/m", "wheel profile curvature at the contact, convex > 0"),
    ("rail_lateral_curvature", "1/m", "rail profile curvature at the contact, convex > 0"),
    ("wheel_rolling_curvature", "1/m", "wheel curvature in the rolling direction cos(d_rel)/r"),
)
"""The per-wheel columns of a `ContactTable`: (name, unit, meaning); each (n, 2) left, right."""


_LATERAL = ("wheel_contact_y", "rail_contact_y")


@dataclasses.dataclass(frozen=True)
class ContactTable:
    """Contact geometry tabulated over the wheelset's lateral displacement (numpy, SI units).

    - `lateral` [m], (n,): wheelset lateral displacement relative to the track, to the left.
    - `roll` [rad], (n,): wheelset roll, positive lifting the left wheel.
    - `height` [m], (n,): wheelset centre above the rail-top level.
    - per wheel, (n, 2) with columns (left, right): see `COLUMNS`.
    """

    lateral: np.ndarray
    roll: np.ndarray
    height: np.ndarray
    rolling_radius: np.ndarray
    contact_angle: np.ndarray
    wheel_contact_y: np.ndarray
    rail_contact_y: np.ndarray
    rail_contact_z: np.ndarray
    wheel_lateral_curvature: np.ndarray
    rail_lateral_curvature: np.ndarray
    wheel_rolling_curvature: np.ndarray

    @property
    def rolling_radius_difference(self) -> np.ndarray:
        """r_left - r_right [m], (n,) (the Delta-r function of EN 15302)."""
        return self.rolling_radius[:, 0] - self.rolling_radius[:, 1]


@dataclasses.dataclass(frozen=True)
class _Side:
    gap: float
    rail_y: float
    wheel_y: float


def _wheel_at(placed: PlacedProfiles, y, c, s, big_y):
    """Wheelset-frame lateral u of the left wheel point that lies at track lateral `big_y` for
    the wheelset at (y, roll with cos c, sin s): c u - s Z_w(u) = big_y - y (Newton)."""
    u = (big_y - y - s * placed.setup.wheel_radius) / c
    for _ in range(3):
        u = u - (c * u - s * placed.wheel(u) - (big_y - y)) / (c - s * placed.wheel(u, 1))
    return u


def _gap(placed, y, c, s, big_y):
    u = _wheel_at(placed, y, c, s, big_y)
    z_wheel = s * u + c * placed.wheel(u)
    inside = (u >= placed.wheel_span[0]) & (u <= placed.wheel_span[1])
    return np.where(inside, z_wheel - placed.rail(big_y), np.inf), u


def _gap_slope(placed, y, c, s, big_y):
    u = _wheel_at(placed, y, c, s, big_y)
    dz = placed.wheel(u, 1)
    return (s + c * dz) / (c - s * dz) - placed.rail(big_y, 1)


def _refine(placed, y, c, s, lo, hi, start):
    """Root of the gap's slope in [lo, hi] by Newton's method from `start` (brentq if Newton
    leaves the bracket); the slope's derivative is w''/(c - s w')^3 - r''."""
    t = start
    for _ in range(12):
        u = _wheel_at(placed, y, c, s, t)
        dw, d2w = placed.wheel(u, 1), placed.wheel(u, 2)
        slope = (s + c * dw) / (c - s * dw) - placed.rail(t, 1)
        curvature = d2w / (c - s * dw) ** 3 - placed.rail(t, 2)
        if not curvature > 0:
            break
        step = slope / curvature
        t = t - step
        if not lo <= t <= hi:
            break
        if abs(step) < 1e-14:
            return float(t)
    f_lo, f_hi = _gap_slope(placed, y, c, s, lo), _gap_slope(placed, y, c, s, hi)
    if f_lo < 0 < f_hi:
        return brentq(lambda v: _gap_slope(placed, y, c, s, v), lo, hi, xtol=1e-14, rtol=1e-15)
    return float(start)  # a kink of the rail data at the minimum: keep the grid point


def _left_side(placed: PlacedProfiles, grid, y: float, roll: float) -> _Side:
    """Smallest vertical gap of the left wheel over the rail at wheelset height 0."""
    c, s = np.cos(roll), np.sin(roll)
    gaps, _ = _gap(placed, y, c, s, grid)
    i = int(np.argmin(gaps))
    if not np.isfinite(gaps[i]) or i == 0 or i == grid.size - 1:
        raise ProfileError(
            f"the profiles do not touch on the rail head at lateral displacement "
            f"{1e3 * y:+.2f} mm (the closest point is at the edge of the rail or wheel profile)"
        )
    big_y = _refine(placed, y, c, s, grid[i - 1], grid[i + 1], grid[i])
    gap, u = _gap(placed, y, c, s, np.asarray(big_y))
    return _Side(gap=float(gap), rail_y=float(big_y), wheel_y=float(u))


def _solve_roll(placed, grid, y: float, guess: float, bracket: float = 0.05) -> float:
    """The roll that makes both wheels touch: secant steps from `guess`, brentq as fallback."""

    def mismatch(roll):
        return _left_side(placed, grid, y, roll).gap - _left_side(placed, grid, -y, -roll).gap

    if y == 0.0:
        return 0.0
    a, b = guess, guess + 1e-6
    fa, fb = mismatch(a), mismatch(b)
    for _ in range(12):
        if fb == fa:
            break
        a, fa, b = b, fb, b - fb * (b - a) / (fb - fa)
        if not -bracket < b < bracket:
            break
        fb = mismatch(b)
        if abs(b - a) < 1e-15:
            lo, hi = b - 1e-12, b + 1e-12  # accept only a bracketed root (no jump in between)
            if mismatch(lo) * mismatch(hi) <= 0:
                return float(b)
            break
    return brentq(mismatch, -bracket, bracket, xtol=1e-15, rtol=1e-15)


def _side_columns(placed: PlacedProfiles, side: _Side, roll: float) -> dict:
    """Columns of the left wheel at its contact (roll of the wheelset `roll`)."""
    rail_dz, rail_d2z = placed.rail(side.rail_y, 1), placed.rail(side.rail_y, 2)
    wheel_z = placed.wheel(side.wheel_y)
    wheel_dz, wheel_d2z = placed.wheel(side.wheel_y, 1), placed.wheel(side.wheel_y, 2)
    radius = -float(wheel_z)
    relative_angle = np.arctan(wheel_dz)  # from the axle
    return {
        "rolling_radius": radius,
        "contact_angle": float(np.arctan(rail_dz)),
        "wheel_contact_y": side.wheel_y,
        "rail_contact_y": side.rail_y,
        "rail_contact_z": float(placed.rail(side.rail_y)),
        "wheel_lateral_curvature": float(wheel_d2z / (1 + wheel_dz**2) ** 1.5),
        "rail_lateral_curvature": float(-rail_d2z / (1 + rail_dz**2) ** 1.5),
        "wheel_rolling_curvature": float(np.cos(relative_angle) / radius),
    }


def contact_table(
    placed: PlacedProfiles, *, max_lateral: float = 0.012, step: float = 5e-5
) -> ContactTable:
    """Tabulate the contact geometry for lateral displacements in [-max_lateral, max_lateral].

    **Arguments:**

    - `placed`: the profiles in place (`place_profiles`).
    - `max_lateral` [m], in [0.001, 0.03]: the table's half range (0.012 m covers flange contact
      of S1002 on UIC60 at standard gauge).
    - `step` [m], in [1e-5, 1e-4]: the spacing of the table.

    **Raises:** `ProfileError` naming the lateral displacement where the profiles do not touch
    on the rail head.
    """
    if not 0.001 <= max_lateral <= 0.03:
        raise ProfileError(f"`max_lateral` = {max_lateral:g} m is outside [0.001, 0.03]")
    if not 1e-5 <= step <= 1e-4:
        raise ProfileError(f"`step` = {step:g} m is outside [1e-5, 1e-4]")
    n = int(round(max_lateral / step))
    lateral = step * np.arange(-n, n + 1)
    grid = np.arange(placed.rail_span[0], placed.rail_span[1], GRID_STEP)
    rows = {name: np.empty((lateral.size, 2)) for name, _, _ in COLUMNS}
    roll, height = np.empty(lateral.size), np.empty(lateral.size)
    phi = 0.0
    for k in range(n, lateral.size):  # y >= 0 outwards from the centre; y < 0 by symmetry
        y = float(lateral[k])
        phi = _solve_roll(placed, grid, y, phi)
        left = _left_side(placed, grid, y, phi)
        right = _left_side(placed, grid, -y, -phi)  # the mirror image of the right side
        roll[k], height[k] = phi, -left.gap
        for j, (side, sign) in enumerate(((left, 1.0), (right, -1.0))):
            for name, value in _side_columns(placed, side, sign * phi).items():
                rows[name][k, j] = sign * value if name in _LATERAL else value
    # The wheelset and track are mirror symmetric: at -y left and right swap, lateral
    # positions and the roll change sign.
    mirror = slice(2 * n, n, -1)
    roll[:n], height[:n] = -roll[mirror], height[mirror]
    for name, value in rows.items():
        value[:n] = (-1.0 if name in _LATERAL else 1.0) * value[mirror, ::-1]
    return ContactTable(lateral=lateral, roll=roll, height=height, **rows)
