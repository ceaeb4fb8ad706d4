"""Save a simulated `Trajectory` as `.npz` or `.csv`.

CSV format: one header line `time_s,<coordinate>[unit],...` with, for each generalised coordinate
of `bogie_jax.model.DOF_NAMES`, its value, rate (`_dot`) and acceleration (`_ddot`) columns,
then one row per sample. The `.npz` holds arrays `ts`, `q`, `qd`, `qdd`, `speed`, `dof_names`,
`dof_units` and `successful`.
"""

from pathlib import Path

import numpy as np

from ..model import DOF_NAMES, DOF_UNITS
from ..simulation import Trajectory


def _columns():
    names, units = [], []
    for suffix, per in (("", ""), ("_dot", "/s"), ("_ddot", "/s^2")):
        names += [f"{n}{suffix}" for n in DOF_NAMES]
        units += [f"{u}{per}" for u in DOF_UNITS]
    return names, units


def save_trajectory(path, trajectory: Trajectory) -> Path:
    """Write `trajectory` to `path` (`.npz` or `.csv`, chosen by the suffix); returns the path."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".npz", ".csv"):
        raise ValueError(f"`path` must end in .npz or .csv, got {str(path)!r}")
    path.parent.mkdir(parents=True, exist_ok=True)
    ts, q = np.asarray(trajectory.ts), np.asarray(trajectory.q)
    qd, qdd = np.asarray(trajectory.qd), np.asarray(trajectory.qdd)
    if suffix == ".npz":
        np.savez(
            path,
            ts=ts,
            q=q,
            qd=qd,
            qdd=qdd,
            speed=np.asarray(trajectory.speed),
            dof_names=np.array(DOF_NAMES),
            dof_units=np.array(DOF_UNITS),
            successful=np.asarray(trajectory.successful),
        )
    else:
        names, units = _columns()
        header = ",".join(["time_s"] + [f"{n}[{u}]" for n, u in zip(names, units)])
        np.savetxt(
            path, np.column_stack([ts, q, qd, qdd]), delimiter=",", header=header, comments=""
        )
    return path
