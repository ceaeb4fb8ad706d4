"""Field helper: every physical parameter carries its SI unit, valid range and plausible bounds.

The value itself stays an ordinary pytree leaf (differentiable, vmappable); the metadata lives in
the dataclass field, so there is one source of truth for units and bounds.

A per-element field (`physical(..., elements=("1L", "1R", "2L", "2R"))`) holds one value per
suspension element, an array of shape (n_elements,); a scalar given to the constructor is
broadcast to every element, so a symmetric group is written as before (`kz=1.22e6`).
"""

import dataclasses
import math

import equinox as eqx
import jax
import jax.numpy as jnp
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
    - `elements`: labels of the elements of a per-element field (value shape (n,)), in the
      order of the value's entries; `()` for a scalar field. Valid range and bounds hold for
      every element.
    """

    unit: str
    valid: tuple[float, float]
    bounds: tuple[float, float]
    doc: str
    elements: tuple[str, ...] = ()

    @property
    def shape(self) -> tuple[int, ...]:
        """Shape of the field's value: () or (n_elements,)."""
        return (len(self.elements),) if self.elements else ()


def physical(
    *,
    unit: str,
    valid: tuple[float, float],
    bounds: tuple[float, float],
    doc: str,
    elements: tuple[str, ...] = (),
):
    """Declare a physical parameter field (a differentiable leaf with unit and bounds metadata);
    with `elements`, one value per element (a scalar argument is broadcast to all of them)."""
    lo, hi = bounds
    if not (valid[0] <= lo < hi <= valid[1]):
        raise ValueError(f"bounds {bounds} must lie inside the valid range {valid} for `{doc}`")
    spec = FieldSpec(unit=unit, valid=valid, bounds=bounds, doc=doc, elements=tuple(elements))
    converter = _per_element(len(elements)) if elements else _as_float_array
    return eqx.field(converter=converter, metadata={"spec": spec})


def _as_float_array(x):
    if isinstance(x, jax.Array | np.ndarray) or hasattr(x, "aval"):
        return x
    return np.asarray(x, dtype=float) if isinstance(x, int | float) else x


def _per_element(n: int):
    """Converter of a per-element field: a scalar becomes n equal values; a list or tuple an
    array; an array of another shape is kept (validation names it)."""

    def convert(x):
        if isinstance(x, list | tuple):
            x = np.asarray(x, dtype=float)
        x = _as_float_array(x)
        if np.shape(x) != ():
            return x
        if isinstance(x, np.ndarray):
            return np.full(n, float(x))
        return jnp.broadcast_to(x, (n,))

    return convert


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
    """Check every physical field of `module`: its shape (scalar, or one value per element),
    finite, inside its valid range (elementwise).

    Values under a JAX transformation (tracers) are skipped: checks happen when a user builds
    parameters, before anything expensive runs.
    """
    for name, spec in spec_fields(module):
        value = getattr(module, name)
        if not _is_concrete(value):
            continue
        arr = np.asarray(value)
        where = f"`{prefix}.{name}`" if prefix else f"`{name}`"
        if arr.shape != spec.shape:
            per_element = (
                f" (or one value per element {', '.join(spec.elements)}: shape {spec.shape})"
                if spec.elements
                else ""
            )
            raise ParameterError(
                f"{where} must be a scalar [{spec.unit}], got an array of shape {arr.shape}"
                + per_element
            )
        lo, hi = spec.valid
        flat = np.atleast_1d(arr).astype(float)
        uniform = bool(np.all(flat == flat[0])) or bool(np.all(np.isnan(flat)))
        for label, x in zip(spec.elements or ("",), flat):
            x = float(x)
            if not math.isfinite(x) or not (lo <= x <= hi):
                at = f" at element {label}" if label and not uniform else ""
                raise ParameterError(
                    f"{where} = {x!r} {spec.unit}{at} is outside its valid range "
                    f"[{lo:g}, {hi:g}] {spec.unit} ({spec.doc})"
                )
