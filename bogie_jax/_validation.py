"""Checks of user input at public entry points: clear messages before anything expensive runs."""

import math

import jax
import numpy as np


def _concrete_float(name: str, value):
    if isinstance(value, jax.core.Tracer):
        return None
    try:
        return float(value)
    except (TypeError, ValueError):
        raise TypeError(f"`{name}` must be a real number, got {value!r}") from None


def check_range(name: str, value, lo: float, hi: float, unit: str = "", *, open_lo: bool = False):
    """Raise ValueError naming `name`, its value and the valid range unless lo <(=) value <= hi."""
    x = _concrete_float(name, value)
    if x is None:
        return
    ok = math.isfinite(x) and (x > lo if open_lo else x >= lo) and x <= hi
    if not ok:
        bracket = "(" if open_lo else "["
        unit = f" {unit}" if unit else ""
        raise ValueError(
            f"`{name}` = {x:g}{unit} is outside the valid range {bracket}{lo:g}, {hi:g}]{unit}"
        )


def check_positive_int(name: str, value, hi: int = 10**9):
    if isinstance(value, bool) or not isinstance(value, int) or not (1 <= value <= hi):
        raise ValueError(f"`{name}` must be an integer in [1, {hi}], got {value!r}")


def check_power_of_two(name: str, value) -> int:
    """Return `value` as an int, or raise ValueError unless it is a power of two >= 2."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise TypeError(f"`{name}` must be an integer power of two, got {value!r}")
    value = int(value)
    if value < 2 or value & (value - 1):
        below = 1 << max(value.bit_length() - 1, 1)
        raise ValueError(
            f"`{name}` must be a power of two >= 2 (the balance properties of a Sobol' design "
            f"hold only then), got {value}; try {below} or {2 * below}"
        )
    return value
