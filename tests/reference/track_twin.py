"""Numpy evaluation of a `TrackIrregularity` (natural cubic spline on a uniform grid) for the
numpy twin, so scipy integrates exactly the same C2 track input as the JAX model."""

import numpy as np


def track_inputs_fn(track, speed: float, axle_positions):
    """`t -> (w, w_dot, w_ddot)`, each (2, 3), for wheelsets at `axle_positions` [m]."""
    s0, h = float(track.s0), float(track.ds)
    values, curv = np.asarray(track.values), np.asarray(track.curvatures)
    last = len(values) - 1
    x_axles = np.asarray(axle_positions, dtype=float)

    def evaluate(s):
        x = (s - s0) / h
        i = np.clip(np.floor(x), 0, last - 1).astype(int)
        t = (x - i)[:, None]
        u = 1.0 - t
        y0, y1, m0, m1 = values[i], values[i + 1], curv[i], curv[i + 1]
        w = u * y0 + t * y1 + h**2 / 6.0 * ((u**3 - u) * m0 + (t**3 - t) * m1)
        dw = (y1 - y0) / h + h / 6.0 * ((3.0 * t**2 - 1.0) * m1 - (3.0 * u**2 - 1.0) * m0)
        d2w = u * m0 + t * m1
        inside = ((x >= 0.0) & (x <= last))[:, None]
        return [np.where(inside, q, 0.0) for q in (w, dw, d2w)]

    def inputs(t):
        w, dw, d2w = evaluate(speed * t + x_axles)
        return w, speed * dw, speed**2 * d2w

    return inputs
