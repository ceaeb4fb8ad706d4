"""Parameter names from tree paths, with their `FieldSpec`s, and reading/writing by name.

Two kinds of names:
- a **tied** name is the tree path, e.g. `primary.kz` or `masses.frame.mass`. For a per-element
  field (suspension, one value per axlebox or side) it addresses all elements together: reading
  gives their common value, writing sets every element.
- an **element** name addresses one element of a per-element field: the group path, the element
  label, the field, e.g. `primary.1L.kz`, `primary.2R.cz` (axleboxes 1L, 1R, 2L, 2R: wheelset 1
  leading, L = +y), `secondary.left.cy`, `yaw_dampers.right.c`.
"""

import dataclasses
import difflib
import functools as ft
from collections.abc import Mapping

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._spec import FieldSpec


def parameter_specs(
    params: eqx.Module, prefix: str = "", *, elements: bool = False
) -> dict[str, FieldSpec]:
    """All physical parameters of `params` as `{dotted.name: FieldSpec}` in tree order.

    With `elements=True` each per-element field's tied name is followed by its element names
    (`primary.kz`, `primary.1L.kz`, ..., `primary.2R.kz`); the element names share the field's
    spec (unit, valid range and bounds hold per element).
    """
    out: dict[str, FieldSpec] = {}
    for f in dataclasses.fields(params):
        name = f"{prefix}{f.name}"
        value = getattr(params, f.name)
        if "spec" in f.metadata:
            spec = f.metadata["spec"]
            out[name] = spec
            if elements:
                out.update({f"{prefix}{label}.{f.name}": spec for label in spec.elements})
        elif isinstance(value, eqx.Module):
            out.update(parameter_specs(value, prefix=name + ".", elements=elements))
    return out


def parameter_names(params: eqx.Module, *, elements: bool = False) -> tuple[str, ...]:
    """Dotted names of all physical parameters of `params` (e.g. `primary.kz`); with
    `elements=True` the element names too (e.g. `primary.1L.kz`), see `parameter_specs`."""
    return tuple(parameter_specs(params, elements=elements))


def element_names(params: eqx.Module) -> tuple[str, ...]:
    """The element names of all per-element fields (`primary.1L.kx`, ..., `yaw_dampers.right.c`)."""
    tied = parameter_specs(params)
    return tuple(n for n in parameter_specs(params, elements=True) if n not in tied)


@dataclasses.dataclass(frozen=True)
class ParameterPath:
    """A resolved parameter name.

    - `name`: the name as given; `path`: attribute path of its leaf in the tree;
    - `element`: index of the element of a per-element leaf, `None` for a tied or scalar name;
    - `spec`: the field's `FieldSpec`.
    """

    name: str
    path: tuple[str, ...]
    element: int | None
    spec: FieldSpec

    @property
    def tied_name(self) -> str:
        """The leaf's tied name (`primary.kz` for `primary.1L.kz`)."""
        return ".".join(self.path)

    @property
    def is_tied_group(self) -> bool:
        """True for a tied name of a per-element field (all its elements at once)."""
        return bool(self.spec.elements) and self.element is None


def resolve_parameter(params: eqx.Module, name: str, context: str = "") -> ParameterPath:
    """Resolve a tied or element name of `params` (`context`, e.g. " in `names`", goes into the
    error message after the name).

    **Raises:** `ValueError` naming the value and the valid choices: an unknown name, or an
    unknown element label of a per-element field (`primary.3L.kz`, `yaw_dampers.middle.c`).
    """
    tied = parameter_specs(params)
    if not isinstance(name, str):
        raise ValueError(f"a parameter name must be a string, got {name!r}")
    if name in tied:
        return ParameterPath(name, tuple(name.split(".")), None, tied[name])
    parts = name.split(".")
    if len(parts) >= 3:
        field = ".".join(parts[:-2] + parts[-1:])
        spec = tied.get(field)
        if spec is not None and spec.elements:
            label = parts[-2]
            if label in spec.elements:
                index = spec.elements.index(label)
                return ParameterPath(name, tuple(field.split(".")), index, spec)
            group = ".".join(parts[:-2])
            raise ValueError(
                f"unknown element {label!r} in parameter {name!r}{context}: the elements of "
                f"`{group}` are "
                f"{', '.join(spec.elements)} (e.g. `{group}.{spec.elements[0]}.{parts[-1]}`), or "
                f"`{field}` for all of them"
            )
    valid = parameter_names(params, elements=True)
    close = difflib.get_close_matches(name, valid, n=3)
    hint = f" (did you mean {', '.join(close)}?)" if close else ""
    raise ValueError(f"unknown parameter {name!r}{context}{hint}; valid names: {', '.join(valid)}")


def _leaf(params, path):
    return ft.reduce(getattr, path, params)


def _is_concrete(x) -> bool:
    return not isinstance(x, jax.core.Tracer)


def get_parameter(params: eqx.Module, name: str):
    """The value of parameter `name` in `params` (tied or element name).

    - an element name (`primary.1L.kz`): that element's value;
    - a tied name of a per-element field (`primary.kz`): the common value of its elements. If
      they differ (concrete values), `ValueError` naming them: a tied name has no single value
      then; read the elements by name. Under a JAX transformation (traced values) no check is
      possible: the result is their mean, computed as x_0 + mean(x - x_0) so that equal elements
      give exactly the common value;
    - any other name: the leaf.
    """
    where = resolve_parameter(params, name)
    value = _leaf(params, where.path)
    if not where.spec.elements or np.ndim(value) == 0:
        return value
    if where.element is not None:
        return value[where.element]
    if _is_concrete(value):
        arr = np.asarray(value, dtype=float)
        if not np.all(arr == arr[0]):
            values = ", ".join(
                f"{where.tied_name.rsplit('.', 1)[0]}.{label}.{where.path[-1]} = {x:g}"
                for label, x in zip(where.spec.elements, arr)
            )
            raise ValueError(
                f"`{name}` has no single value: its elements differ ({values} {where.spec.unit}); "
                "address them by element name"
            )
        return value[0]
    return value[0] + jnp.mean(value - value[0])


def _array(value):
    """A concrete number as a float numpy array (a Python float in a module is a static leaf for
    `eqx.filter_jit`: each new value would compile again); JAX arrays and tracers unchanged."""
    return value if isinstance(value, jax.Array) else np.asarray(value, dtype=float)


def set_parameters(params: eqx.Module, values: Mapping[str, object]) -> eqx.Module:
    """`params` with the parameters `{name: value}` replaced (tied or element names).

    A tied name of a per-element field sets every element to the value; an element name sets
    that element only. Works on traced values (pure, differentiable). Names are resolved first:
    unknown names raise `ValueError` before anything changes.
    """
    resolved = [(resolve_parameter(params, n), v) for n, v in values.items()]
    leaves: dict[tuple[str, ...], object] = {}
    for where, value in resolved:
        n = len(where.spec.elements)
        if where.element is None:
            new = jnp.broadcast_to(jnp.asarray(value, dtype=float), (n,)) if n else _array(value)
        else:
            old = leaves.get(where.path, _leaf(params, where.path))
            old = jnp.broadcast_to(jnp.asarray(old, dtype=float), (n,))
            new = old.at[where.element].set(value)
        leaves[where.path] = new
    if not leaves:
        return params
    paths = tuple(leaves)
    return eqx.tree_at(
        lambda p: tuple(_leaf(p, path) for path in paths), params, tuple(leaves[p] for p in paths)
    )
