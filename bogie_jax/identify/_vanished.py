"""`restart_vanished`: a least-squares fit in log coordinates repeated with the coordinates that
ran to zero restarted at their reference.

In a log coordinate phi = ln(p / p_ref) the Jacobian's column is dr/dphi = p dr/dp: it shrinks
with p. A fit whose path takes a parameter towards zero (a damper's, while the other
parameters are still far from their optimum) leaves it there: at phi = -20 the parameter is
2e-9 of its reference, the cost is flat in phi for many units around, and a step of the
largest size a fit allows (a factor e in p, `levenberg_marquardt`'s `max_step`) changes nothing
the data can tell apart, so the fit stops with phi where it is, whatever the data say. The
rest of the fit then settles around the stranded parameter, in a minimum of its own
(docs/history.md: a lost anti-yaw damper of the detection benchmark). Restarting those
coordinates at the reference is a second local fit from a point the first cannot reach; it is
kept only where it ends lower.
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
