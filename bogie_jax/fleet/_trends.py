"""Per bogie, the trend of every element over its stored judgements (`bogie_jax.monitor.trend`):
the estimates with a standard error, in date order; a group only over the judgements whose
estimate weighs its members as the latest one does (`bogie_jax.monitor.same_measure`), the
rule `bogie-jax monitor --history` applies to output folders."""

import dataclasses

from ..monitor import ToleranceBand, Trend, band_of_row, comparable_estimates, trend_of_rows


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


def _series(name, rows, bogie_id, false_alarm_rate) -> ElementTrend:
    latest = rows[-1][1]
    points = tuple(
        (d, r.get("estimate"), *(r.get("ci95") or (None, None)), r["verdict"]) for d, r in rows
    )
    known, _ = comparable_estimates(rows)
    fitted = trend_of_rows(name, known, false_alarm_rate) if len(known) >= 2 else None
    return ElementTrend(bogie_id, name, latest.get("unit", ""), band_of_row(latest), points, fitted)


def element_trends(bogie_id: str, records, false_alarm_rate: float = 0.05) -> list[ElementTrend]:
    """The trend of every element of one bogie over `records` (`verdicts.json` objects, any
    order; sorted by date here)."""
    series: dict[str, list] = {}
    for record in sorted(records, key=lambda r: r["date"]):
        for row in record["verdicts"]:
            series.setdefault(row["name"], []).append((record["date"], row))
    return [_series(n, rows, bogie_id, false_alarm_rate) for n, rows in series.items()]
