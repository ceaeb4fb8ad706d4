"""Per bogie, the trend of every element over its stored judgements (`bogie_jax.monitor.trend`):
the estimates with a standard error, in date order; a group only over the judgements whose
estimate weighs its members as the latest one does (`bogie_jax.monitor.same_measure`), the
rule `bogie-jax monitor --history` applies to output folders."""

import dataclasses

from ..monitor import ToleranceBand, Trend, same_measure, trend


@dataclasses.dataclass(frozen=True)
class ElementTrend:
    """One element's series of one bogie: `points` `(date, estimate, ci_lo, ci_hi, verdict)`
    of every judgement that estimates it, `band` of the latest, `unit`, and `trend` (`None`
    with fewer than two comparable estimates)."""

    bogie_id: str
    name: str
    unit: str
    band: ToleranceBand
    points: tuple[tuple, ...]
    trend: Trend | None


def _band(row) -> ToleranceBand:
    b = row["tolerance_band"]
    return ToleranceBand(
        tuple(b["healthy"]),
        unit=b.get("unit", ""),
        failed_below=b.get("failed_below"),
        failed_above=b.get("failed_above"),
    )


def _weights(row):
    return (row.get("evidence") or {}).get("member_weights")


def _comparable(rows):
    """The rows with an estimate and a standard error that measure what the latest does."""
    known = [(d, r) for d, r in rows if r.get("estimate") is not None and r.get("std_error")]
    if not known:
        return []
    reference = _weights(known[-1][1])
    return [(d, r) for d, r in known if same_measure(_weights(r), reference)]


def _series(name, rows, bogie_id, false_alarm_rate) -> ElementTrend:
    latest = rows[-1][1]
    points = tuple(
        (d, r.get("estimate"), *(r.get("ci95") or (None, None)), r["verdict"]) for d, r in rows
    )
    known = _comparable(rows)
    fitted = None
    if len(known) >= 2:
        fitted = trend(
            name,
            [d for d, _ in known],
            [r["estimate"] for _, r in known],
            [r["std_error"] for _, r in known],
            false_alarm_rate=false_alarm_rate,
            band=_band(known[-1][1]),
        )
    return ElementTrend(bogie_id, name, latest.get("unit", ""), _band(latest), points, fitted)


def element_trends(bogie_id: str, records, false_alarm_rate: float = 0.05) -> list[ElementTrend]:
    """The trend of every element of one bogie over `records` (`verdicts.json` objects, any
    order; sorted by date here)."""
    series: dict[str, list] = {}
    for record in sorted(records, key=lambda r: r["date"]):
        for row in record["verdicts"]:
            series.setdefault(row["name"], []).append((record["date"], row))
    return [_series(n, rows, bogie_id, false_alarm_rate) for n, rows in series.items()]
