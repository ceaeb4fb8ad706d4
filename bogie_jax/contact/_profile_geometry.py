"""Contact geometry from a contact table, read by the equations of motion through a smooth JAX
interpolation (the profile strategy beside `ConeGeometry`).

The table of `_search.py` is exact for rigid profiles, and its rolling radii, contact angles and
contact positions jump where the contact point jumps (to the flange root, to the flange). A
rigid jump would give the vector field a discontinuity: an adaptive solver then shrinks its step
at every crossing (a step-size collapse at a two-point contact that the motion sits on) and
derivatives through the jump are undefined. The jumps are therefore smoothed once, outside
`jit`, by a Gaussian of width `smoothing` (0.3 mm by default: a tenth of the lateral semi-axis
of the Hertz patch, over which a real contact spreads the change of contact position), and every
column is then interpolated by a C2 cubic spline (scipy's not-a-knot `CubicSpline`
coefficients, evaluated here by Horner's rule). Values, first and second derivatives are
continuous, so the mass matrix and the generalised forces are C1 in the state and Jacobians,
adjoints and stability analyses are defined everywhere; no branch of the interpolation divides,
so no NaN can arise. Beyond the table the columns continue linearly (C1) with the end slope.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from scipy.interpolate import CubicSpline
from scipy.ndimage import gaussian_filter1d

from ._search import ContactTable


QUANTITIES = (
    "rolling_radius_left",  # [m]
    "rolling_radius_right",  # [m]
    "tan_contact_angle_left",  # [-] track plane
    "tan_contact_angle_right",  # [-]
    "wheel_contact_y_left",  # [m] wheelset frame, > 0
    "wheel_contact_y_right",  # [m] < 0
    "roll",  # [rad]
    "height",  # [m] centre height minus its centred value
)
"""The interpolated columns of a `ProfileGeometry`, in the order of its coefficient array."""


class ProfileGeometry(eqx.Module):
    """Contact geometry of a wheel/rail profile pair as functions of the wheelset's lateral
    displacement relative to the track, y [m] (the profile strategy beside `ConeGeometry`).

    All fields are arrays (data of the model, differentiable, never static):

    - `start` [m], `step` [m]: the table's first lateral displacement and spacing.
    - `coefficients`: (n - 1, 4, 8) cubic coefficients per interval (highest power first) of
      the 8 `QUANTITIES` (rolling radii, tangents of the track-plane contact angles, wheel
      contact positions, roll, centre height): one contiguous block per interval, so that a
      lookup reads one row.
    - `vertical_yaw_coefficient` [m]: xi of `u_z = ... - xi psi^2 / 2`, the cone value
      tan(d) (e - r tan(d)) at the centred contact (reference doc 1.2; a 2-D table has no yaw).
    - `cone_angle` [rad]: the contact angle of the centred contact (static normal load).
    - `hertz_curvatures` [1/m], (2,): A, B of the Hertz gap at the centred contact: the wheel's
      rolling-direction curvature / 2 and (rail + wheel lateral curvature) / 2 (reference doc 3).
    """

    start: Array
    step: Array
    coefficients: Array
    vertical_yaw_coefficient: Array
    cone_angle: Array
    hertz_curvatures: Array

    def evaluate(self, y):
        """Values, first and second derivatives with respect to y of the `QUANTITIES` at the
        lateral displacement(s) `y` [m]; each of shape (8, *y.shape)."""
        y = jnp.asarray(y)
        n = self.coefficients.shape[0]
        end = self.start + n * self.step
        inside = jnp.clip(y, self.start, end)
        i = jnp.clip(jnp.floor((inside - self.start) / self.step), 0, n - 1).astype(int)
        t = (inside - (self.start + i * self.step))[..., None]
        a, b, c, d = jnp.moveaxis(self.coefficients[i], -2, 0)  # each (*y.shape, 8)
        value = ((a * t + b) * t + c) * t + d
        slope = (3 * a * t + 2 * b) * t + c
        curvature = 6 * a * t + 2 * b
        beyond = (y - inside)[..., None]
        curvature = jnp.where(beyond == 0, curvature, 0.0)
        return tuple(jnp.moveaxis(x, -1, 0) for x in (value + slope * beyond, slope, curvature))

    @property
    def half_range(self):
        """Largest |y| [m] covered by the table."""
        return -self.start


def profile_geometry(table: ContactTable, *, smoothing: float = 3e-4) -> ProfileGeometry:
    """Build the `ProfileGeometry` of a contact table (numpy and scipy, outside `jit`).

    **Arguments:**

    - `table`: a symmetric, evenly spaced `ContactTable`.
    - `smoothing` [m], in [0, 0.002]: width (standard deviation) of the Gaussian that smooths
      the contact-point jumps; 0 keeps the table as it is (a cone has no jumps).
    """
    lateral = table.lateral
    step = float(lateral[1] - lateral[0])
    if not np.allclose(np.diff(lateral), step, rtol=1e-9, atol=0):
        raise ValueError("the contact table must be evenly spaced")
    if not 0.0 <= smoothing <= 0.002:
        raise ValueError(f"`smoothing` = {smoothing:g} m is outside [0, 0.002]")
    centre = int(np.argmin(np.abs(lateral)))
    columns = [
        table.rolling_radius[:, 0],
        table.rolling_radius[:, 1],
        np.tan(table.contact_angle[:, 0]),
        np.tan(table.contact_angle[:, 1]),
        table.wheel_contact_y[:, 0],
        table.wheel_contact_y[:, 1],
        table.roll,
        table.height - table.height[centre],
    ]
    if smoothing > 0:
        columns = [gaussian_filter1d(c, smoothing / step, mode="nearest") for c in columns]
    coefficients = np.stack([CubicSpline(lateral, c).c.T for c in columns], axis=-1)
    tan_d = np.tan(table.contact_angle[centre, 0])
    e, r = table.wheel_contact_y[centre, 0], table.rolling_radius[centre, 0]
    hertz = [
        0.5 * table.wheel_rolling_curvature[centre, 0],
        0.5 * (table.rail_lateral_curvature[centre, 0] + table.wheel_lateral_curvature[centre, 0]),
    ]
    return ProfileGeometry(
        start=jnp.asarray(lateral[0]),
        step=jnp.asarray(step),
        coefficients=jnp.asarray(coefficients),
        vertical_yaw_coefficient=jnp.asarray(tan_d * (e - r * tan_d)),
        cone_angle=jnp.asarray(table.contact_angle[centre, 0]),
        hertz_curvatures=jnp.asarray(hertz),
    )


def blend_geometries(new: ProfileGeometry, worn: ProfileGeometry, level) -> ProfileGeometry:
    """(1 - level) new + level worn, field by field (differentiable in `level` [-]); the two
    tables must share their lateral grid (`start`, `step`), as the shipped pairs do."""
    level = jnp.asarray(level)
    return jax.tree_util.tree_map(lambda a, b: a + level * (b - a), new, worn)


def scale_conicity(geometry: ProfileGeometry, factor) -> ProfileGeometry:
    """`geometry` with each wheel's rolling radius moved from its centred value r_0 by `factor`
    [-] times as much: r(y) -> r_0 + factor (r(y) - r_0). The rolling radius difference Delta r
    scales by `factor`, and so does the equivalent conicity at every amplitude (a linear
    functional of Delta r; UIC 519, 2004); the contact angles, contact positions, roll and
    height stay as they are. Differentiable in `factor`; a factor of 1 returns the coefficients
    unchanged bit for bit."""
    change = jnp.asarray(factor) - 1.0
    radii = geometry.coefficients[..., :2]  # rolling radius left, right: (n - 1, 4, 2)
    centred = geometry.evaluate(0.0)[0][:2]
    about = jnp.zeros_like(radii).at[:, 3, :].set(centred)  # r_0 in the constant term only
    radii = radii + change * (radii - about)
    return eqx.tree_at(
        lambda g: g.coefficients, geometry, geometry.coefficients.at[..., :2].set(radii)
    )
