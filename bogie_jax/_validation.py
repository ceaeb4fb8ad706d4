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


def check_range(
    name: str,
    value,
    lo: float,
    hi: float,
    unit: str = "",
    *,
    open_lo: bool = False,
    open_hi: bool = False,
):
    """Raise ValueError naming `name`, its value and the valid range unless value is finite and
    lies in [lo, hi] (`open_lo`, `open_hi`: that end excluded; `hi` may be `inf`)."""
    x = _concrete_float(name, value)
    if x is None:
        return
    ok = math.isfinite(x) and (x > lo if open_lo else x >= lo) and (x < hi if open_hi else x <= hi)
    if not ok:
        left, right = "(" if open_lo else "[", ")" if open_hi or math.isinf(hi) else "]"
        unit = f" {unit}" if unit else ""
        raise ValueError(
            f"`{name}` = {x:g}{unit} is outside the valid range {left}{lo:g}, {hi:g}{right}{unit}"
        )


def check_number(name: str, value, lo: float, hi: float, unit: str = "", **ends) -> float:
    """`value` as a float: a real number (not a bool or a string) in the range of `check_range`
    (`ends`: its `open_lo`, `open_hi`). **Raises:** `ValueError` naming `name`."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ValueError(f"`{name}` = {value!r} must be a number{f' [{unit}]' if unit else ''}")
    check_range(name, value, lo, hi, unit, **ends)
    return float(value)


def check_positive_int(name: str, value, hi: int = 10**9, *, lo: int = 1) -> int:
    """`value` as an int, or `ValueError` naming `name` unless it is an integer in [lo, hi]."""
    if (
        isinstance(value, bool)
        or not isinstance(value, int | np.integer)
        or not (lo <= value <= hi)
    ):
        raise ValueError(f"`{name}` must be an integer in [{lo}, {hi}], got {value!r}")
    return int(value)


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


def nonempty_tuple(name: str, values, kind: type, hint: str) -> tuple:
    """`values` (an iterable) as a tuple of `kind` instances. **Raises:** `ValueError` naming
    `name` with `hint` (what to give) when it is empty, `TypeError` naming the first entry that
    is not a `kind`."""
    values = tuple(values)
    if not values:
        raise ValueError(f"`{name}` is empty: {hint}")
    article = "an" if kind.__name__[0] in "AEIOUaeiou" else "a"
    for k, value in enumerate(values):
        if not isinstance(value, kind):
            raise TypeError(
                f"`{name}[{k}]` must be {article} {kind.__name__}, got {type(value).__name__}"
            )
    return values
