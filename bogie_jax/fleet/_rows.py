"""A `verdicts.json` record (`bogie_jax.io.verdicts_record`: what a fleet worker returns and
what `fleet import` reads) as the rows of one judgement: pure functions, no database."""

import json
import math


def _number(x):
    return float(x) if isinstance(x, (int, float)) and math.isfinite(x) else None


def judgement_row(record: dict) -> dict:
    """The `judgements` columns a record determines (the caller adds ids, run, vehicle, ...)."""
    rows = record.get("verdicts") or []
    runs = record.get("runs") or []
    return {
        "source": str(record.get("source", "")),
        "false_alarm_rate": _number(record.get("false_alarm_rate")),
        "n_alarms": sum(r.get("verdict") in ("degraded", "failed") for r in rows),
        "n_watches": sum(bool((r.get("evidence") or {}).get("watch")) for r in rows),
        "runs_used": sum(bool(r.get("used", True)) for r in runs),
        "runs_total": len(runs),
        "explains_data": explains_data(record),
        "record": json.dumps(record, allow_nan=False, separators=(",", ":")),
    }


def explains_data(record: dict) -> bool:
    """Whether the judgement's data are explained: the fit's misfit within its limit
    (`FitSummary.explains_data`) and every measurement run used."""
    fit = record.get("fit") or {}
    runs = record.get("runs") or []
    return bool(fit.get("explains_data", True)) and all(r.get("used", True) for r in runs)


def verdict_rows(record: dict) -> list[dict]:
    """One `verdicts` row per verdict of the record, in its order."""
    out = []
    for k, r in enumerate(record.get("verdicts") or []):
        band = r.get("tolerance_band") or {}
        lo, hi = (band.get("healthy") or [math.nan, math.nan])[:2]
        ci = r.get("ci95") or [None, None]
        evidence = r.get("evidence") or {}
        out.append(
            {
                "position": k,
                "name": str(r["name"]),
                "verdict": str(r["verdict"]),
                "watch": evidence.get("watch"),
                "estimate": _number(r.get("estimate")),
                "std_error": _number(r.get("std_error")),
                "ci_lo": _number(ci[0]),
                "ci_hi": _number(ci[1]),
                "band_lo": float(lo),
                "band_hi": float(hi),
                "failed_below": _number(band.get("failed_below")),
                "failed_above": _number(band.get("failed_above")),
                "unit": str(r.get("unit", "")),
                "reason": str(evidence.get("reason", "")),
            }
        )
    return out


def fit_row(record: dict) -> dict:
    """The `fits` row of the record's joint fit."""
    fit = record.get("fit") or {}
    return {
        "status": str(fit.get("status", "unknown")),
        "steps": fit.get("steps"),
        "evaluations": fit.get("evaluations"),
        "cost": _number(fit.get("cost")),
        "condition_number": _number(fit.get("condition_number")),
        "misfit_ratio": _number(fit.get("misfit_ratio")),
        "explains_data": bool(fit.get("explains_data", True)),
    }
