"""Parameter names from tree paths (`primary.kz`), with their `FieldSpec`s."""

import dataclasses

import equinox as eqx

from ._spec import FieldSpec


def parameter_specs(params: eqx.Module, prefix: str = "") -> dict[str, FieldSpec]:
    """All physical parameters of `params` as `{dotted.name: FieldSpec}` in tree order."""
    out: dict[str, FieldSpec] = {}
    for f in dataclasses.fields(params):
        name = f"{prefix}{f.name}"
        value = getattr(params, f.name)
        if "spec" in f.metadata:
            out[name] = f.metadata["spec"]
        elif isinstance(value, eqx.Module):
            out.update(parameter_specs(value, prefix=name + "."))
    return out


def parameter_names(params: eqx.Module) -> tuple[str, ...]:
    """Dotted names of all physical parameters of `params` (e.g. `primary.kz`)."""
    return tuple(parameter_specs(params))
