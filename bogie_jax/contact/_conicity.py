"""Equivalent conicity of a contact table by harmonic linearisation (numpy, outside `jit`).

For a wheelset oscillating laterally as y = A sin(theta), the rolling-radius difference
Delta r(y) = r_left - r_right is replaced by the linear law 2 tan(gamma_e) y with the same first
Fourier harmonic (the describing function of Delta r):

    tan(gamma_e)(A) = 1 / (2 pi A) * integral_0^{2 pi} Delta r(A sin(theta)) sin(theta) d theta

This is the harmonic-linearisation definition of the equivalent conicity of UIC 519 (2004) and
EN 15302 (the standards' reference results hold for their other methods too, within their
tolerances). For a cone, Delta r = 2 lambda y and tan(gamma_e) = lambda at every amplitude.
"""

import numpy as np


def equivalent_conicity(lateral, delta_r, amplitudes, *, points: int = 4096) -> np.ndarray:
    """tan(gamma_e) [-] at each amplitude [m] from a Delta-r function tabulated over `lateral`.

    **Arguments:**

    - `lateral` [m], (n,): increasing lateral displacements of the table.
    - `delta_r` [m], (n,): r_left - r_right at `lateral`.
    - `amplitudes` [m]: scalar or array, each in (0, max |lateral|].
    - `points`: quadrature points over one period (midpoint rule, exact for a trigonometric
      polynomial of degree below `points`).

    **Raises:** `ValueError` naming an amplitude outside the table.
    """
    lateral, delta_r = np.asarray(lateral, float), np.asarray(delta_r, float)
    amplitudes = np.asarray(amplitudes, float)
    reach = min(-lateral[0], lateral[-1])
    bad = (amplitudes <= 0) | (amplitudes > reach * (1 + 1e-12))
    if np.any(bad):
        value = float(np.atleast_1d(amplitudes)[np.atleast_1d(bad)][0])
        raise ValueError(
            f"amplitude {1e3 * value:g} mm is outside the table (0, {1e3 * reach:g}] mm"
        )
    theta = 2 * np.pi * (np.arange(points) + 0.5) / points
    sine = np.sin(theta)
    y = amplitudes[..., None] * sine
    first_harmonic = np.mean(np.interp(y, lateral, delta_r) * sine, axis=-1) * 2
    return first_harmonic / (2 * amplitudes)
