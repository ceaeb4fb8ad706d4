"""`restart_vanished`: a least-squares fit in log coordinates repeated with the coordinates that
ran to zero restarted at their reference.

In a log coordinate phi = ln(p / p_ref) a parameter can run to zero (phi -> -inf): where, with
the other parameters where the fit's path has left them, any amount of it raises the cost (a
damper's, while the others are still far from their optimum), the fit has a minimum on the
boundary p -> 0 and ends there, the cost flat in phi for many units (at phi = -20, p is 2e-9 of
its reference). A lower minimum may lie with the parameter at a finite value and the others
elsewhere, which the fit cannot reach from the boundary: every small move raises the cost
(docs/history.md: a lost anti-yaw damper of the detection benchmark). Restarting those
coordinates at the reference, the others as fitted, is a second local fit from a point the
first cannot reach; it is kept only where it ends lower.
"""

from collections.abc import Callable, Iterable

import numpy as np

from ._levenberg_marquardt import HostFit, levenberg_marquardt


def restart_vanished(
    evaluate: Callable,
    fit: HostFit,
    coordinates: Iterable[int],
    *,
    level: float,
    max_steps: int = 30,
) -> HostFit:
    """`fit`, or the fit (`levenberg_marquardt` with `evaluate`, `max_steps`) from its estimate
    with each of `coordinates` (indices into `fit.phi`, log coordinates) that lies below `level`
    set to 0 (the reference), where that one ends at a lower cost (module docstring). `fit`
    itself where none lies below `level`, `fit` failed, or the restart fails or ends no lower."""
    index = np.asarray(list(coordinates), dtype=int)
    if fit.status == "failed" or index.size == 0:
        return fit
    below = index[np.asarray(fit.phi)[index] < level]
    if below.size == 0:
        return fit
    start = np.array(fit.phi, dtype=float)
    start[below] = 0.0
    again = levenberg_marquardt(evaluate, start, max_steps=max_steps)
    return again if again.status != "failed" and again.cost < fit.cost else fit
