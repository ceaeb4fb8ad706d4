"""`ParameterSelection`: the parameters to identify, by dotted name, in unconstrained coordinates.

theta_i = log(p_i / p0_i) for a positive quantity (log scale), or, for a parameter with bounds
[lo, hi], the scaled logit theta_i = logit(u_i) - logit(u0_i) with u = (p - lo) / (hi - lo)
(inverse: p = lo + (hi - lo) sigmoid(theta + logit(u0))). Either way theta = 0 is the nominal
value p0 taken from the base parameters, and every real theta maps to a valid value: the fit runs
unconstrained (optimistix has no box bounds) and never clips inside the physics.

Names are tied (`primary.kz`: one theta sets all four axleboxes) or one element
(`primary.1L.kz`: one theta for that axlebox), see `bogie_jax.params`; a selection may not mix a
tied group with one of its members.
"""

import math
from collections.abc import Mapping, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..params import (
    BogieParams,
    get_parameter,
    parameter_names as _parameter_names,
    resolve_parameter,
    set_parameters,
)


class ParameterSelection(eqx.Module):
    """Selected parameters (n) of a `BogieParams` tree and their transforms.

    - `names`: dotted names; `units`: their SI units;
    - `nominal` (n,): physical values at theta = 0;
    - `lower`, `upper` (n,): bounds (0 and inf for a log-scale parameter);
    - `log_scale`: per parameter, True for log(p / p0), False for the scaled logistic.

    Build it with `select_parameters`.
    """

    names: tuple[str, ...] = eqx.field(static=True)
    units: tuple[str, ...] = eqx.field(static=True)
    log_scale: tuple[bool, ...] = eqx.field(static=True)
    nominal: Float[Array, " n"]
    lower: Float[Array, " n"]
    upper: Float[Array, " n"]

    @property
    def n_params(self) -> int:
        return len(self.names)

    def _logistic_parts(self):
        log = np.asarray(self.log_scale)
        lo = jnp.where(log, 0.0, self.lower)
        span = jnp.where(log, 1.0, self.upper - self.lower)
        u0 = jnp.where(log, 0.5, (self.nominal - lo) / span)
        return log, lo, span, jnp.log(u0) - jnp.log1p(-u0)

    @eqx.filter_jit
    def to_physical(self, theta) -> Float[Array, " n"]:
        """Physical values (in `units`) for unconstrained `theta` (n,). A `jit` of its own: called
        from Python (reporting, starts, records) it compiles once instead of once per operation."""
        log, lo, span, logit0 = self._logistic_parts()
        theta = jnp.asarray(theta)
        # double-where: each branch sees only its own (safe) entries, so no inf/NaN in gradients
        by_log = self.nominal * jnp.exp(jnp.where(log, theta, 0.0))
        by_logistic = lo + span * jax.nn.sigmoid(jnp.where(log, 0.0, theta) + logit0)
        return jnp.where(log, by_log, by_logistic)

    @eqx.filter_jit
    def to_theta(self, physical) -> Float[Array, " n"]:
        """Unconstrained coordinates of `physical` values (n,), strictly inside the bounds (a `jit`
        of its own, as `to_physical`)."""
        log, lo, span, logit0 = self._logistic_parts()
        p = jnp.asarray(physical)
        ratio = jnp.where(log, p / self.nominal, 1.0)
        u = jnp.where(log, 0.5, (p - lo) / span)
        return jnp.where(log, jnp.log(ratio), jnp.log(u) - jnp.log1p(-u) - logit0)

    def values(self, params: BogieParams) -> Float[Array, " n"]:
        """The selected values of a parameter tree (physical units); a tied name of a
        per-element field reads the common value of its elements (see `get_parameter`)."""
        return jnp.stack([jnp.asarray(get_parameter(params, n)) for n in self.names])

    def apply(self, params: BogieParams, theta) -> BogieParams:
        """`params` with the selected parameters set from `theta`; the others unchanged. A tied
        name sets all its elements to one value, an element name that element only."""
        values = self.to_physical(theta)
        return set_parameters(params, {n: values[i] for i, n in enumerate(self.names)})

    def describe(self, theta) -> dict[str, tuple[float, str]]:
        """`{name: (physical value, unit)}` for a concrete `theta`."""
        values = np.asarray(self.to_physical(theta))
        return {n: (float(v), u) for n, v, u in zip(self.names, values, self.units)}


def select_parameters(
    params: BogieParams,
    names: str | Sequence[str],
    *,
    bounds: None | str | Mapping[str, str | tuple[float, float]] = None,
) -> ParameterSelection:
    """Select parameters of `params` by dotted name; their values in `params` are the nominal
    (theta = 0) values.

    **Arguments:**
    - `names`: dotted names, tied (`primary.kz`) or element (`primary.1L.kz`);
      `bogie_jax.params.parameter_names(params, elements=True)` lists them all. A tied name of a
      per-element field needs equal values over its elements in `params`.
    - `bounds`: `None`: every parameter on log scale (positive quantities); `"spec"`: every
      parameter scaled-logistic within its plausible bounds (`FieldSpec.bounds`); a mapping
      `{name: (lo, hi) | "spec"}`: those parameters scaled-logistic, the others log scale.

    **Raises:** `ValueError` for an empty selection, unknown or repeated names, an unknown element
    (`primary.3L.kz`), a tied group together with one of its members (`primary.kz` and
    `primary.1L.kz`), a tied name whose elements differ in `params`, bounds for a name that is
    not selected, bounds outside the valid range, `lo >= hi`, a nominal value that is not
    strictly inside its bounds, or a non-positive nominal value on log scale.
    """
    names = _check_names(params, names)
    specs = {n: resolve_parameter(params, n).spec for n in names}
    per_name = _bounds_per_name(names, bounds)
    nominal, lower, upper, log_scale = [], [], [], []
    for name in names:
        spec = specs[name]
        p0 = float(np.asarray(get_parameter(params, name)))
        b = per_name.get(name)
        if b is None:
            if not p0 > 0:
                raise ValueError(
                    f"`{name}` = {p0:g} {spec.unit} cannot be log-scaled (log(p / p_nominal) needs "
                    "p_nominal > 0): give it `bounds`"
                )
            lo, hi = 0.0, math.inf
        else:
            lo, hi = spec.bounds if isinstance(b, str) else _check_bound_pair(name, b, spec)
            if not lo < p0 < hi:
                raise ValueError(
                    f"starting value `{name}` = {p0:g} {spec.unit} is outside its bounds "
                    f"({lo:g}, {hi:g}) {spec.unit}; it must lie strictly inside"
                )
        nominal.append(p0), lower.append(lo), upper.append(hi), log_scale.append(b is None)
    return ParameterSelection(
        names=names,
        units=tuple(specs[n].unit for n in names),
        log_scale=tuple(log_scale),
        nominal=np.asarray(nominal),
        lower=np.asarray(lower),
        upper=np.asarray(upper),
    )


def _check_names(params, names) -> tuple[str, ...]:
    if isinstance(names, str):
        names = (names,)
    names = tuple(names)
    if not names:
        valid = _parameter_names(params, elements=True)
        raise ValueError(
            f"`names` is empty: select at least one parameter; valid: {', '.join(valid)}"
        )
    resolved = [resolve_parameter(params, name, " in `names`") for name in names]
    dups = sorted({n for n in names if names.count(n) > 1})
    if dups:
        raise ValueError(f"`names` must not repeat a parameter; repeated: {', '.join(dups)}")
    tied = {r.tied_name for r in resolved if r.is_tied_group}
    for group in sorted(tied):
        members = [r.name for r in resolved if r.element is not None and r.tied_name == group]
        if members:
            raise ValueError(
                f"`names` mixes the tied group `{group}` (all its elements, one value) with its "
                f"member(s) {', '.join(f'`{m}`' for m in members)}: select either `{group}` or "
                "element names only"
            )
    return names


def _bounds_per_name(names, bounds) -> dict:
    if bounds is None:
        return {}
    if isinstance(bounds, str):
        if bounds != "spec":
            raise ValueError(f"`bounds` must be None, 'spec' or a mapping, got {bounds!r}")
        return {n: "spec" for n in names}
    if not isinstance(bounds, Mapping):
        raise TypeError(f"`bounds` must be None, 'spec' or a mapping, got {type(bounds).__name__}")
    extra = [k for k in bounds if k not in names]
    if extra:
        raise ValueError(
            f"`bounds` given for parameters that are not selected: {', '.join(map(str, extra))}"
        )
    return dict(bounds)


def _check_bound_pair(name, b, spec) -> tuple[float, float]:
    if isinstance(b, str):
        raise ValueError(f"`bounds[{name!r}]` must be 'spec' or (lo, hi), got {b!r}")
    try:
        lo, hi = (float(v) for v in b)
    except (TypeError, ValueError):
        raise ValueError(f"`bounds[{name!r}]` must be 'spec' or (lo, hi), got {b!r}") from None
    vlo, vhi = spec.valid
    if not (vlo <= lo < hi <= vhi):
        raise ValueError(
            f"`bounds[{name!r}]` = ({lo:g}, {hi:g}) {spec.unit} must satisfy lo < hi inside the "
            f"valid range [{vlo:g}, {vhi:g}] {spec.unit}"
        )
    return lo, hi
