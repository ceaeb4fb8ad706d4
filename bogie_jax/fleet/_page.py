"""The fleet page: one static HTML file (inline style, script and SVG figures; opens from disk).

Order: the alarms and watches of each bogie's latest judgement (failed, then degraded, then on
watch); the judgements whose data the fit does not explain and the bogie-dates that could not
be judged; then one section per bogie, most severe first (reorderable), with its latest verdict
chart, the trend of each element over its judgements and its history. Every table sorts by a
click on its header."""

import datetime
from html import escape
from pathlib import Path

from ._page_assets import SCRIPT, STYLE
from ._store import FleetStore
from ._svg import COLOURS, trend_chart, verdict_chart
from ._trends import element_trends


SEVERITY = {"failed": 0, "degraded": 1, "watch": 2, "unexplained": 3, "healthy": 4}
PAGE_FILE = "index.html"


def _label(row) -> str:
    return (
        "watch"
        if row.get("watch") and row["verdict"] not in ("failed", "degraded")
        else row["verdict"]
    )


def _g(x, unit="") -> str:
    return "-" if x is None else f"{x:.4g}{' ' + escape(unit) if unit else ''}"


def _table(tid: str, header, rows) -> str:
    head = "".join(f"<th>{escape(h)}</th>" for h in header)
    body = (
        "\n".join(rows) if rows else f'<tr><td colspan="{len(header)}" class="muted">none</td></tr>'
    )
    return (
        f'<table class="sortable" id="{tid}"><thead><tr>{head}</tr></thead>'
        f"<tbody>\n{body}\n</tbody></table>"
    )


def _row(*cells) -> str:
    return "<tr>" + "".join(cells) + "</tr>"


def _cell(text, *, sort=None, cls=None) -> str:
    attrs = (f' data-sort="{escape(str(sort))}"' if sort is not None else "") + (
        f' class="{cls}"' if cls else ""
    )
    return f"<td{attrs}>{text}</td>"


class _Fleet:
    """What the page shows, read from the store once."""

    def __init__(self, store: FleetStore):
        self.judgements = store.judgements()
        self.verdicts = store.verdict_rows()
        self.failures = store.failures()
        self.by_bogie: dict[str, list] = {}
        for j in self.judgements:
            self.by_bogie.setdefault(j["bogie_id"], []).append(j)
        self.latest = {b: js[-1] for b, js in self.by_bogie.items()}
        self.rows = {}
        for v in self.verdicts:
            self.rows.setdefault((v["bogie_id"], v["date"]), []).append(v)

    def latest_rows(self, bogie):
        j = self.latest[bogie]
        return self.rows.get((bogie, j["date"]), [])

    def status(self, bogie) -> str:
        labels = [_label(r) for r in self.latest_rows(bogie)]
        if not self.latest[bogie]["explains_data"]:
            labels.append("unexplained")
        return min(labels, key=lambda s: SEVERITY.get(s, 4), default="healthy")


def _alarms(f: _Fleet) -> str:
    rows = []
    for bogie in f.latest:
        for r in f.latest_rows(bogie):
            label = _label(r)
            if label not in ("failed", "degraded", "watch"):
                continue
            ci = "-" if r["ci_lo"] is None else f"[{r['ci_lo']:.4g}, {r['ci_hi']:.4g}]"
            rows.append((SEVERITY[label], bogie, _row(
                _cell(f'<a href="#bogie-{escape(bogie)}">{escape(bogie)}</a>', sort=bogie),
                _cell(r["date"]),
                _cell(escape(r["name"])),
                _cell(label, sort=SEVERITY[label], cls=label),
                _cell(_g(r["estimate"]), sort=r["estimate"], cls="num"),
                _cell(ci),
                _cell(f"[{r['band_lo']:.4g}, {r['band_hi']:.4g}]"),
                _cell(escape(r["unit"])),
                _cell(escape(r["reason"])),
            )))  # fmt: skip
    rows.sort(key=lambda t: (t[0], t[1]))
    header = ("bogie", "date", "element", "verdict", "estimate", "95 % interval",
              "healthy band", "unit", "reason")  # fmt: skip
    return _table("alarms", header, [r for _, _, r in rows])


def _unexplained(f: _Fleet) -> str:
    rows = []
    for j in f.judgements:
        if j["explains_data"]:
            continue
        fit = j["record"].get("fit") or {}
        left = [r for r in j["record"].get("runs") or [] if not r.get("used", True)]
        why = "; ".join(f"run {r.get('index')} left out ({r.get('reason', '')})" for r in left)
        ratio = fit.get("misfit_ratio")
        rows.append(_row(
            _cell(escape(j["bogie_id"])), _cell(j["date"]),
            _cell(_g(ratio), sort=ratio, cls="num"),
            _cell(f"{j['runs_used']}/{j['runs_total']}"),
            _cell(escape(why) or "misfit above its limit"),
        ))  # fmt: skip
    judged = {(j["bogie_id"], j["date"]) for j in f.judgements}
    last = {(x["bogie_id"], x["date"]): x for x in f.failures}  # the latest attempt's error
    errors = [x for k, x in sorted(last.items()) if k not in judged]
    fails = [
        _row(_cell(escape(x["bogie_id"])), _cell(x["date"]), _cell(x["created_at"]),
             _cell(escape(x["error"])))
        for x in errors
    ]  # fmt: skip
    return "\n".join([
        _table("unexplained", ("bogie", "date", "misfit ratio", "runs used", "why"), rows),
        "<h3>Not judged (the error of the last attempt; the next run tries again)</h3>",
        _table("failures", ("bogie", "date", "when", "error"), fails),
    ])  # fmt: skip


def _overview(f: _Fleet) -> str:
    rows = []
    for bogie, js in f.by_bogie.items():
        status, j = f.status(bogie), f.latest[bogie]
        rows.append(_row(
            _cell(f'<a href="#bogie-{escape(bogie)}">{escape(bogie)}</a>', sort=bogie),
            _cell(status, sort=SEVERITY.get(status, 4), cls=status.replace(" ", "-")),
            _cell(j["date"]), _cell(str(len(js)), cls="num"),
            _cell(str(j["n_alarms"]), cls="num"), _cell(str(j["n_watches"]), cls="num"),
            _cell("yes" if j["explains_data"] else "no"), _cell(escape(j["vehicle"])),
            _cell(escape(j["code_version"])),
        ))  # fmt: skip
    header = ("bogie", "status", "latest", "judgements", "alarms", "watches", "data explained",
              "vehicle", "code version")  # fmt: skip
    return _table("bogies", header, rows)


def _history(f: _Fleet, bogie: str) -> str:
    rows = []
    for j in f.by_bogie[bogie]:
        names = [f"{escape(r['name'])}: {_label(r)}" for r in f.rows.get((bogie, j["date"]), [])
                 if _label(r) in ("failed", "degraded", "watch")]  # fmt: skip
        rows.append(_row(
            _cell(j["date"]), _cell(str(j["n_alarms"]), cls="num"),
            _cell(str(j["n_watches"]), cls="num"), _cell("yes" if j["explains_data"] else "no"),
            _cell(", ".join(names) or "-"), _cell(escape(j["code_version"])),
        ))  # fmt: skip
    header = ("date", "alarms", "watches", "data explained", "alarms and watches", "code version")
    return _table(f"history-{escape(bogie)}", header, rows)


def _bogie_section(f: _Fleet, bogie: str, alpha: float) -> str:
    j, status = f.latest[bogie], f.status(bogie)
    rows = f.latest_rows(bogie)
    chart = verdict_chart(rows, f"{bogie} on {j['date']}: estimates against healthy bands")
    series = element_trends(bogie, [x["record"] for x in f.by_bogie[bogie]], alpha)
    trends = [trend_chart(t) for t in series if sum(p[1] is not None for p in t.points) >= 2]
    trend_html = (
        f'<div class="trends">{"".join(trends)}</div>' if trends
        else '<p class="muted">one judgement with estimates: no trend yet</p>'
    )  # fmt: skip
    return f"""<section class="bogie" id="bogie-{escape(bogie)}" data-id="{escape(bogie)}"
 data-severity="{SEVERITY.get(status, 4)}" data-date="{j["date"]}">
<h3>{escape(bogie)}: <span class="{status.replace(" ", "-")}">{escape(status)}</span>
 (latest {j["date"]}, {len(f.by_bogie[bogie])} judgements)</h3>
<p>Latest estimates relative to the middle of each healthy band (green: the band; dashed red:
the failure limit; bar: the 95 % interval; colour: the verdict).</p>
{chart}
<h4>Trends (estimates and 95 % intervals by date; dashed: the fitted trend)</h4>
{trend_html}
<h4>History</h4>
{_history(f, bogie)}
</section>"""


def _legend() -> str:
    items = "".join(
        f'<span style="color:{c}">&#9679; {escape(k)}</span>' for k, c in COLOURS.items()
    )
    return f'<p class="legend">{items}</p>'


def fleet_page(store: FleetStore, *, false_alarm_rate: float = 0.05) -> str:
    """The whole page as text."""
    f = _Fleet(store)
    bogies = sorted(f.latest, key=lambda b: (SEVERITY.get(f.status(b), 4), b))
    sections = "\n".join(_bogie_section(f, b, false_alarm_rate) for b in bogies)
    now = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Fleet report</title>
<style>{STYLE}</style></head>
<body data-ready="no">
<h1>Fleet report</h1>
<p>{len(f.latest)} bogies, {len(f.judgements)} judgements, from {escape(store.where)};
written {now}. Verdicts and intervals as <code>bogie-jax monitor</code> gives them (the verdict
rules: docs/monitoring.md of bogie_jax).</p>
{_legend()}
<h2 id="alarms-and-watches">Alarms and watches (latest judgement of each bogie)</h2>
{_alarms(f)}
<h2 id="data-not-explained">Data not explained</h2>
{_unexplained(f)}
<h2 id="fleet">Bogies</h2>
{_overview(f)}
<p><label>Order the bogies by <select id="bogie-order"><option value="severity">severity
</option><option value="id">id</option><option value="date">latest date</option></select>
</label></p>
<div id="bogie-sections">
{sections}
</div>
<script>{SCRIPT}</script>
</body></html>
"""


def write_fleet_page(store: FleetStore, out, *, false_alarm_rate: float = 0.05) -> Path:
    """Write `out/index.html`; returns its path."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / PAGE_FILE
    path.write_text(fleet_page(store, false_alarm_rate=false_alarm_rate), encoding="utf-8")
    return path
