"""Two rankings of the parameters side by side: global (Sobol') against local (Fisher)."""

import numpy as np

from ._common import get_axes


def plot_sensitivity_ranking(indices, fim, ax=None):
    """Each parameter as a point: its total Sobol index S_Ti (with its bootstrap interval) on
    the x axis, its relative standard error from the Fisher information (Cramer-Rao bound, in
    per cent, log scale) on the y axis. Influential parameters lie to the right; identifiable
    ones low; the two rankings agree when the points fall from upper left to lower right.

    **Arguments:** `indices` (`bogie_jax.sensitivity.SobolIndices`) and `fim`
    (`bogie_jax.sensitivity.FisherInformation`) over the same parameters (matched by name);
    `ax`.

    **Returns:** the axes.
    """
    names = list(indices.names)
    missing = [n for n in names if n not in fim.names]
    if missing:
        raise ValueError(
            f"`fim` has no parameter {', '.join(missing)}; it has {', '.join(fim.names)}"
        )
    ax = get_axes(ax, (6.0, 4.2))
    total, ci = np.asarray(indices.total, float), np.asarray(indices.total_ci, float)
    rel = np.asarray(fim.relative_std_errors, float)
    rel = 100 * np.array([rel[list(fim.names).index(n)] for n in names])
    shown = np.where(np.isfinite(rel), rel, np.nan)
    err = np.abs(np.stack([total - ci[:, 0], ci[:, 1] - total]))
    ax.errorbar(total, shown, xerr=err, fmt="o", capsize=3)
    for k, name in enumerate(names):
        if np.isfinite(shown[k]):
            ax.annotate(name, (total[k], shown[k]), textcoords="offset points", xytext=(5, 4))
    ax.set_yscale("log")
    ax.set_xlabel("total Sobol index $S_{Ti}$ [-]")
    ax.set_ylabel("relative std error (Fisher) [%]")
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title("global influence against local identifiability", fontsize=10)
    return ax
