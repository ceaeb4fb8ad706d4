"""Matplotlib figures (imported lazily; nothing in the core imports this module)."""

import numpy as np

from ._plot_identify import plot_estimates as plot_estimates, plot_waterfall as plot_waterfall
from ._plot_sensitivity import (
    plot_cost_surface as plot_cost_surface,
    plot_fim_eigenvalues as plot_fim_eigenvalues,
    plot_profiles as plot_profiles,
    plot_sobol_indices as plot_sobol_indices,
    plot_sweeps as plot_sweeps,
)
from .model import DOF_NAMES


def _index(name):
    return DOF_NAMES.index(name)


def plot_simulation(trajectory, *, title: str | None = None):
    """Wheelset lateral displacement [mm] and yaw [mrad], frame accelerations [m/s^2]."""
    import matplotlib.pyplot as plt

    ts = np.asarray(trajectory.ts)
    q, qdd = np.asarray(trajectory.q), np.asarray(trajectory.qdd)
    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    for k, name in enumerate(("wheelset1", "wheelset2")):
        axes[0].plot(ts, 1e3 * q[:, _index(f"{name}.y")], label=f"{name} lateral")
        axes[1].plot(ts, 1e3 * q[:, _index(f"{name}.yaw")], label=f"{name} yaw")
    for name in ("frame.y", "frame.z"):
        axes[2].plot(ts, qdd[:, _index(name)], label=f"{name} acceleration")
    axes[0].set_ylabel("lateral [mm]")
    axes[1].set_ylabel("yaw [mrad]")
    axes[2].set_ylabel("acceleration [m/s$^2$]")
    axes[2].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    axes[0].set_title(title or f"bogie at {float(trajectory.speed):.1f} m/s")
    fig.tight_layout()
    return fig


def plot_stability(sweep, critical=None, ax=None):
    """Largest eigenvalue real part [1/s] against speed [m/s], with the critical speed marked."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(7, 4))
    ax.plot(np.asarray(sweep.speeds), np.asarray(sweep.max_real_part), "o-", ms=3)
    ax.axhline(0.0, color="k", lw=0.8)
    if critical is not None and bool(critical.found):
        v = float(critical.speed)
        ax.axvline(v, color="C3", ls="--", label=f"critical {v:.1f} m/s, {float(critical.frequency):.2f} Hz")
        ax.legend()
    ax.set_xlabel("speed [m/s]")
    ax.set_ylabel("max Re(eigenvalue) [1/s]")
    ax.grid(True, alpha=0.3)
    return ax


def plot_gradient_components(records, names, ax=None):
    """Gradient components dJ/dtheta_i by method, grouped by parameter (cf. paper figure 5).

    `records`: `bogie_jax.gradients.gradient_report` records of one selection (those with a
    `grad`); `names`: the parameter names. Symmetric-log y axis (components span decades).
    """
    import matplotlib.pyplot as plt

    records = [r for r in records if r.get("grad") is not None]
    if ax is None:
        _, ax = plt.subplots(figsize=(max(6.0, 0.5 * len(names) * len(records) / 3 + 3), 4))
    x = np.arange(len(names))
    width = 0.8 / max(len(records), 1)
    largest = max((np.max(np.abs(r["grad"])) for r in records), default=1.0) or 1.0
    for k, r in enumerate(records):
        ax.bar(x + (k - (len(records) - 1) / 2) * width, r["grad"], width, label=r["method"])
    ax.set_yscale("symlog", linthresh=1e-4 * largest)
    ax.set_xticks(x, names, rotation=60, ha="right", fontsize=8)
    ax.set_ylabel(r"$\partial J / \partial \theta_i$")
    ax.axhline(0.0, color="k", lw=0.6)
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=8, ncol=3)
    ax.figure.tight_layout()
    return ax


def plot_gradient_cost(records, ax=None):
    """Time per gradient over one forward solve against the number of parameters n, per method
    (log-log), with the slope of a cost proportional to n for reference."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(6.5, 4.5))
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
    ax.set_xlabel("number of parameters n")
    ax.set_ylabel("time per gradient / forward solve")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax.figure.tight_layout()
    return ax
