"""Matplotlib figures of sensitivity and identifiability results (imported lazily).

Every function takes an optional `ax` (a new figure otherwise) and returns the axes (or the
figure, for several panels). Inputs are the result modules of `bogie_jax.sensitivity`.
"""

import numpy as np

from ._common import get_axes


def plot_sobol_indices(indices, ax=None, *, title: str | None = None):
    """Bars of first-order and total Sobol indices with their bootstrap intervals."""
    ax = get_axes(ax, figsize=(max(5, 0.8 * len(indices.names) + 2), 4))
    names = indices.names
    x = np.arange(len(names))
    w = 0.38
    for k, (label, value, ci) in enumerate(
        (
            ("first order $S_i$", indices.first_order, indices.first_order_ci),
            ("total $S_{Ti}$", indices.total, indices.total_ci),
        )
    ):
        value, ci = np.asarray(value), np.asarray(ci)
        err = np.abs(np.stack([value - ci[:, 0], ci[:, 1] - value]))
        ax.bar(x + (k - 0.5) * w, value, w, yerr=err, capsize=3, label=label)
    ax.set_xticks(x, names, rotation=30, ha="right")
    ax.set_ylabel("Sobol index [-]")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.legend(fontsize=8)
    ax.grid(True, axis="y", alpha=0.3)
    ax.set_title(title or f"Sobol indices ({int(100 * indices.confidence)} % bootstrap intervals)")
    return ax


def plot_cost_surface(grid, *, label: str = "cost J", log: bool = False):
    """Figure 4 of the paper: the cost over a two-parameter `ScreeningGrid`, as a filled contour
    (left) and a 3-D surface (right). Returns the figure."""
    import matplotlib.pyplot as plt

    x, y = np.asarray(grid.x_values), np.asarray(grid.y_values)
    z = np.asarray(grid.outputs).T  # rows: y
    if log:
        z = np.log10(np.maximum(z, np.nanmin(z[z > 0]) if np.any(z > 0) else 1e-300))
        label = f"log10 {label}"
    gx, gy = np.meshgrid(x, y)
    fig = plt.figure(figsize=(11, 4.5))
    ax1 = fig.add_subplot(1, 2, 1)
    cs = ax1.contourf(gx, gy, z, levels=20, cmap="viridis")
    ax1.contour(gx, gy, z, levels=10, colors="k", linewidths=0.4)
    fig.colorbar(cs, ax=ax1, label=label)
    ax1.set_xlabel(grid.names[0])
    ax1.set_ylabel(grid.names[1])
    ax2 = fig.add_subplot(1, 2, 2, projection="3d")
    ax2.plot_surface(gx, gy, z, cmap="viridis", linewidth=0, antialiased=True)
    ax2.set_xlabel(grid.names[0])
    ax2.set_ylabel(grid.names[1])
    ax2.set_zlabel(label)
    fig.tight_layout()
    return fig


def plot_sweeps(sweeps, ax=None, *, label: str = "cost J", all_names=None):
    """One line per swept parameter of a `ScreeningSweeps`. With `all_names` (the names of every
    parameter, in the order of `sweeps.nominal`, e.g. `objective.selection.names`) the x axis is
    the value relative to its nominal value, so sweeps of different units share one axes."""
    ax = get_axes(ax)
    values, outputs = np.asarray(sweeps.values), np.asarray(sweeps.outputs)
    nominal = np.asarray(sweeps.nominal)
    for k, name in enumerate(sweeps.names):
        v = values[k]
        if all_names is not None:
            v = v / nominal[list(all_names).index(name)]
        ax.plot(v, outputs[k], marker=".", label=name)
    ax.set_xlabel("value / nominal [-]" if all_names is not None else "value")
    ax.set_ylabel(label)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return ax


def plot_profiles(profile, *, ncols: int = 3):
    """Profile likelihood Delta J of each parameter with the 95 % threshold and interval.
    Returns the figure."""
    import matplotlib.pyplot as plt

    n = len(profile.names)
    ncols = min(ncols, n)
    nrows = -(-n // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(4 * ncols, 3.2 * nrows), squeeze=False)
    delta = profile.delta_cost
    for k, name in enumerate(profile.names):
        ax = axes.flat[k]
        v = np.asarray(profile.values[k])
        ax.plot(v, delta[k], marker=".", label="profile $\\Delta J$")
        ax.axhline(
            profile.threshold, color="r", ls="--", lw=1, label=f"threshold {profile.threshold:.2f}"
        )
        lo, hi = np.asarray(profile.interval[k])
        left = lo if np.isfinite(lo) else v.min()
        right = hi if np.isfinite(hi) else v.max()
        ax.axvspan(left, right, color="g", alpha=0.12, label="95 % interval")
        ax.axvline(float(np.asarray(profile.estimate)[profile.indices[k]]), color="k", lw=0.8)
        unit = f" [{profile.units[k]}]" if profile.units[k] else ""
        ax.set_xlabel(f"{name}{unit}")
        ax.set_ylabel("$\\Delta J$")
        ax.set_title(f"{name}: {profile.status[k]}", fontsize=9)
        ax.grid(True, alpha=0.3)
        if k == 0:
            ax.legend(fontsize=7)
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    fig.tight_layout()
    return fig


def plot_fim_eigenvalues(fim, ax=None, *, max_relative_std: float = 0.1):
    """Bars of the eigenvalues of the relative Fisher information (log scale), labelled by each
    eigenvector's dominant parameters; the level below which a combination has a relative std
    above `max_relative_std` is marked."""
    ax = get_axes(ax, figsize=(max(5, 0.9 * len(fim.names) + 2), 4.2))
    w = np.asarray(fim.eigenvalues)
    v = np.asarray(fim.eigenvectors)
    names = fim.names
    labels = []
    for k in range(w.size):
        order = np.argsort(-np.abs(v[:, k]))
        cum = np.cumsum(v[order, k] ** 2)
        top = order[: int(np.searchsorted(cum, 0.9) + 1)][:2]
        labels.append("\n".join(names[i] for i in top))
    floor = np.maximum(w, np.finfo(float).tiny)
    colors = ["tab:red" if x < 1 / max_relative_std**2 else "tab:blue" for x in w]
    ax.bar(np.arange(w.size), floor, color=colors)
    ax.set_yscale("log")
    ax.axhline(
        1 / max_relative_std**2,
        color="k",
        ls="--",
        lw=1,
        label=f"relative std {100 * max_relative_std:g} %",
    )
    ax.set_xticks(np.arange(w.size), labels, fontsize=7)
    ax.set_ylabel("eigenvalue of $F$ (d ln p)")
    ax.set_title(f"Fisher information eigenvalues (condition {fim.condition_number:.2g})")
    ax.legend(fontsize=8)
    ax.grid(True, axis="y", alpha=0.3)
    return ax
