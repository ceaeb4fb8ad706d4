"""`benchmarks/_common.coverage_reading`: how per-element coverage counts read against a
calibrated monitor, checked against binomial sums written out with `math.comb`."""

import math
import sys
from pathlib import Path


sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import coverage_reading  # noqa: E402


def _pmf(k: int, n: int, p: float) -> float:
    return math.comb(n, k) * p**k * (1 - p) ** (n - k)


def test_the_chance_of_a_calibrated_monitor_in_the_band_is_the_binomial_sum():
    """One element of 50 intervals: 90-98 % means 45-49 covered."""
    expected = sum(_pmf(k, 50, 0.95) for k in range(45, 50))
    text = coverage_reading({"a": (47, 50)})
    assert f"with probability {expected:.2f} " in text
    two = coverage_reading({"a": (47, 50), "b": (48, 50)})
    assert f"with probability {expected**2:.2f} " in two


def test_under_and_over_coverage_beyond_chance_are_named():
    """43 of 50 has a lower tail below 2.5 % (under); 50 of 50 has 0.95^50 = 7.7 % (not beyond
    chance); 100 of 100 has 0.6 % (over)."""
    assert sum(_pmf(k, 50, 0.95) for k in range(44)) < 0.025
    assert 0.95**50 > 0.025 and 0.95**100 < 0.025
    text = coverage_reading({"a": (43, 50), "b": (50, 50), "c": (100, 100)})
    assert "a 43/50 under" in text and "c 100/100 over" in text and "b 50/50" not in text
    assert "beyond chance for a calibrated monitor (binomial, 5 %): none" in coverage_reading(
        {"a": (47, 50)}
    )
