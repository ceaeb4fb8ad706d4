"""Generalised coordinates of the 10-DOF bogie (paper eq. 1) and the state layout.

q = (x_f, y_f, z_f, roll_f, pitch_f, yaw_f, y_1, y_2, yaw_1, yaw_2):
frame displacements from static equilibrium [m], frame Cardan angles [rad] (R = Rz Ry Rx),
lateral displacements [m] and yaw angles [rad] of the leading (1) and trailing (2) wheelset.
The ODE state is y = (q, q_dot), 20 entries.
"""

DOF_NAMES: tuple[str, ...] = (
    "frame.x",
    "frame.y",
    "frame.z",
    "frame.roll",
    "frame.pitch",
    "frame.yaw",
    "wheelset1.y",
    "wheelset2.y",
    "wheelset1.yaw",
    "wheelset2.yaw",
)
DOF_UNITS: tuple[str, ...] = ("m", "m", "m", "rad", "rad", "rad", "m", "m", "rad", "rad")
N_DOF = len(DOF_NAMES)
FRAME = slice(0, 6)
WHEELSET_LATERAL = slice(6, 8)
WHEELSET_YAW = slice(8, 10)
GRAVITY = 9.81  # [m/s^2]


def dof_index(name: str) -> int:
    """Index of the generalised coordinate `name` (one of `DOF_NAMES`)."""
    try:
        return DOF_NAMES.index(name)
    except ValueError:
        raise ValueError(f"unknown coordinate `{name}`; valid: {', '.join(DOF_NAMES)}") from None
