"""The numpy twin's reading of a profile contact table (tests only).

The twin reads the same table as the JAX model: the cubic pieces of a
`bogie_jax.contact.ProfileGeometry` (its `coefficients`, `start`, `step`), evaluated here with
scipy's `PPoly` (values and the first two derivatives; beyond the table the same linear
continuation as the model's, docs in `bogie_jax/contact/_profile_geometry.py`).
"""

import numpy as np
from scipy.interpolate import PPoly


class TwinTable:
    """Quantities of `bogie_jax.contact.QUANTITIES` as functions of y_rel [m]."""

    def __init__(self, geometry):
        coefficients = np.asarray(geometry.coefficients)  # (n - 1, 4, 8), highest power first
        start, step = float(geometry.start), float(geometry.step)
        breaks = start + step * np.arange(coefficients.shape[0] + 1)
        self.lo, self.hi = breaks[0], breaks[-1]
        self.pieces = [PPoly(coefficients[:, :, q].T, breaks) for q in range(8)]
        self.xi = float(geometry.vertical_yaw_coefficient)

    def __call__(self, y_rel: float):
        """(values, d/dy, d2/dy2), each (8,), at y_rel."""
        inside = min(max(y_rel, self.lo), self.hi)
        value = np.array([p(inside) for p in self.pieces])
        slope = np.array([p(inside, 1) for p in self.pieces])
        curvature = np.array([p(inside, 2) for p in self.pieces])
        if inside != y_rel:
            return value + slope * (y_rel - inside), slope, np.zeros(8)
        return value, slope, curvature
