"""Field helper: every physical parameter carries its SI unit, valid range and plausible bounds.

The value itself stays an ordinary pytree leaf (differentiable, vmappable); the metadata lives in
the dataclass field, so there is one source of truth for units and bounds.
"""

import dataclasses
import math

import equinox as eqx
import jax
import numpy as np


class ParameterError(ValueError):
    """A physical parameter has an invalid value (names the field, value and valid range)."""


@dataclasses.dataclass(frozen=True)
class FieldSpec:
    """Metadata of one physical parameter.

    - `unit`: SI unit string.
    - `valid`: `(lo, hi)`: physically admissible values (closed interval); outside raises.
    - `bounds`: `(lo, hi)`: plausible range for identification and sensitivity studies.
    - `doc`: one-line description.
    """

    unit: str
    valid: tuple[float, float]
    bounds: tuple[float, float]
    doc: str


def physical(*, unit: str, valid: tuple[float, float], bounds: tuple[float, float], doc: str):
    """Declare a physical parameter field (a differentiable leaf with unit and bounds metadata)."""
    lo, hi = bounds
    if not (valid[0] <= lo < hi <= valid[1]):
        raise ValueError(f"bounds {bounds} must lie inside the valid range {valid} for `{doc}`")
    spec = FieldSpec(unit=unit, valid=valid, bounds=bounds, doc=doc)
    return eqx.field(converter=_as_float_array, metadata={"spec": spec})


def _as_float_array(x):
    if isinstance(x, jax.Array | np.ndarray) or hasattr(x, "aval"):
        return x
    return np.asarray(x, dtype=float) if isinstance(x, int | float) else x


def field_spec(module: eqx.Module, name: str) -> FieldSpec:
    """The `FieldSpec` of field `name` of a parameter module."""
    for f in dataclasses.fields(module):
        if f.name == name:
            return f.metadata["spec"]
    raise KeyError(name)


def spec_fields(module: eqx.Module):
    """Iterate over `(name, FieldSpec)` for the physical fields of `module`."""
    for f in dataclasses.fields(module):
        if "spec" in f.metadata:
            yield f.name, f.metadata["spec"]


def _is_concrete(x) -> bool:
    return not isinstance(x, jax.core.Tracer)


def validate_fields(module: eqx.Module, prefix: str) -> None:
    """Check every physical field of `module`: scalar, finite, inside its valid range.

    Values under a JAX transformation (tracers) are skipped: checks happen when a user builds
    parameters, before anything expensive runs.
    """
    for name, spec in spec_fields(module):
        value = getattr(module, name)
        if not _is_concrete(value):
            continue
        arr = np.asarray(value)
        where = f"`{prefix}.{name}`" if prefix else f"`{name}`"
        if arr.shape != ():
            raise ParameterError(
                f"{where} must be a scalar [{spec.unit}], got an array of shape {arr.shape}"
            )
        x = float(arr)
        lo, hi = spec.valid
        if not math.isfinite(x) or not (lo <= x <= hi):
            raise ParameterError(
                f"{where} = {x!r} {spec.unit} is outside its valid range [{lo:g}, {hi:g}] "
                f"{spec.unit} ({spec.doc})"
            )
