"""`bogie_jax.identify.restart_vanished`: a log coordinate a fit left near zero is restarted at
its reference, and the restart is kept only where it ends lower.

The model m = p1 u + p2 (p1 - 1) w, w = -3 u + v (v orthogonal to u), fitted in phi = ln p, has
a minimum on the boundary p2 -> 0 (p1 about 0.6: there, raising p2 raises the cost) beside the
optimum. m = A u + B v with A = p1 - 3 B, B = p2 (p1 - 1), so numpy's linear least squares for
(A, B) gives the optimum exactly: the oracle.
"""

import dataclasses

import numpy as np

from bogie_jax.identify import levenberg_marquardt, restart_vanished


T = np.linspace(0.0, 4.0, 300)
U = np.exp(-T)
V = np.sin(2.0 * T) - (np.sin(2.0 * T) @ U) / (U @ U) * U
W = -3.0 * U + V
LEVEL = np.log(1e-3)


def _data(b: float, seed: int) -> np.ndarray:
    """Data 0.5 u + b v plus noise (b = 0.5: p = (2, 0.5))."""
    return 0.5 * U + b * V + 0.01 * np.random.default_rng(seed).normal(size=T.size)


def _evaluate(data):
    def evaluate(phi):
        p1, p2 = np.exp(phi)
        jac = np.stack([p1 * (U + p2 * W), p2 * (p1 - 1.0) * W], axis=1)
        return p1 * U + p2 * (p1 - 1.0) * W - data, jac

    return evaluate


def test_a_coordinate_left_near_zero_is_restarted_and_reaches_the_optimum():
    data = _data(0.5, seed=5)
    evaluate = _evaluate(data)
    a, b = np.linalg.lstsq(np.stack([U, V], axis=1), data, rcond=None)[0]
    p1 = a + 3.0 * b
    optimum = np.array([p1, b / (p1 - 1.0)])
    least = 0.5 * np.sum((a * U + b * V - data) ** 2)

    stranded = levenberg_marquardt(evaluate, np.array([0.0, -20.0]), max_steps=100)
    assert stranded.status == "converged" and stranded.phi[1] < LEVEL  # the boundary minimum
    assert stranded.cost > 100.0 * least

    revived = restart_vanished(evaluate, stranded, [0, 1], level=LEVEL, max_steps=100)

    assert revived is not stranded and revived.status == "converged"
    assert revived.cost < 1.01 * least  # LM stops short of the optimum by a fraction of an SE
    np.testing.assert_allclose(np.exp(revived.phi), optimum, rtol=2e-3)


def test_nothing_above_the_level_or_outside_the_coordinates_is_restarted():
    evaluate = _evaluate(_data(0.5, seed=5))
    fitted = levenberg_marquardt(evaluate, np.array([0.5, -1.0]), max_steps=100)
    assert fitted.phi[1] > LEVEL
    assert restart_vanished(evaluate, fitted, [0, 1], level=LEVEL) is fitted
    stranded = levenberg_marquardt(evaluate, np.array([0.0, -20.0]), max_steps=100)
    assert restart_vanished(evaluate, stranded, [0], level=LEVEL) is stranded
    assert restart_vanished(evaluate, stranded, [], level=LEVEL) is stranded
    failed = dataclasses.replace(stranded, status="failed")
    assert restart_vanished(evaluate, failed, [0, 1], level=LEVEL) is failed


def test_a_restart_that_ends_higher_is_not_kept():
    """Data with B = 0.05: B > 0 needs p1 > 1, so A >= 1 - 3 B = 0.85 against the data's 0.5,
    and p1 < 1 needs B < 0; the boundary p2 -> 0 (p1 = 0.5, B = 0) is the optimum, and a
    restart from p2 = 1 ends above it."""
    evaluate = _evaluate(_data(0.05, seed=6))
    stranded = levenberg_marquardt(evaluate, np.array([0.0, -20.0]), max_steps=100)
    assert stranded.phi[1] < LEVEL
    restart = stranded.phi.copy()
    restart[1] = 0.0
    again = levenberg_marquardt(evaluate, restart, max_steps=100)
    assert again.cost > stranded.cost  # the premise, measured

    kept = restart_vanished(evaluate, stranded, [0, 1], level=LEVEL, max_steps=100)

    assert kept is stranded
