"""What `monitor` judges: candidate elements, their tolerance bands, and the identifiability
rule that decides, from the Fisher information of the actual runs, which elements are judged
alone, which only as a group, and which not at all.

Identifiability rule (documented in the README, "Verdict rules"). The Jacobian S of the
weighted residuals of all runs with respect to ln p of every candidate, at the nominal bogie,
gives the Cramer-Rao covariance C = (S^T S)^+ of the relative errors (unit-variance residuals:
the sensors' nominal noise), computed by `bogie_jax.cost.covariance_from_jacobian`.

1. An element is **identifiable alone** when, with every candidate free,
   - its decision interval is small against its band: z * se_i <= `resolution` * h_i, with
     se_i = sqrt(C_ii) (relative standard error), h_i the half-width of its healthy band
     relative to nominal, z = `decision_z(false_alarm_rate, n_candidates)` and `resolution`
     = 0.5 by default (the interval spans at most half the band, so an element half a band
     beyond the band's edge is called);
   - and it is not collinear with another candidate: |corr_ij| <= `max_correlation` (0.98)
     for every other candidate j of finite se (a pair so correlated may trade off far beyond
     the linear prediction when the true values are away from nominal; a candidate along an
     exactly unidentifiable direction has infinite se and fails by itself).
2. The other elements are grouped by their tied name (`yaw_dampers.left.c` and
   `yaw_dampers.right.c` -> `yaw_dampers.c`): the group moves as one factor (the column of
   the group is the sum of its members' columns). With the alone elements and the groups free,
   a group that passes the same two tests is **identifiable as a group**; its verdict names the
   group, e.g. `yaw_dampers.c` (all members) or `primary.{1R,2L}.ky` (some members). Where
   the runs separate parts of a group but not their members, the group is split: of the
   partitions of its members into two or more parts of two or more members, the one with the
   most parts whose every part passes both tests (the other groups whole), the parts' largest
   se / limit breaking ties: e.g. `primary.{1L,1R}.ky` and `primary.{2L,2R}.ky` where the runs
   separate the wheelsets' springs but not left from right.
   A group's estimate measures a weighted mean of its members, which the verdict reports
   (`group_weights`).
3. Everything else is **not identifiable**: held at its nominal value in the fit.
"""

import dataclasses
from collections.abc import Mapping

import numpy as np

from ..cost import covariance_from_jacobian
from ..params import BogieParams, get_parameter, resolve_parameter
from ._verdict import ToleranceBand


DEFAULT_CANDIDATES = (
    "yaw_dampers.left.c",
    "yaw_dampers.right.c",
    *(f"primary.{a}.{f}" for f in ("cz", "kz", "ky") for a in ("1L", "1R", "2L", "2R")),
    "secondary.left.cy",
    "secondary.right.cy",
)
"""The per-element suspension parameters a maintenance engineer asks about."""
DEFAULT_TOLERANCE = 0.2  # healthy band: nominal * (1 -+ 0.2)
DEFAULT_FAILED_FRACTION = 0.25  # failed below 25 % of nominal
RESOLUTION = 0.5
MAX_CORRELATION = 0.98


@dataclasses.dataclass(frozen=True)
class Coordinate:
    """One fitted coordinate: an element, or a group of elements moving by one factor.

    `name`: element name or group name; `members`: candidate indices; `nominal` [unit]: the
    mean nominal value of the members (the estimate is `nominal * exp(phi)`); `unit`; `band`.
    """

    name: str
    members: tuple[int, ...]
    nominal: float
    unit: str
    band: ToleranceBand


@dataclasses.dataclass(frozen=True)
class ElementStatus:
    """Identifiability of one candidate at the nominal point.

    - `name`; `status`: `"alone"`, `"group"` or `"none"`; `coordinate`: the name of the
      verdict that covers it (itself, its group, or itself when not identifiable);
    - `relative_std_error`: se_i of the rule (every candidate free); `limit`: the largest se_i
      the rule accepts; `max_correlation` with another candidate, and that candidate's name.
    """

    name: str
    status: str
    coordinate: str
    relative_std_error: float
    limit: float
    max_correlation: float
    most_correlated: str

    def to_dict(self) -> dict:
        return {k: _json(v) for k, v in dataclasses.asdict(self).items()}


def _json(x):
    if isinstance(x, float) and not np.isfinite(x):
        return None
    return x


def check_candidates(params: BogieParams, candidates, label: str = "candidates") -> tuple[str, ...]:
    """Candidate names (default `DEFAULT_CANDIDATES`), checked: `ValueError` naming `label`
    (the argument or option they came from) for an empty list, a repeated name or an unknown
    one (with the nearest valid names, `bogie_jax.params.resolve_parameter`)."""
    names = DEFAULT_CANDIDATES if candidates is None else tuple(candidates)
    if isinstance(candidates, str):
        names = (candidates,)
    if not names:
        raise ValueError(f"`{label}` is empty: give at least one element name")
    dups = sorted({n for n in names if names.count(n) > 1})
    if dups:
        raise ValueError(f"`{label}` repeats {', '.join(dups)}")
    for name in names:
        resolve_parameter(params, name, f" in `{label}`")
    return names


def tied_group(params: BogieParams, name: str) -> str:
    """The tied name of an element (`yaw_dampers.c` for `yaw_dampers.left.c`), else `name`."""
    where = resolve_parameter(params, name)
    return where.tied_name if where.element is not None else name


def element_band(
    name: str, nominal: float, unit: str, band, tied: str | None = None
) -> ToleranceBand:
    """The `ToleranceBand` of element or group `name` (see `monitor`'s `band` argument): from a
    mapping by `name`, else by its `tied` group name; a number is a relative half-width."""
    if isinstance(band, Mapping):
        given = band.get(name)
        band = band.get(tied) if given is None and tied is not None else given
    if band is None:
        band = DEFAULT_TOLERANCE
    if isinstance(band, ToleranceBand):
        return band
    try:
        return ToleranceBand.relative(
            nominal, float(band), unit=unit, failed_fraction=DEFAULT_FAILED_FRACTION
        )
    except (TypeError, ValueError) as e:
        raise ValueError(
            f"`band` of `{name}` = {band!r}: {e} (a relative half-width, or a ToleranceBand)"
        ) from None


def nominal_values(params: BogieParams, names) -> np.ndarray:
    return np.array([float(np.asarray(get_parameter(params, n))) for n in names])


def group_name(params: BogieParams, members: list[str], tied: str) -> str:
    """`tied` for all of its elements, else `group.{a,b}.field`."""
    where = resolve_parameter(params, tied)
    labels = [resolve_parameter(params, m).spec.elements[resolve_parameter(params, m).element]
              for m in members]  # fmt: skip
    if where.is_tied_group and len(labels) == len(where.spec.elements):
        return tied
    group, field = tied.rsplit(".", 1)
    return f"{group}.{{{','.join(labels)}}}.{field}"


def _half_width(band: ToleranceBand, nominal: float) -> float:
    """Half-width of the healthy band relative to `nominal`."""
    return (band.healthy[1] - band.healthy[0]) / 2 / nominal


def _passes(jac, z, half_widths, resolution, max_correlation):
    cov = covariance_from_jacobian(jac)
    se = np.asarray(cov.std_errors)
    # NaN: correlation with a candidate of infinite se (a null direction), which fails by
    # itself; a candidate without a component along the null directions is not collinear
    corr = np.abs(np.nan_to_num(np.asarray(cov.correlation), nan=0.0))
    np.fill_diagonal(corr, 0.0)
    limit = resolution * half_widths / z
    most = corr.argmax(axis=1) if corr.shape[0] > 1 else np.zeros(1, dtype=int)
    worst = corr.max(axis=1) if corr.shape[0] > 1 else np.zeros(1)
    ok = np.isfinite(se) & (se <= limit) & (worst <= max_correlation)
    return ok, se, limit, worst, most


def _splits(members):
    """The partitions of `members` into two or more blocks of two or more members each."""

    def partitions(items):
        if not items:
            yield []
            return
        first, rest = items[0], items[1:]
        for tail in partitions(rest):
            for i in range(len(tail)):
                yield tail[:i] + [[first, *tail[i]]] + tail[i + 1 :]
            yield [[first], *tail]

    for blocks in partitions(list(members)):
        if len(blocks) >= 2 and min(len(b) for b in blocks) >= 2:
            yield sorted((sorted(b) for b in blocks), key=lambda b: b[0])


@dataclasses.dataclass(frozen=True)
class _Rule:
    """The identifiability rule's tests on the Jacobian `jac` of the candidates `names`."""

    params: BogieParams
    names: tuple[str, ...]
    jac: np.ndarray
    nominal: np.ndarray
    bands: dict
    band_arg: object
    z: float
    limits: tuple[float, float]  # resolution, max_correlation

    def passes(self, coords):
        """`_passes` on the columns of the coordinates `coords` (a group: its members' sum)."""
        cols = np.stack([self.jac[:, list(c.members)].sum(axis=1) for c in coords], axis=1)
        half = np.array([_half_width(c.band, c.nominal) for c in coords])
        return _passes(cols, self.z, half, *self.limits)

    def element(self, i: int) -> Coordinate:
        band = self.bands[self.names[i]]
        return Coordinate(self.names[i], (i,), float(self.nominal[i]), band.unit, band)

    def group(self, members, tied: str) -> Coordinate:
        name = group_name(self.params, [self.names[i] for i in members], tied)
        p0 = float(np.mean(self.nominal[members]))
        unit = self.bands[self.names[members[0]]].unit
        return Coordinate(
            name, tuple(members), p0, unit, element_band(name, p0, unit, self.band_arg, tied)
        )

    def best_split(self, tied: str, members, others) -> list[Coordinate]:
        """The group whole, or its split with the most parts that all pass beside `others`
        (the parts' largest se / limit breaking ties)."""
        best = None
        for blocks in _splits(members):
            trial = [self.group(b, tied) for b in blocks]
            ok, se, limit = self.passes(others + trial)[:3]
            n = len(trial)
            if ok[-n:].all():
                key = (n, -float(np.max(se[-n:] / limit[-n:])))
                if best is None or key > best[0]:
                    best = (key, trial)
        return [self.group(members, tied)] if best is None else best[1]


def classify_elements(
    params: BogieParams,
    names: tuple[str, ...],
    jacobian,
    bands: dict,
    band_arg,
    z: float,
    *,
    resolution: float = RESOLUTION,
    max_correlation: float = MAX_CORRELATION,
) -> tuple[list[Coordinate], list[ElementStatus]]:
    """The rule of the module docstring on `jacobian` (m, n): dr/d ln p of the candidates
    `names` at the nominal point. Returns the fitted coordinates and each candidate's status."""
    jac = np.asarray(jacobian, dtype=float)
    nominal = nominal_values(params, names)
    rule = _Rule(params, names, jac, nominal, bands, band_arg, z, (resolution, max_correlation))
    half = np.array([_half_width(bands[n], p) for n, p in zip(names, nominal)])
    ok, se, limit, worst, most = _passes(jac, z, half, resolution, max_correlation)
    coords = [rule.element(i) for i in range(len(names)) if ok[i]]
    grouped: dict[str, list[int]] = {}
    for i in np.flatnonzero(~ok):
        grouped.setdefault(tied_group(params, names[i]), []).append(int(i))
    tied_groups = [(t, m) for t, m in grouped.items() if len(m) >= 2]
    groups = [
        c
        for k, (tied, members) in enumerate(tied_groups)
        for c in rule.best_split(
            tied,
            members,
            coords + [rule.group(m, t) for j, (t, m) in enumerate(tied_groups) if j != k],
        )
    ]
    status = {c.members[0]: ("alone", c.name) for c in coords}
    if groups:
        ok_g = rule.passes(coords + groups)[0][len(coords) :]
        coords += [c for c, good in zip(groups, ok_g) if good]
        status.update(
            {i: ("group", c.name) for c, good in zip(groups, ok_g) if good for i in c.members}
        )
    statuses = [
        ElementStatus(
            name=n,
            status=status.get(i, ("none", n))[0],
            coordinate=status.get(i, ("none", n))[1],
            relative_std_error=float(se[i]),
            limit=float(limit[i]),
            max_correlation=float(worst[i]),
            most_correlated=names[int(most[i])] if len(names) > 1 else "",
        )
        for i, n in enumerate(names)
    ]
    return coords, statuses


def group_weights(member_columns, other_columns) -> np.ndarray:
    """The weights v (summing to 1) of a group's members in its common factor phi: with the
    members' columns M (m, n_g) and the other coordinates' columns O, in the fit's weights,
    phi = v^T theta, v = S 1 / (1^T S 1), S = M_perp^T M_perp, M_perp = M with O projected out
    (Frisch-Waugh-Lovell): the estimate is the weighted mean sum_i v_i p_i / p_i0."""
    m = np.asarray(member_columns, dtype=float)
    o = np.asarray(other_columns, dtype=float)
    if o.size:
        m = m - o @ np.linalg.lstsq(o, m, rcond=None)[0]
    share = m.T @ m.sum(axis=1)
    return share / share.sum()


def group_value(
    members, values: Mapping, nominals: Mapping, weights: Mapping | None = None
) -> float:
    """What a group's estimate measures when its members have `values` (mappings by member
    name, in their unit): the members' mean nominal times the weighted mean of their values
    relative to nominal, sum_i v_i p_i / p_i0, with a verdict's `member_weights` (default equal
    weights: the members' mean); `group_weights` says why."""
    weights = weights or {m: 1 / len(members) for m in members}
    p0 = float(np.mean([nominals[m] for m in members]))
    return p0 * sum(weights[m] * values[m] / nominals[m] for m in members)


WEIGHT_TOLERANCE = 0.05  # largest difference of one member's weight between comparable estimates


def same_measure(weights, reference, tolerance: float = WEIGHT_TOLERANCE) -> bool:
    """Whether a group's estimate with member `weights` measures what one with `reference`
    does (mappings member -> weight, `None` for an element judged alone): the same members,
    each weight within `tolerance`. A trend mixes no other estimates: members weighed 0.5 and
    0.5 in one run and 0.2 and 0.8 in another put the group at 0.55 and 0.82 of nominal for the
    same first member failed to 10 % (`group_value`)."""
    if not weights or not reference:
        return not weights and not reference
    if set(weights) != set(reference):
        return False
    return all(abs(float(weights[m]) - float(reference[m])) <= tolerance for m in reference)
