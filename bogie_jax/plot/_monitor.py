"""Condition-monitoring figures: every element's estimate and interval against its tolerance
band, measured against fitted sensor signals, and an element's trend over dated runs.

Verdicts are taken as `bogie_jax.monitor.Verdict` objects or as their dictionaries (the rows of
`verdicts.json`, `Verdict.to_dict`). matplotlib is imported lazily; every function takes
`ax=None` (a new figure) and returns the axes.
"""

import math

import numpy as np

from ._common import get_axes


_VERDICT_COLOURS = {
    "healthy": "C2",
    "degraded": "C1",
    "failed": "C3",
    "not identifiable": "0.55",
}


def _row(verdict) -> dict:
    """A verdict as the dictionary of `Verdict.to_dict` (an estimate the data do not
    determine, a non-finite standard error, becomes `None` as in `verdicts.json`)."""
    row = verdict.to_dict() if hasattr(verdict, "to_dict") else dict(verdict)
    se = row.get("std_error")
    if se is None or not math.isfinite(float(se)):
        row = {**row, "estimate": None, "ci95": None}
    return row


def plot_verdicts(verdicts, *, ax=None, title: str | None = None):
    """Each element's estimate with its 95 % interval against its healthy band, all relative
    to the band's centre (the nominal value for the default bands `nominal * (1 -+ t)`), so
    elements of different units share one axis.

    The healthy band is the shaded span of each row, the failure limit (`failed_below`,
    `failed_above`) a red tick, the Wald decision interval estimate +- z standard errors (the
    evidence's `decision_interval`, wider than the 95 % interval when several elements are
    judged; an element estimated outside its band is judged by its profile test) a
    pale bar behind the 95 % error bar; markers are coloured by verdict (healthy green, degraded
    orange, failed red, not identifiable grey: no estimate, the row shows only the band).

    **Arguments:** `verdicts`: `Verdict`s or `verdicts.json` rows; `ax`; `title`.
    **Returns:** the axes.
    """
    rows = [_row(v) for v in verdicts]
    if not rows:
        raise ValueError("`verdicts` is empty: nothing to plot")
    ax = get_axes(ax, (7.5, 0.42 * len(rows) + 2.2))
    y = np.arange(len(rows))[::-1]
    for k, row in zip(y, rows):
        band = row["tolerance_band"]
        lo, hi = band["healthy"]
        ref = 0.5 * (lo + hi)
        ax.fill_betweenx(
            [k - 0.3, k + 0.3], lo / ref, hi / ref, color="C2", alpha=0.15, lw=0,
            label="healthy band" if k == y[0] else None,
        )  # fmt: skip
        for limit in (band.get("failed_below"), band.get("failed_above")):
            if limit is not None:
                ax.plot([limit / ref] * 2, [k - 0.3, k + 0.3], color="C3", lw=1.5)
        colour = _VERDICT_COLOURS.get(row["verdict"], "k")
        if row["estimate"] is not None:
            est = row["estimate"] / ref
            lo95, hi95 = (c / ref for c in row["ci95"])
            decision = (row.get("evidence") or {}).get("decision_interval")
            if decision is not None:
                ax.plot(
                    [decision[0] / ref, decision[1] / ref], [k, k], color=colour, lw=4,
                    alpha=0.3, solid_capstyle="butt",
                )  # fmt: skip
            ax.errorbar(est, k, xerr=[[est - lo95], [hi95 - est]], fmt="o", color=colour, capsize=3)
        ax.annotate(
            row["verdict"], (1.0, k), xycoords=("axes fraction", "data"), xytext=(4, 0),
            textcoords="offset points", va="center", fontsize="small", color=colour,
        )  # fmt: skip
    ax.plot([], [], color="C3", lw=1.5, label="failure limit")
    ax.errorbar([], [], xerr=[], fmt="o", color="k", capsize=3, label="estimate, 95 % interval")
    ax.plot([], [], color="k", lw=4, alpha=0.3, label="decision interval (estimate +- z SE)")
    ax.axvline(1.0, color="k", lw=0.6)
    ax.set_yticks(y, [r["name"] for r in rows])
    ax.set_ylim(y.min() - 2.2, y.max() + 0.7)  # below the last row: room for the legend
    ax.set_xlabel("value / band centre (nominal) [-]")
    ax.set_title(title or "verdicts: estimates against tolerance bands")
    ax.legend(fontsize="small", loc="lower center", ncol=2)
    ax.grid(True, axis="x", alpha=0.3)
    return ax


def plot_signal_fit(
    times,
    measured,
    fitted,
    *,
    name: str,
    unit: str,
    ax=None,
    title: str | None = None,
):
    """One sensor channel: measured samples against the model's signal at the estimate, and
    their difference (the residual, dotted).

    **Arguments:** `times` (n,) [s]; `measured`, `fitted` (n,) [`unit`] (NaN: a missing
    sample); `name`, `unit` of the channel; `ax`; `title` (default: the channel name).
    **Returns:** the axes.
    """
    t = np.asarray(times, dtype=float)
    y, f = np.asarray(measured, dtype=float), np.asarray(fitted, dtype=float)
    if not (t.shape == y.shape == f.shape and t.ndim == 1):
        raise ValueError(
            f"`times`, `measured` and `fitted` must be 1-D of one length; got shapes {t.shape}, "
            f"{y.shape}, {f.shape}"
        )
    ax = get_axes(ax, (7, 2.8))
    ax.plot(t, y, ".", ms=2.5, color="0.35", label="measured")
    ax.plot(t, f, "-", lw=1.2, color="C0", label="fitted model")
    ax.plot(t, y - f, ":", lw=0.9, color="C3", label="measured - fitted")
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"{name} [{unit}]")
    ax.set_title(title or name, fontsize="medium")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="x-small", loc="upper right", ncol=3)
    return ax


def plot_trend(trend, *, band=None, unit: str = "", ax=None):
    """One element's estimates over the dated runs (error bars +- 1.96 standard errors: the
    trend uses the standard errors only, and a verdict's own 95 % interval can be wider, see
    `bogie_jax.monitor.judge`), the weighted regression line of `bogie_jax.monitor.trend`, and
    the healthy band; the title carries the drift flag.

    **Arguments:** `trend`: a `bogie_jax.monitor.Trend` (or its `to_dict()` with `times` added);
    `band`: the element's `ToleranceBand` or its dictionary (shaded), or `None`; `unit` of the
    estimates; `ax`.
    **Returns:** the axes.
    """
    d = trend.to_dict() if hasattr(trend, "to_dict") else dict(trend)
    t = np.asarray(trend.times if hasattr(trend, "times") else d["times"], dtype=float)
    p = np.asarray(d["estimates"], dtype=float)
    s = np.asarray(d["std_errors"], dtype=float)
    ax = get_axes(ax, (7, 3.2))
    ax.errorbar(t, p, yerr=1.96 * s, fmt="o", capsize=3, color="C0", label="estimate +- 1.96 SE")
    line = d["level"] + d["slope_per_day"] * (t - t[-1])
    ax.plot(t, line, "-", color="C1", label=f"trend {d['slope_per_day']:+.3g} {unit}/day")
    if band is not None:
        healthy = band.healthy if hasattr(band, "healthy") else band["healthy"]
        ax.axhspan(*healthy, color="C2", alpha=0.12, label="healthy band")
    flag = "DRIFT" if d["drift"] else "no drift"
    p_text = "p < 1e-6" if d["p_value"] < 1e-6 else f"p = {d['p_value']:.2g}"
    ax.set_title(f"{d['name']}: {flag} ({p_text})", fontsize="medium")
    ax.set_xlabel(f"days since {d['dates'][0][:10]} [day]")
    ax.set_ylabel(f"estimate [{unit}]" if unit else "estimate [-]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="x-small")
    return ax
