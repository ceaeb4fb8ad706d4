"""Figures of one run: the simulated trajectory, and linear stability against speed."""

import numpy as np

from ..model import DOF_NAMES
from ._common import get_axes


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
    ax = get_axes(ax, (7, 4))
    ax.plot(np.asarray(sweep.speeds), np.asarray(sweep.max_real_part), "o-", ms=3)
    ax.axhline(0.0, color="k", lw=0.8)
    if critical is not None and bool(critical.found):
        v = float(critical.speed)
        label = f"critical {v:.1f} m/s, {float(critical.frequency):.2f} Hz"
        ax.axvline(v, color="C3", ls="--", label=label)
        ax.legend()
    ax.set_xlabel("speed [m/s]")
    ax.set_ylabel("max Re(eigenvalue) [1/s]")
    ax.grid(True, alpha=0.3)
    return ax
