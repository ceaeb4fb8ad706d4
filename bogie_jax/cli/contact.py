"""`bogie-jax contact`: the contact table and equivalent conicity of a wheel/rail profile pair.

Writes `contact_table.csv` (one row per lateral displacement, each column with its unit),
`conicity.json` (`equivalent_conicity_3mm` and the curve over amplitude) and `contact.png`
(profiles in contact at a few displacements, the rolling-radius difference, the conicity curve).
Without `--wheel`/`--rail` it uses the package's shipped S1002 and UIC60 1:40 (the Manchester
Contact Benchmark pair, `bogie_jax/contact/profiles/README.md`).
"""

import json
import pathlib

import numpy as np

from ..contact import (
    COLUMNS,
    ContactTable,
    ProfileError,
    ProfileSetup,
    contact_table,
    equivalent_conicity,
    place_profiles,
    profile_pair,
    read_profile,
)
from ._common import UsageError


AMPLITUDES_MM = tuple(round(0.5 * k, 1) for k in range(1, 21))  # 0.5 ... 10 mm


def add_parser(sub):
    p = sub.add_parser("contact", help="contact table and equivalent conicity of a profile pair")
    add = p.add_argument
    add("--wheel", default=None, help="wheel profile: .prw or .csv (y, z in mm, z down)")
    add("--rail", default=None, help="rail profile: .prr or .csv (y, z in mm, z down)")
    add("--out", default="contact", help="output directory (default ./contact)")
    add("--gauge", type=float, default=1435.0, help="track gauge [mm] (default 1435)")
    add("--gauge-height", type=float, default=14.0, help="gauge point below rail top [mm]")
    add("--flange-back-spacing", type=float, default=1360.0, help="[mm] (default 1360)")
    add("--rail-cant", type=float, default=0.0, help="extra rail inclination [rad] (0: as read)")
    add("--wheel-radius", type=float, default=460.0, help="nominal rolling radius [mm]")
    add("--flange-back", type=float, default=-70.0, help="flange back y in the wheel file [mm]")
    add("--max-lateral", type=float, default=12.0, help="table half range [mm] (default 12)")
    add("--step", type=float, default=0.05, help="table step [mm] (default 0.05)")
    return p


def _setup(args) -> ProfileSetup:
    return ProfileSetup(
        gauge=1e-3 * args.gauge,
        gauge_height=1e-3 * args.gauge_height,
        flange_back_spacing=1e-3 * args.flange_back_spacing,
        rail_cant=args.rail_cant,
        wheel_radius=1e-3 * args.wheel_radius,
        flange_back=1e-3 * args.flange_back,
    )


def _profiles(args):
    if (args.wheel is None) != (args.rail is None):
        raise UsageError("give both `--wheel` and `--rail`, or neither (the shipped S1002/UIC60)")
    if args.wheel is None:
        wheel, rail, _ = profile_pair("s1002-uic60")
        return wheel, rail
    return read_profile(args.wheel, kind="wheel"), read_profile(args.rail, kind="rail")


def run(args, progress) -> int:
    try:
        wheel, rail = _profiles(args)
        placed = place_profiles(wheel, rail, _setup(args))
        table = contact_table(placed, max_lateral=1e-3 * args.max_lateral, step=1e-3 * args.step)
        amplitudes = np.array([a for a in AMPLITUDES_MM if a <= args.max_lateral]) * 1e-3
        gamma = equivalent_conicity(table.lateral, table.rolling_radius_difference, amplitudes)
        gamma_3mm = float(equivalent_conicity(table.lateral, table.rolling_radius_difference, 3e-3))
    except (ProfileError, ValueError) as e:
        raise UsageError(str(e)) from None
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_table_csv(table, out / "contact_table.csv")
    (out / "conicity.json").write_text(
        json.dumps(
            {
                "wheel": wheel.source,
                "rail": rail.source,
                "equivalent_conicity_3mm": gamma_3mm,
                "method": "harmonic linearisation of Delta r (UIC 519 / EN 15302)",
                "amplitude_mm": [round(1e3 * a, 3) for a in amplitudes],
                "equivalent_conicity": [float(g) for g in gamma],
            },
            indent=2,
        )
    )
    plot_contact(placed, table, amplitudes, gamma).savefig(out / "contact.png", dpi=110)
    progress.say(f"equivalent conicity at 3 mm: {gamma_3mm:.4f}")
    names = ", ".join(str(out / n) for n in ("contact_table.csv", "conicity.json", "contact.png"))
    progress.say(f"wrote {names}")
    return 0


def write_table_csv(table: ContactTable, path) -> None:
    """One row per lateral displacement; lengths in mm, angles in rad, curvatures in 1/m."""
    scale = {"m": (1e3, "mm"), "rad": (1.0, "rad"), "1/m": (1.0, "1/m")}
    header = ["lateral [mm]", "roll [rad]", "height [mm]"]
    data = [1e3 * table.lateral, table.roll, 1e3 * table.height]
    for name, unit, _ in COLUMNS:
        factor, shown = scale[unit]
        values = getattr(table, name)
        for j, side in enumerate(("left", "right")):
            header.append(f"{name}_{side} [{shown}]")
            data.append(factor * values[:, j])
    np.savetxt(path, np.column_stack(data), delimiter=",", header=",".join(header), comments="")


def plot_contact(placed, table: ContactTable, amplitudes, gamma):
    """Left wheel on its rail at a few displacements, Delta r(y), and tan(gamma_e)(amplitude)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax0, ax1, ax2) = plt.subplots(1, 3, figsize=(15, 4.5))
    rail_y = np.linspace(*placed.rail_span, 400)
    ax0.plot(1e3 * rail_y, 1e3 * placed.rail(rail_y), "k", label="rail")
    wheel_u = np.linspace(*placed.wheel_span, 600)
    for y in (-6e-3, 0.0, 3e-3, 6e-3):
        k = int(np.argmin(np.abs(table.lateral - y)))
        c, s = np.cos(table.roll[k]), np.sin(table.roll[k])
        big_z = placed.wheel(wheel_u)
        ax0.plot(
            1e3 * (table.lateral[k] + c * wheel_u - s * big_z),
            1e3 * (table.height[k] + s * wheel_u + c * big_z),
            label=f"y = {1e3 * table.lateral[k]:+.0f} mm",
        )
        ax0.plot(1e3 * table.rail_contact_y[k, 0], 1e3 * table.rail_contact_z[k, 0], "o", ms=4)
    ax0.set(xlabel="track y [mm]", ylabel="z [mm]", title="left wheel on left rail", ylim=(-20, 25))
    ax0.legend(fontsize=8)
    ax1.plot(1e3 * table.lateral, 1e3 * table.rolling_radius_difference)
    ax1.set(xlabel="lateral displacement [mm]", ylabel="r_left - r_right [mm]", title="Delta r")
    ax2.plot(1e3 * amplitudes, gamma, "o-")
    ax2.set(xlabel="amplitude [mm]", ylabel="tan(gamma_e)", title="equivalent conicity")
    for ax in (ax0, ax1, ax2):
        ax.grid(True)
    fig.tight_layout()
    return fig
