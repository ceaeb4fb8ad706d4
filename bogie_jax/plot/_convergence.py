"""Identification runs over their evaluations (paper figures 6-7): a running best against the
cost evaluations spent, and where local runs started and ended relative to the truth."""

import numpy as np

from ._common import get_axes


def plot_convergence(
    evaluations, values, ax=None, *, ylabel: str, truth=None, log: bool = False, label=None
):
    """A quantity (the best cost so far, or a parameter of the best point so far) against the
    number of cost evaluations, with its true value as a dashed line.

    **Arguments:** `evaluations` (k,) counts; `values` (k,); `ax`; `ylabel` with its unit, e.g.
    `"primary.cx [N s/m]"`; `truth`; `log`: log-scale y axis; `label` for a legend.

    **Returns:** the axes.
    """
    ax = get_axes(ax, (5.0, 3.2))
    ax.plot(np.asarray(evaluations), np.asarray(values, float), "-", lw=1.2, label=label)
    if truth is not None:
        ax.axhline(float(truth), color="k", ls="--", lw=0.8, label="true value")
    if log:
        ax.set_yscale("log")
    ax.set_xlabel("cost evaluations [-]")
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", alpha=0.3)
    if label is not None or truth is not None:
        ax.legend(fontsize=8)
    return ax


def plot_runs(names, starts, ends, truth, ax=None, *, costs=None):
    """Local runs as arrows from each start to its end, every parameter relative to its true
    value (1 = exact); one colour per run, its final cost in the legend.

    **Arguments:** `names` (n,); `starts`, `ends` (N, n) physical; `truth` (n,); `ax`; `costs`
    (N,) final costs [-] or None.

    **Returns:** the axes.
    """
    starts = np.atleast_2d(np.asarray(starts, float))
    ends = np.atleast_2d(np.asarray(ends, float))
    truth = np.asarray(truth, float)
    ax = get_axes(ax, (6.0, 0.6 * len(names) + 2.0))
    y = np.arange(len(names))[::-1].astype(float)
    n_runs = starts.shape[0]
    for k in range(n_runs):
        shift = 0.6 * (k - (n_runs - 1) / 2) / max(n_runs, 1)
        s, e = starts[k] / truth, ends[k] / truth
        cost = "" if costs is None else f", J = {float(np.asarray(costs)[k]):.2g}"
        colour = f"C{k % 10}"
        for i in range(len(names)):
            ax.annotate(
                "",
                xy=(e[i], y[i] + shift),
                xytext=(s[i], y[i] + shift),
                arrowprops=dict(arrowstyle="->", color=colour, lw=1.2),
            )
        ax.plot(s, y + shift, "o", mfc="none", color=colour, ms=5)
        ax.plot(e, y + shift, "o", color=colour, ms=5, label=f"run {k + 1}{cost}")
    ax.axvline(1.0, color="k", lw=0.8)
    ax.set_yticks(y, list(names))
    ax.set_ylim(y.min() - 0.6, y.max() + 0.6)
    ax.set_xlabel("value / true value [-] (open: start, filled: end)")
    ax.grid(True, axis="x", alpha=0.3)
    ax.legend(fontsize=7)
    return ax
