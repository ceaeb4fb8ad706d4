"""Regenerate the smooth Kalker fits hard-coded in `bogie_jax/contact/_kalker.py` (`_LOG_FIT`).

For each coefficient (C11, C22, C23) and each tabulated Poisson ratio (0, 0.25, 0.5) of Kalker's
Table E.3 (reference doc 2.2), fit ln C by least squares as a polynomial in x = ln(a/b) over the
19 table rows. The lowest common degree in 4..6 that reproduces every table node within 0.5 % is
used. Prints the array literal to paste into `_kalker.py`, and the worst node error.

Run: `python tests/reference/fit_kalker.py`
"""

import numpy as np

from bogie_jax.contact import KALKER_TABLE_A_OVER_B, KALKER_TABLE_E3


TOLERANCE = 0.005


def fit(degree: int) -> tuple[np.ndarray, float]:
    """Return the coefficients (coef, nu, degree + 1) and the worst relative node error."""
    x = np.log(KALKER_TABLE_A_OVER_B)
    coeffs = np.empty((3, 3, degree + 1))
    worst = 0.0
    for i in range(3):
        for j in range(3):
            table = KALKER_TABLE_E3[:, i, j]
            coeffs[i, j] = np.polyfit(x, np.log(table), degree)
            error = np.exp(np.polyval(coeffs[i, j], x)) / table - 1.0
            worst = max(worst, float(np.abs(error).max()))
    return coeffs, worst


def main() -> None:
    for degree in (4, 5, 6):
        coeffs, worst = fit(degree)
        if worst <= TOLERANCE:
            break
    else:
        raise RuntimeError("no degree in 4..6 meets the tolerance")
    print(f"# degree {degree}, worst node error {100 * worst:.3f} %")
    print("_LOG_FIT = np.array([")
    for i, name in enumerate(("C11", "C22", "C23")):
        print("    [  # " + name + ", nu = 0, 0.25, 0.5")
        for j in range(3):
            values = [repr(float(c)) for c in coeffs[i, j]]
            lines = [", ".join(values[k : k + 3]) for k in range(0, len(values), 3)]
            print("        [\n            " + ",\n            ".join(lines) + ",\n        ],")
        print("    ],")
    print("])")


if __name__ == "__main__":
    main()
