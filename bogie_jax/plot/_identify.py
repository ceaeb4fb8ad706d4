"""Identification plots: the multistart waterfall and estimated against true parameters.

matplotlib is imported lazily; every function takes `ax=None` (a new figure) and returns the axes.
"""

import numpy as np

from ._common import get_axes


def plot_waterfall(costs, failed=None, *, ax=None, label=None):
    """Final costs of every start, sorted ascending (log scale): a flat head means many starts
    reached the same (best) minimum; steps are distinct local minima. Failed starts are left out
    and counted in the title.

    **Arguments:** `costs` (N,); `failed` (N,) bool or None; `ax`; `label` for a legend.
    **Returns:** the axes.
    """
    ax = get_axes(ax, (6, 3.5))
    costs = np.asarray(costs, dtype=float)
    bad = np.zeros(costs.shape, bool) if failed is None else np.array(failed, bool)
    bad |= ~np.isfinite(costs)
    ok = np.sort(costs[~bad])
    floor = np.finfo(float).tiny
    ax.semilogy(np.arange(1, ok.size + 1), np.maximum(ok, floor), "o-", ms=3, label=label)
    ax.set_xlabel("start (sorted by final cost) [-]")
    ax.set_ylabel("final cost J [-]")
    ax.set_title(
        f"multistart waterfall: {ok.size} starts"
        + (f", {int(bad.sum())} failed" if bad.any() else "")
    )
    ax.grid(True, which="both", alpha=0.3)
    if label is not None:
        ax.legend()
    return ax


def plot_estimates(names, estimates, ci95, *, truth=None, nominal=None, ax=None):
    """Each estimate with its 95 % interval, relative to the true value (or, where unknown, to
    the nominal value): a point on the line 1 is exact; the interval should cover it.

    **Arguments:** `names` (n,), `estimates` (n,), `ci95` (n, 2), `truth` (n,) or None,
    `nominal` (n,) or None (shown as crosses), `ax`.
    **Returns:** the axes.
    """
    estimates = np.asarray(estimates, dtype=float)
    ci = np.asarray(ci95, dtype=float).reshape(-1, 2)
    ref = np.asarray(truth if truth is not None else nominal, dtype=float)
    ax = get_axes(ax, (6, 0.45 * len(names) + 1.6))
    y = np.arange(len(names))[::-1]
    rel, lo, hi = estimates / ref, ci[:, 0] / ref, ci[:, 1] / ref
    ax.errorbar(
        rel,
        y,
        xerr=np.abs(np.stack([rel - lo, hi - rel])),
        fmt="o",
        capsize=3,
        label="estimate, 95 % interval",
    )
    if truth is not None and nominal is not None:
        ax.plot(
            np.asarray(nominal, dtype=float) / ref,
            y,
            "x",
            color="0.5",
            label="nominal (start band centre)",
        )
    ax.axvline(1.0, color="k", lw=0.8)
    ax.set_yticks(y, list(names))
    ax.set_xlabel("estimate / true value" if truth is not None else "estimate / nominal value")
    ax.set_title(
        "estimated against true parameters" if truth is not None else "estimated parameters"
    )
    ax.legend(fontsize="small")
    ax.grid(True, axis="x", alpha=0.3)
    return ax
