"""How far a wheel lies from the wear family that `WheelWear` spans (a diagnostic; prints).

For the shipped half-worn wheel (`half-worn-uic60`): the raw contact table's rolling radius
difference, contact-angle difference (tangents) and roll over |y| <= 6 mm against the nearest
blend of the new S1002's and the worn wheel's tables, each misfit as the RMS of the difference
relative to the wheel's own RMS, then with the blend's Delta r scaled (`wear.conicity_factor`)
and the contact-angle difference scaled too, and with an odd polynomial in y (to fifth order)
added to the blend's Delta r; and the equivalent conicities at 1 and 3 mm. Run: `python
benchmarks/wear_family.py` (seconds; `--wheel NAME` for another shipped pair).
"""

import argparse

import numpy as np
from scipy.optimize import least_squares

from bogie_jax.contact import equivalent_conicity, named_contact_table


SPAN = 0.006  # [m]: |y| compared
AMPLITUDES = np.array([1e-3, 3e-3])  # [m]


def quantities(table) -> dict:
    angle = np.tan(table.contact_angle)
    return {
        "dr": table.rolling_radius_difference,
        "dta": angle[:, 0] - angle[:, 1],
        "roll": table.roll,
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--wheel", default="half-worn-uic60")
    args = p.parse_args()
    tables = [named_contact_table(k) for k in ("s1002-uic60", "worn-uic60", args.wheel)]
    new, worn, wheel = (quantities(t) for t in tables)
    y = tables[0].lateral
    inside = np.abs(y) <= SPAN

    def blend(level, k_dr=1.0, k_dta=1.0):
        out = {key: (1 - level) * new[key] + level * worn[key] for key in new}
        return {**out, "dr": k_dr * out["dr"], "dta": k_dta * out["dta"]}

    def misfits(model) -> dict:
        return {
            key: float(
                np.linalg.norm((model[key] - wheel[key])[inside])
                / np.linalg.norm(wheel[key][inside])
            )
            for key in wheel
        }

    def residual(x, free):
        m = misfits(blend(x[0], *(x[1 : 1 + free])))
        return np.array(list(m.values()))

    levels = []
    for free, what in (
        (0, "level"),
        (1, "level, Delta r factor"),
        (2, "level, Delta r and angle factors"),
    ):
        fit = least_squares(residual, [0.5, 1.0, 1.0][: 1 + free], args=(free,))
        levels.append(fit.x[0])
        m = misfits(blend(fit.x[0], *fit.x[1:]))
        print(
            f"{what}: {np.round(fit.x, 3)}; relative misfit "
            + ", ".join(f"{k} {v:.3f}" for k, v in m.items())
        )
    base = blend(levels[0])["dr"][inside]  # the nearest blend, no factor
    ys = y[inside]
    for order in (1, 3, 5):
        basis = np.stack([ys**n for n in range(1, order + 1, 2)], axis=1)
        c, *_ = np.linalg.lstsq(basis, wheel["dr"][inside] - base, rcond=None)
        left = np.linalg.norm(base + basis @ c - wheel["dr"][inside]) / np.linalg.norm(
            wheel["dr"][inside]
        )
        print(f"Delta r with an odd polynomial to order {order} added: relative misfit {left:.3f}")
    for name, t in zip(("new", "worn", args.wheel), tables):
        gamma = equivalent_conicity(t.lateral, t.rolling_radius_difference, AMPLITUDES)
        print(f"equivalent conicity of {name} at 1, 3 mm: {np.round(gamma, 3)}")


if __name__ == "__main__":
    main()
