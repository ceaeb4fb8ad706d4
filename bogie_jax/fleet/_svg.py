"""The fleet page's figures as inline SVG (no plotting library, no script): each element's
latest estimate and 95 % interval against its healthy band, and its estimates over dates."""

import datetime
import math
from html import escape


COLOURS = {
    "failed": "#b00020",
    "degraded": "#d35400",
    "watch": "#b7950b",
    "healthy": "#1e7b34",
    "not identifiable": "#7f8c8d",
}
ROW = 22  # [px] per element in a verdict chart
LEFT, WIDTH = 190, 620  # [px] label column, whole width
SCALE = (0.0, 2.0)  # relative to the band's middle: 0 % to 200 %


def colour(verdict: str, watch) -> str:
    return (
        COLOURS["watch"]
        if watch and verdict not in ("failed", "degraded")
        else COLOURS.get(verdict, "#444")
    )


def _x(value: float, mid: float) -> float:
    lo, hi = SCALE
    rel = min(max(value / mid, lo), hi) if mid else lo
    return LEFT + (rel - lo) / (hi - lo) * (WIDTH - LEFT - 20)


def _axis(height: int) -> list[str]:
    parts = []
    for pct in range(0, 201, 25):
        x = _x(pct / 100, 1.0)
        parts.append(f'<line x1="{x:.1f}" y1="14" x2="{x:.1f}" y2="{height - 18}" stroke="#ddd"/>')
        parts.append(f'<text x="{x:.1f}" y="{height - 5}" text-anchor="middle">{pct} %</text>')
    return parts


def verdict_chart(rows, title: str) -> str:
    """Rows: `verdicts` rows (`_store.verdict_rows` form) of one judgement."""
    height = 40 + ROW * len(rows)
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" class="chart" width="{WIDTH}" '
             f'height="{height}" role="img" aria-label="{escape(title)}">',
             f"<title>{escape(title)}</title>", *_axis(height)]  # fmt: skip
    for k, r in enumerate(rows):
        parts += _verdict_row(r, 18 + ROW * k)
    parts.append("</svg>")
    return "\n".join(parts)


def _verdict_row(r, y) -> list[str]:
    mid = 0.5 * (r["band_lo"] + r["band_hi"])
    x0, x1 = _x(r["band_lo"], mid), _x(r["band_hi"], mid)
    c = colour(r["verdict"], r.get("watch"))
    label = f"{r['name']}: {r['verdict']}{' (watch)' if r.get('watch') else ''}"
    parts = [
        f'<text x="4" y="{y + 14}">{escape(r["name"])}</text>',
        f'<rect x="{x0:.1f}" y="{y + 3}" width="{x1 - x0:.1f}" height="{ROW - 6}" fill="#e3f1e6"/>',
    ]
    if r.get("failed_below") is not None:
        xf = _x(r["failed_below"], mid)
        parts.append(
            f'<line x1="{xf:.1f}" y1="{y + 2}" x2="{xf:.1f}" y2="{y + ROW - 2}" stroke="#b00020" '
            'stroke-dasharray="3,2"/>'
        )
    if r.get("estimate") is None:
        parts.append(f'<text x="{x1 + 6:.1f}" y="{y + 14}" fill="{c}">not identifiable</text>')
        return parts
    if r.get("ci_lo") is not None:
        a, b = _x(r["ci_lo"], mid), _x(r["ci_hi"], mid)
        parts.append(
            f'<line x1="{a:.1f}" y1="{y + 11}" x2="{b:.1f}" y2="{y + 11}" '
            f'stroke="{c}" stroke-width="2"/>'
        )
    xe = _x(r["estimate"], mid)
    parts.append(
        f'<circle cx="{xe:.1f}" cy="{y + 11}" r="4" fill="{c}">'
        f"<title>{escape(label)}: {r['estimate']:.4g} {escape(r['unit'])}</title></circle>"
    )
    return parts


def _days(dates) -> list[float]:
    first = datetime.date.fromisoformat(dates[0])
    return [(datetime.date.fromisoformat(d) - first).days for d in dates]


def trend_chart(series) -> str:
    """One element's estimates and 95 % intervals over dates (`_trends.ElementTrend`), with its
    healthy band and, where fitted, the trend line."""
    pts = [p for p in series.points if p[1] is not None]
    w, h, pad = 350, 150, 34
    lo, hi = series.band.healthy
    values = [lo, hi] + [v for p in pts for v in p[1:4] if v is not None]
    vmin, vmax = min(values), max(values)
    span = (vmax - vmin) or abs(vmax) or 1.0
    vmin, vmax = vmin - 0.08 * span, vmax + 0.08 * span
    days = _days([p[0] for p in pts]) if pts else []
    dmax = max(days[-1], 1) if days else 1
    x = lambda d: pad + d / dmax * (w - pad - 8)
    y = lambda v: 20 + (vmax - v) / (vmax - vmin) * (h - 40)
    t = series.trend
    drift = (
        ""
        if t is None
        else (f", {t.slope:+.3g} {series.unit}/day" + (", DRIFT" if t.drift else ""))
    )
    title = f"{series.name} [{series.unit}]{drift}"
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" class="chart trend" width="{w}" '
             f'height="{h}" role="img" aria-label="{escape(title)}">',
             f"<title>{escape(title)}</title>",
             f'<text x="4" y="12" font-size="10">{escape(title)}</text>',
             f'<rect x="{pad}" y="{y(hi):.1f}" width="{w - pad - 8}" height="{y(lo) - y(hi):.1f}" '
             'fill="#e3f1e6"/>']  # fmt: skip
    if t is not None:
        a = t.level - t.slope * t.times[-1]
        parts.append(
            f'<line x1="{x(0):.1f}" y1="{y(a):.1f}" x2="{x(t.times[-1]):.1f}" '
            f'y2="{y(t.level):.1f}" stroke="#555" stroke-dasharray="4,3"/>'
        )
    for (date, est, clo, chi, verdict), d in zip(pts, days):
        c = colour(verdict, None)
        if clo is not None:
            parts.append(
                f'<line x1="{x(d):.1f}" y1="{y(clo):.1f}" x2="{x(d):.1f}" '
                f'y2="{y(chi):.1f}" stroke="{c}"/>'
            )
        parts.append(
            f'<circle cx="{x(d):.1f}" cy="{y(est):.1f}" r="3.5" fill="{c}"><title>'
            f"{date}: {est:.4g} {escape(series.unit)} ({verdict})</title></circle>"
        )
    parts.append(f'<text x="{pad}" y="{h - 4}">{escape(pts[0][0]) if pts else ""}</text>')
    if len(pts) > 1:
        parts.append(f'<text x="{w - 8}" y="{h - 4}" text-anchor="end">{escape(pts[-1][0])}</text>')
    parts.append(f'<text x="2" y="{y(hi) + 4:.1f}" font-size="9">{_g(hi)}</text>')
    parts.append(f'<text x="2" y="{y(lo) + 4:.1f}" font-size="9">{_g(lo)}</text>')
    parts.append("</svg>")
    return "\n".join(parts)


def _g(x: float) -> str:
    return f"{x:.3g}" if math.isfinite(x) else "-"
