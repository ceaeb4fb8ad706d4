"""The cost over two parameters as a filled contour on one axes (paper figure 4)."""

import numpy as np

from ._common import get_axes


def _axis_label(name: str, unit: str) -> str:
    return f"{name} [{unit or '-'}]"


def plot_cost_contour(
    grid,
    ax=None,
    *,
    units=("", ""),
    label: str = "cost J [-]",
    log: bool = False,
    levels: int = 15,
    marker=None,
):
    """Filled contour of the cost over a two-parameter `ScreeningGrid` (the others fixed), with
    the grid point of lowest cost marked by a white cross.

    **Arguments:** `grid` (`bogie_jax.sensitivity.ScreeningGrid`); `ax`; `units`: the units of
    the two parameters (e.g. `objective.selection.units` of the pair), shown as `name [unit]`;
    `label`: the colour bar's label with its unit; `log`: colour by log10 of the cost;
    `levels`: contour levels; `marker`: an `(x, y)` point (e.g. the true values) drawn as a
    red dot.

    **Returns:** the axes.
    """
    ax = get_axes(ax, (5.5, 4.2))
    x, y = np.asarray(grid.x_values, float), np.asarray(grid.y_values, float)
    z = np.asarray(grid.outputs, float).T  # rows: y
    if log:
        positive = z[np.isfinite(z) & (z > 0)]
        z = np.log10(np.maximum(z, positive.min() if positive.size else np.finfo(float).tiny))
        label = f"log10 {label}"
    filled = ax.contourf(x, y, z, levels=levels, cmap="viridis")
    ax.contour(x, y, z, levels=levels, colors="k", linewidths=0.3)
    ax.figure.colorbar(filled, ax=ax, label=label)
    j, i = np.unravel_index(np.nanargmin(z), z.shape)
    ax.plot(x[i], y[j], "wx", ms=9, mew=2, label="lowest grid point")
    if marker is not None:
        ax.plot(*marker, "o", color="tab:red", ms=6, label="true values")
    ax.set_xlabel(_axis_label(grid.names[0], units[0]))
    ax.set_ylabel(_axis_label(grid.names[1], units[1]))
    ax.legend(fontsize=8, loc="upper right")
    return ax
