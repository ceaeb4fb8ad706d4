"""Checks of sensitivity inputs, run on concrete values before any model evaluation."""

from collections.abc import Sequence

import numpy as np

from .._validation import (
    check_positive_int as check_positive_int,
    check_power_of_two as check_power_of_two,
)


def default_names(n: int) -> tuple[str, ...]:
    return tuple(f"x{i}" for i in range(n))


def check_bounds(lower, upper, names: Sequence[str] | None = None):
    """Return `(lower, upper)` as float numpy vectors, or raise naming the first bad parameter.

    **Raises:** `ValueError` unless both are finite 1-D vectors of one length (matching `names`)
    with `lower < upper` element by element.
    """
    lo = np.asarray(lower, dtype=float)
    hi = np.asarray(upper, dtype=float)
    if lo.ndim != 1 or lo.shape != hi.shape or lo.size == 0:
        raise ValueError(
            f"`lower` and `upper` must be non-empty 1-D vectors of one length, got shapes "
            f"{lo.shape} and {hi.shape}"
        )
    names = tuple(names) if names is not None else default_names(lo.size)
    if len(names) != lo.size:
        raise ValueError(f"`names` has {len(names)} entries but the bounds have {lo.size}")
    for i, name in enumerate(names):
        if not (np.isfinite(lo[i]) and np.isfinite(hi[i])):
            raise ValueError(f"bounds of `{name}` must be finite, got [{lo[i]:g}, {hi[i]:g}]")
        if not lo[i] < hi[i]:
            raise ValueError(
                f"bounds of `{name}` need lower < upper, got lower = {lo[i]:g} >= upper = {hi[i]:g}"
            )
    return lo, hi


def check_point_in_bounds(name: str, point, lower, upper, names: Sequence[str]):
    """Return `point` as a float vector of the bounds' length lying inside them, or raise."""
    x = np.asarray(point, dtype=float)
    if x.shape != np.shape(lower):
        raise ValueError(f"`{name}` must have shape {np.shape(lower)}, got {x.shape}")
    for i, pname in enumerate(names):
        if not (np.isfinite(x[i]) and lower[i] <= x[i] <= upper[i]):
            raise ValueError(
                f"`{name}` of `{pname}` = {x[i]:g} is outside its bounds "
                f"[{lower[i]:g}, {upper[i]:g}]"
            )
    return x


def resolve_names(requested: Sequence[str | int], names: Sequence[str]) -> tuple[int, ...]:
    """Map parameter names (or integer positions) to positions, or raise naming the unknown one."""
    if isinstance(requested, str | int):
        requested = (requested,)
    positions = []
    for r in requested:
        if isinstance(r, str):
            if r not in names:
                raise ValueError(f"unknown parameter `{r}`; known parameters: {', '.join(names)}")
            positions.append(names.index(r))
        elif isinstance(r, int | np.integer) and not isinstance(r, bool) and 0 <= r < len(names):
            positions.append(int(r))
        else:
            raise ValueError(
                f"parameter {r!r} is neither a known name nor a position in [0, {len(names)})"
            )
    if len(set(positions)) != len(positions):
        raise ValueError(f"parameters must be distinct, got {tuple(requested)!r}")
    return tuple(positions)
