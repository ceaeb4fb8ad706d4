"""Condition-monitoring files: `verdicts.json` (writer and reader) and the one-page markdown
reports of a monitoring run and of a trend over dated runs.

`verdicts.json` (UTF-8 JSON, one object):

- `format`: `"bogie_jax.verdicts/1"`; `date`: the run's date, `YYYY-MM-DD` (trends order runs
  by it); `source`: what was measured (free text);
- `verdicts`: one row per judged element or group, then one per element that is not
  identifiable: `name`, `verdict` (`healthy`, `degraded`, `failed`, `not identifiable`),
  `estimate` and `std_error` [unit], `ci95` `[lo, hi]` [unit] (`null` when the data do not
  determine the element), `tolerance_band` (`healthy` `[lo, hi]`, `failed_below`,
  `failed_above`, `unit`), `unit`, `evidence` (decision interval, its z, the tests at the
  band's limits with their Wald and profile statistics, the reason, `watch`: `above` or
  `below` where the element is on watch (`bogie_jax.monitor.Verdict.watch`), runs used);
- `elements` (identifiability of every candidate), `fit`, `runs`, `false_alarm_rate`,
  `timings` [s]: as `bogie_jax.monitor.MonitorResult.to_dict`; further keys a caller adds
  (the demo adds `truth`: the hidden true values).

Non-finite numbers are written as `null`. `read_verdicts` checks the format, the date and the
rows' keys and raises `ValueError` naming the file and the problem.
"""

import datetime
import json
import math
import os
from pathlib import Path

from ..monitor import LONG_BAND, WATCH_NOTE, misfit_warning, not_explained_line, verdict_label


VERDICTS_FORMAT = "bogie_jax.verdicts/1"
VERDICTS_FILE = "verdicts.json"
VERDICT_KEYS = ("name", "verdict", "estimate", "ci95", "tolerance_band", "unit")
RULES = 'docs/monitoring.md of bogie_jax, section "Verdicts"'


def check_date(date) -> str:
    """`date` (`YYYY-MM-DD` text, `datetime.date` or `None` for today) as ISO text.
    **Raises:** `ValueError` naming the value."""
    if date is None:
        return datetime.date.today().isoformat()
    if isinstance(date, datetime.date):
        return date.isoformat()[:10]
    try:
        return datetime.date.fromisoformat(str(date)).isoformat()
    except ValueError:
        raise ValueError(f"`date` = {date!r} is not a date YYYY-MM-DD") from None


def _clean(x):
    """JSON-ready: non-finite floats become `None`, tuples lists, numpy scalars floats."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if hasattr(x, "item") and getattr(x, "ndim", 1) == 0:
        return _clean(x.item())
    return x


def verdicts_record(result, *, date=None, source: str = "", **extra) -> dict:
    """The `verdicts.json` object of `result` (a `MonitorResult`, or its `to_dict()`), dated
    `date` (default today), with `source` and any `extra` keys."""
    body = result.to_dict() if hasattr(result, "to_dict") else dict(result)
    record = {"format": VERDICTS_FORMAT, "date": check_date(date), "source": source}
    record.update(body)
    record.update(extra)
    return _clean(record)


def write_verdicts(path, result, *, date=None, source: str = "", **extra) -> Path:
    """Write `verdicts_record(result, ...)` to `path` (a `.json` file, or a directory: then
    `path/verdicts.json`); returns the file's path."""
    path = Path(path)
    if path.suffix.lower() != ".json":
        path = path / VERDICTS_FILE
    path.parent.mkdir(parents=True, exist_ok=True)
    record = verdicts_record(result, date=date, source=source, **extra)
    path.write_text(json.dumps(record, indent=1, allow_nan=False) + "\n", encoding="utf-8")
    return path


def read_verdicts(path) -> dict:
    """Read a `verdicts.json` (or a directory holding one, e.g. an earlier `--out`).

    **Raises:** `ValueError` naming the file: missing, not JSON, another format, no or a bad
    `date`, no `verdicts`, or a row without one of `VERDICT_KEYS`.
    """
    path = Path(os.fspath(path))
    if path.is_dir():
        path = path / VERDICTS_FILE
    if not path.is_file():
        raise ValueError(f"{path}: no such verdicts file (give a verdicts.json or its directory)")
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ValueError(f"{path}: not a JSON file ({e})") from None
    if not isinstance(record, dict) or record.get("format") != VERDICTS_FORMAT:
        got = record.get("format") if isinstance(record, dict) else type(record).__name__
        raise ValueError(f"{path}: format {got!r} is not {VERDICTS_FORMAT!r}")
    try:
        record["date"] = check_date(record.get("date"))
    except ValueError as e:
        raise ValueError(f"{path}: {e}") from None
    rows = record.get("verdicts")
    if not isinstance(rows, list) or not rows:
        raise ValueError(f"{path}: `verdicts` must be a non-empty list")
    for k, row in enumerate(rows):
        missing = [key for key in VERDICT_KEYS if key not in row]
        if missing:
            raise ValueError(f"{path}: verdict {k} lacks {', '.join(missing)}")
    record["path"] = str(path)
    return record


TRENDS_FORMAT = "bogie_jax.trends/1"


def write_trends(path, trends, *, false_alarm_rate: float, sources=()) -> Path:
    """Write per-element trends (`Trend`s or their dictionaries) to the JSON file `path`:
    `format` `"bogie_jax.trends/1"`, `false_alarm_rate`, `sources` (the verdict files, oldest
    first) and `trends` (`Trend.to_dict()` rows plus what the caller added, e.g. `unit`)."""
    path = Path(path)
    rows = [t.to_dict() if hasattr(t, "to_dict") else dict(t) for t in trends]
    record = {
        "format": TRENDS_FORMAT,
        "false_alarm_rate": false_alarm_rate,
        "sources": [str(s) for s in sources],
        "trends": rows,
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(_clean(record), indent=1, allow_nan=False) + "\n", encoding="utf-8")
    return path


# --- reports ---------------------------------------------------------------------------------


def _g(x, digits: int = 4) -> str:
    return "-" if x is None else f"{x:.{digits}g}"


def _p(p) -> str:
    return "-" if p is None else "< 1e-6" if p < 1e-6 else f"{p:.2g}"


def _verdict_table(rows) -> list[str]:
    lines = [
        "| element | verdict | estimate | 95 % interval | healthy band | failed below | unit |",
        "|---|---|---:|---|---|---:|---|",
    ]
    for r in rows:
        band = r["tolerance_band"]
        ci = "-" if r["ci95"] is None else f"[{_g(r['ci95'][0])}, {_g(r['ci95'][1])}]"
        label = verdict_label(r["verdict"], (r.get("evidence") or {}).get("watch"))
        label = label.replace("*", "\\*")  # markdown: a literal asterisk
        verdict = label if r["verdict"] == "healthy" else f"**{label}**"
        lines.append(
            f"| `{r['name']}` | {verdict} | {_g(r['estimate'])} | {ci} | "
            f"[{_g(band['healthy'][0])}, {_g(band['healthy'][1])}] | "
            f"{_g(band.get('failed_below'))} | {r['unit']} |"
        )
    if _watched(rows):
        lines += ["", WATCH_NOTE.replace("*", "\\*", 1) + "."]
    return lines


def _watched(rows) -> list[dict]:
    return [r for r in rows if (r.get("evidence") or {}).get("watch")]


def _runs_table(runs) -> list[str]:
    lines = [
        "| run | speed [m/s] | duration [s] | track | used | residual RMS [noise std] | "
        "fitted track offset [m] | fitted speed factor | note |",
        "|---:|---:|---:|---|---|---:|---:|---:|---|",
    ]
    for r in runs:
        fitted = r.get("corrected")
        lines.append(
            f"| {r['index']} | {_g(r['speed'])} | {_g(r['duration'])} | {r['track']} | "
            f"{'yes' if r['used'] else 'no'} | {_g(r.get('residual_rms'), 3)} | "
            f"{_g(r.get('position_offset'), 3) if fitted else '-'} | "
            f"{_g(r.get('speed_factor'), 5) if fitted else '-'} | {r.get('reason') or ''} |"
        )
    return lines


def _rules(record) -> list[str]:
    alpha = record.get("false_alarm_rate")
    judged = [r for r in record["verdicts"] if r["estimate"] is not None]
    z = judged[0]["evidence"].get("z") if judged and "evidence" in judged[0] else None
    fit = record.get("fit") or {}
    return [
        f"- Decision level: z = {_g(z, 3)} (false-alarm rate {_g(alpha, 3)} for the whole "
        f"bogie, Bonferroni over the {len(judged)} judged elements). An element estimated "
        "outside its band is tested at the band's edge (and the failure limit) by the profile "
        "likelihood ratio (the fit repeated with the element held there): `failed` beyond the "
        "failure limit, `degraded` outside the healthy band; `not identifiable`: the sensors do "
        "not determine the element (Fisher information of these runs) or, no test rejecting, "
        "the decision interval estimate +- z standard errors is wider than the band; else "
        "`healthy`. On watch (\\*): no alarm, but the 95 % interval lies outside the band; "
        "not held to the false-alarm rate.",
        "- Identifiable elements are chosen from the Fisher information of these runs at the "
        "nominal bogie; elements the sensors cannot separate are judged as their group and held "
        "at nominal otherwise.",
        _standard_errors(fit),
        *_model(fit),
        f"- Full rules: {RULES}.",
    ]


def _model(fit) -> list[str]:
    """The fitted model's line, where the fit record names it."""
    if not fit.get("model"):
        return []
    why = (
        ", fitted because the configured model did not explain the data (its goodness-of-fit "
        "test failed or a run was left out); this one does"
    )
    return [f"- Model: {fit['model']}{why if fit.get('model_refit') else ''}."]


def _standard_errors(fit) -> str:
    """The rule behind the standard errors, from the fit record (`monitor`'s `noise` and
    `covariance`)."""
    noise, kind = fit.get("noise") or "max", fit.get("covariance") or "gauss-newton"
    sigma2 = {
        "per-channel": "each channel's noise estimated from the residuals and the fit reweighted",
        "nominal": "the sensors' nominal noise",
        "estimated": "the fit's own estimate",
        "max": "the larger of the sensors' nominal noise, 1, and the fit's own estimate",
    }.get(noise, noise)
    bias = "sensor bias removed per run and channel; " if fit.get("bias_removed") else ""
    if kind == "sandwich":
        how = (
            f"sandwich covariance (Newey-West, Bartlett bandwidth {_g(fit.get('bandwidth'), 3)} "
            "samples: misfit correlated in time allowed), never below Gauss-Newton with "
            f"residual variance {_g(fit.get('sigma2'), 3)}"
        )
    else:
        how = f"Gauss-Newton with residual variance {_g(fit.get('sigma2'), 3)}"
    return (
        f"- Standard errors: {bias}{how} ({sigma2}){_record_error(fit)}; the 95 % interval is "
        "estimate +- t standard errors, t the 0.975 quantile of Student's t with the standard "
        "error's degrees of freedom (`ci95_dof` in `verdicts.json`; 1.96 where they are "
        "unbounded)."
    )


def _record_error(fit) -> str:
    """The track records' error in the standard errors, from the fit record; "" without one."""
    rms = fit.get("track_error") or 0.0
    if not rms > 0:
        return ""
    white = fit.get("track_error_white_share") or 0.0
    long = fit.get("track_error_long_wave_share") or 0.0
    shape = ", shaped like the track"
    if white > 0:
        calibrated = "; the fit repeated on records calibrated for it"
        shape = (
            f", {100 * white:.0f} % of its variance white over the recording band (the misfit "
            f"calls for it{calibrated if fit.get('track_records_calibrated') else ''}), the rest "
            "shaped like the track"
        )
    elif long > 0:
        shape = (
            f", {100 * long:.4g} % of its variance long-wave drift ({LONG_BAND[0]:g}-"
            f"{LONG_BAND[1]:g} m; the residuals hold far less misfit than the track's shape "
            "leaves), the rest shaped like the track"
        )
    return f"; the track records' error of {1e3 * rms:.3g} mm RMS included{shape}"


def write_report(
    path,
    record: dict,
    *,
    figures=(),
    title: str = "Bogie condition report",
    notes=(),
    timing=None,
) -> Path:
    """A one-page markdown report of a monitoring run: verdict table, figures, runs, the rules
    used, timing and `notes`.

    **Arguments:** `record`: a `verdicts.json` object (`verdicts_record`); `figures`: pairs
    `(caption, file)` embedded as images (file names relative to the report); `notes`: lines
    of text (e.g. the demo's true values); `timing`: `{label: seconds}` (default: the record's
    `timings`).
    **Returns:** the report's path.
    """
    path = Path(path)
    rows = record["verdicts"]
    alarms = [r for r in rows if r["verdict"] in ("degraded", "failed")]
    summary = (
        "No alarm: every identifiable element is healthy."
        if not alarms
        else "Alarm: " + "; ".join(f"`{r['name']}` {r['verdict']}" for r in alarms) + "."
    )
    watched = _watched(rows)
    if watched:
        summary += (
            " Watch: "
            + "; ".join(
                f"`{r['name']}` (95 % interval {r['evidence']['watch']} its band)" for r in watched
            )
            + "."
        )
    lines = [f"# {title}", "", f"Date {record['date']}. {record.get('source', '')}", ""]
    lines += [f"**{summary}**", ""]
    warning = misfit_warning((record.get("fit") or {}).get("misfit_ratio"))
    if warning:
        lines += [f"**{warning}.**", ""]
    unexplained = not_explained_line(record.get("goodness_of_fit"))
    if unexplained:
        lines += [f"**{unexplained}.**", ""]
    lines += [*_verdict_table(rows), ""]
    for caption, file in figures:
        lines += [f"![{caption}]({file})", "", f"*{caption}*", ""]
    lines += ["## Runs", "", *_runs_table(record.get("runs", [])), ""]
    lines += ["## Rules used", "", *_rules(record), ""]
    timing = record.get("timings", {}) if timing is None else timing
    if timing:
        parts = [f"{label} {_g(seconds, 3)} s" for label, seconds in timing.items()]
        lines += ["## Timing", "", "; ".join(parts) + ".", ""]
    if notes:
        lines += ["## Notes", "", *[f"- {n}" for n in notes], ""]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines), encoding="utf-8")
    return path


def write_trend_report(path, trends, *, sources=(), figure: str | None = None, notes=()) -> Path:
    """A markdown report of per-element trends: a table (level, slope, its standard error,
    drift flag, p-value, days to the band's edge), the figure and the dated inputs.

    **Arguments:** `trends`: `bogie_jax.monitor.Trend`s (or their dictionaries) with an extra
    `unit` where known; `sources`: `(date, file)` pairs; `figure`: an image file relative to
    the report; `notes`: lines of text.
    """
    path = Path(path)
    lines = ["# Bogie condition trends", ""]
    lines += [
        "| element | runs | level | slope [unit/day] | se(slope) | drift | p | days to band edge "
        "| unit |",
        "|---|---:|---:|---:|---:|---|---:|---:|---|",
    ]
    for t in trends:
        d = t.to_dict() if hasattr(t, "to_dict") else dict(t)
        drift = "**drift**" if d["drift"] else "no"
        lines.append(
            f"| `{d['name']}` | {len(d['dates'])} | {_g(d['level'])} | {_g(d['slope_per_day'], 3)} "
            f"| {_g(d['slope_std_error'], 3)} | {drift} | {_p(d['p_value'])} | "
            f"{_g(d.get('days_to_band_edge'), 3)} | {d.get('unit', '')} |"
        )
    lines.append("")
    if figure:
        lines += [f"![trends]({figure})", ""]
    lines += [
        "Weighted least squares of the estimates on time (weights 1 / se^2); drift when "
        "|slope| / se(slope) exceeds the two-sided quantile at the false-alarm rate, se(slope) "
        "inflated by the Birge ratio when the scatter exceeds the standard errors "
        f"({RULES}).",
        "",
    ]
    if sources:
        lines += ["## Inputs", "", *[f"- {date}: `{file}`" for date, file in sources], ""]
    if notes:
        lines += [*[f"- {n}" for n in notes], ""]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines), encoding="utf-8")
    return path
