"""Independent oracles for the contact table (tests only; written apart from
`bogie_jax.contact._search`, sharing none of its code).

1. `brute_force_contact`: the rigid two-wheel contact found by brute force. Each profile is a
   quintic interpolating B-spline (the package uses cubic ones), sampled on a fine grid of wheel
   points; the vertical gap to the rail is taken at every sample and its plain minimum is the
   contact (no refinement); the roll is found by bisection on the gap mismatch of the two wheels.
2. `cone_on_circle_exact`: the exact contact of a conical wheel on a circular rail head by the
   offset-surface reduction of the physics reference 1.2 (the circle's centre lies on the cone
   offset by the circle's radius), solved with `scipy.optimize.fsolve` for (height, roll).

Frames as in the package's module docs: track y left, z up; profiles in the files' right-side
frame, y to the field side, z down; the left side is the mirror image.
"""

import pathlib
import warnings

import numpy as np
from scipy.interpolate import make_interp_spline
from scipy.optimize import fsolve


def read_points(path):
    """(y, z) [m] of a SIMPACK profile, mirror flags applied, sorted by y (own small parser)."""
    rows, inside, mirror_y, scale = [], False, False, 1000.0
    for raw in pathlib.Path(path).read_text().splitlines():
        line = raw.split("!")[0].strip()
        if line.startswith("point.begin"):
            inside = True
        elif line.startswith("point.end"):
            inside = False
        elif inside and line:
            rows.append([float(v) for v in line.split()[:2]])
        elif line.replace(" ", "").startswith("mirror.y="):
            mirror_y = line.split("=")[1].strip() == "1"
        elif line.replace(" ", "").startswith("units.len.f="):
            scale = float(line.split("=")[1])
    pts = np.array(rows) / scale
    if mirror_y:
        pts[:, 0] *= -1
    order = np.argsort(pts[:, 0])
    return pts[order, 0], pts[order, 1]


class BruteForce:
    """The left wheel and rail placed as in the Manchester set-up, quintic splines, z up."""

    def __init__(
        self,
        wheel,
        rail,
        *,
        gauge=1.435,
        gauge_height=0.014,
        back_to_back=1.360,
        radius=0.46,
        flange_back=-0.070,
        max_slope=10.0,
        sample=1e-6,
    ):
        yw, zw = wheel
        nominal = flange_back + 0.070
        z_nom = np.interp(nominal, yw, zw)
        self.wheel = make_interp_spline(
            0.5 * back_to_back + (yw - flange_back), -(zw - z_nom) - radius, k=5
        )
        yr, zr = rail
        top = int(np.argmin(zr))
        depth = zr[top] + gauge_height
        i = np.nonzero(zr[:top] >= depth)[0][-1]
        y_gauge = np.interp(depth, [zr[i + 1], zr[i]], [yr[i + 1], yr[i]])
        keep = np.abs(np.gradient(zr, yr)) <= max_slope
        lo, hi = top, top
        while lo > 0 and keep[lo - 1]:
            lo -= 1
        while hi < yr.size - 1 and keep[hi + 1]:
            hi += 1
        self.rail_y = 0.5 * gauge + (yr[lo : hi + 1] - y_gauge)
        self.rail = make_interp_spline(self.rail_y, -(zr[lo : hi + 1] - zr[top]), k=5)
        span = 0.5 * back_to_back + (yw - flange_back)
        self.u = np.arange(span[0], span[-1], sample)
        self.wheel_z = self.wheel(self.u)

    def _side(self, y, roll):
        """(gap, index of the wheel sample) of the left wheel at wheelset height 0."""
        c, s = np.cos(roll), np.sin(roll)
        big_y = y + c * self.u - s * self.wheel_z
        big_z = s * self.u + c * self.wheel_z
        on_rail = (big_y > self.rail_y[0]) & (big_y < self.rail_y[-1])
        gaps = np.where(on_rail, big_z - self.rail(np.clip(big_y, *self.rail_y[[0, -1]])), np.inf)
        k = int(np.argmin(gaps))
        return gaps[k], k, big_y[k]

    def contact(self, y):
        """Roll [rad], left and right rolling radii [m] and rail contact y [m] at displacement y."""
        lo, hi = -0.05, 0.05
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            if self._side(y, mid)[0] - self._side(-y, -mid)[0] > 0:
                hi = mid
            else:
                lo = mid
        roll = 0.5 * (lo + hi)
        _, kl, yl = self._side(y, roll)
        _, kr, yr = self._side(-y, -roll)
        radii = np.array([-self.wheel_z[kl], -self.wheel_z[kr]])
        return roll, radii, np.array([yl, -yr])


def cone_on_circle_exact(y, *, r0, e0, slope, rail_radius):
    """Exact contact of a cone (tan delta0 = `slope`) on circles of radius `rail_radius` whose
    tops sit at +-(e0 + R sin delta0), the nominal contact points at +-e0 (reference doc 1.2).

    Returns a dict: roll [rad], height (wheelset centre minus its centred value) [m], rolling
    radii (left, right) [m], contact angles in the track plane (left, right) [rad], wheel
    contact lateral positions in the wheelset frame (left, right) [m]."""
    d0 = np.arctan(slope)
    sd, cd, R = np.sin(d0), np.cos(d0), rail_radius
    centre_y, centre_z = e0 + R * sd, -R  # left circle centre, track frame (rail top at z = 0)

    def on_offset_cone(h, roll, side):
        c, s = np.cos(roll), np.sin(roll)
        dy, dz = side * centre_y - y, centre_z - h
        py, pz = c * dy + s * dz, -s * dy + c * dz  # circle centre in the wheelset frame
        return pz - (-r0 - R * cd + slope * (side * py - e0 - R * sd))

    h0 = r0 + R * cd - R

    def residual(v):
        return [on_offset_cone(v[0], v[1], 1.0), on_offset_cone(v[0], v[1], -1.0)]

    with warnings.catch_warnings():  # fsolve warns when it cannot improve on rounding
        warnings.simplefilter("ignore", RuntimeWarning)
        h, roll = fsolve(residual, [h0, 0.0], xtol=1e-15)
    assert np.max(np.abs(residual([h, roll]))) < 1e-14
    c, s = np.cos(roll), np.sin(roll)
    radii, lateral = [], []
    for side in (1.0, -1.0):
        dy, dz = side * centre_y - y, centre_z - h
        py, pz = c * dy + s * dz, -s * dy + c * dz
        py, pz = py - side * R * sd, pz + R * cd  # back from the offset cone to the wheel
        radii.append(-pz)
        lateral.append(py)
    return {
        "roll": roll,
        "height": h - h0,
        "rolling_radius": np.array(radii),
        "contact_angle": np.array([d0 + roll, d0 - roll]),
        "wheel_contact_y": np.array(lateral),
    }
