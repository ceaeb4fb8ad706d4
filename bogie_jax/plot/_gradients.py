"""Figures of gradient checks: components by method, and cost against the parameter count."""

import numpy as np

from ._common import get_axes


def plot_gradient_components(records, names, ax=None):
    """Gradient components dJ/dtheta_i by method, grouped by parameter (cf. paper figure 5).

    `records`: `bogie_jax.gradients.gradient_report` records of one selection (those with a
    `grad`); `names`: the parameter names. Symmetric-log y axis (components span decades).
    """
    records = [r for r in records if r.get("grad") is not None]
    ax = get_axes(ax, (max(6.0, 0.5 * len(names) * len(records) / 3 + 3), 4))
    x = np.arange(len(names))
    width = 0.8 / max(len(records), 1)
    largest = max((np.max(np.abs(r["grad"])) for r in records), default=1.0) or 1.0
    for k, r in enumerate(records):
        ax.bar(x + (k - (len(records) - 1) / 2) * width, r["grad"], width, label=r["method"])
    ax.set_yscale("symlog", linthresh=1e-4 * largest)
    ax.set_xticks(x, names, rotation=60, ha="right", fontsize=8)
    ax.set_ylabel(r"$\partial J / \partial \theta_i$ [-]")
    ax.axhline(0.0, color="k", lw=0.6)
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=8, ncol=3)
    return ax


def plot_gradient_cost(records, ax=None):
    """Time per gradient over one forward solve against the number of parameters n, per method
    (log-log), with the slope of a cost proportional to n for reference."""
    import matplotlib.pyplot as plt

    ax = get_axes(ax, (6.5, 4.5))
    methods = [m for m in dict.fromkeys(r["method"] for r in records) if m != "forward-solve"]
    for method in methods:
        rows = sorted((r["n_params"], r["time_ratio"]) for r in records if r["method"] == method)
        ax.plot(*zip(*rows), "o-", label=method)
    ns = sorted({r["n_params"] for r in records})
    if ns:
        ax.plot(ns, [2.0 * n for n in ns], "k:", lw=1, label=r"$\propto n$")
    ax.set_xscale("log")
    ax.set_yscale("log")
    if ns:  # label the measured n, not the log axis' decades
        ax.set_xticks(ns, [str(n) for n in ns])
        ax.xaxis.set_minor_formatter(plt.NullFormatter())
    ax.set_xlabel("number of parameters n [-]")
    ax.set_ylabel("time per gradient / forward solve [-]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    return ax
