"""Sensor layouts compared by the identifiability study and the `sensitivity` command."""

from ..measure import Accelerometer, Axlebox, DisplacementSensor, FramePoint, default_sensor_layout


LAYOUTS = ("default", "displacement", "frame-acc", "frame+axlebox-acc")


def sensor_layouts(params) -> dict[str, tuple]:
    """`{name: sensors}` for the layouts of the identifiability study (geometry of `params`):

    - `default`: the 13-channel default layout of `bogie_jax.measure`;
    - `displacement`: frame displacements (the paper's choice): lateral and vertical
      `DisplacementSensor`s on the frame above each axlebox, `frame_{1,2}{L,R}_d{y,z}` (8);
    - `frame-acc`: frame accelerometers at the same points, `frame_{1,2}{L,R}_{y,z}` (8);
    - `frame+axlebox-acc`: `frame-acc` plus the axlebox lateral accelerometers (12).
    """
    g = params.geometry
    a, b = float(g.semi_wheelbase), float(g.primary_semi_spacing)
    disp, acc, axle = [], [], []
    for ws, x in ((1, a), (2, -a)):
        for side, sign in (("L", 1.0), ("R", -1.0)):
            point = FramePoint(x, sign * b, 0.0)
            for axis in ("y", "z"):
                disp.append(DisplacementSensor(f"frame_{ws}{side}_d{axis}", point, axis))
                acc.append(Accelerometer(f"frame_{ws}{side}_{axis}", point, axis))
    for ws in (1, 2):
        for side, name in (("L", "left"), ("R", "right")):
            axle.append(Accelerometer(f"axlebox_{ws}{side}_y", Axlebox(ws, name), "y"))
    return {
        "default": default_sensor_layout(params),
        "displacement": tuple(disp),
        "frame-acc": tuple(acc),
        "frame+axlebox-acc": tuple(acc + axle),
    }
