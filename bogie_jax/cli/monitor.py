"""`bogie-jax monitor`: verdicts per suspension element from measurement files, or the trend of
every element over earlier results.

- `--data FILE...`: measurement files (`bogie_jax.io` CSV or NPZ: each with its speed, track
  reference and window position) of one bogie, judged jointly by `bogie_jax.monitor.monitor`;
  writes `verdicts.json` (dated by `--date`), `verdicts.png`, `signals.png` and `report.md`.
- `--history DIR...`: earlier output directories (or their `verdicts.json` files), in date
  order; per element `bogie_jax.monitor.trend` -> `trends.json`, `trends.png`, `trends.md`.
- `--candidates NAME...` (with `--data`): the elements judged; `--list-elements` prints the
  names it takes and exits (`_candidates.py`).
- `--contact` and `--fit-model` (with `--data`): the wheel-rail contact and the equations the
  fit uses (`_model_choice.py`); `verdicts.json` records both.

Without `--data` or `--history` there is nothing to judge: the command says so (exit code 2)
and points at `bogie-jax demo`, which runs the built-in case.

Exit codes of `--data`: 0 verdicts written; 1 every run's simulation failed; 2 bad input;
`NOT_EXPLAINED` (3) verdicts written, but the fit does not explain the data in some run and
channel group (`MonitorResult.explained`: the verdicts, the table and the report say where).
"""

import math
from pathlib import Path

import numpy as np

from ..io import (
    check_date,
    load_measurement,
    load_run_tracks,
    read_verdicts,
    write_trend_report,
    write_trends,
)
from ..monitor import (
    MonitorOptions,
    band_of_row,
    comparable_estimates,
    monitor,
    trend_of_rows,
)
from ._candidates import add_options, check_candidates, list_elements
from ._common import UsageError, text_table
from ._model_choice import add_contact, add_fit_model, fit_model, params_with_contact
from ._monitor_output import fitted_signals, verdict_table, write_outputs
from ._names import lookup, names


NOT_EXPLAINED = 3  # exit code: the verdicts are written, but the data are not explained


def add_parser(sub):
    p = sub.add_parser(
        "monitor",
        help="verdicts per suspension element from measurement files, or trends over results",
        description="--data FILE...: judge every suspension element from measurement files of "
        "one bogie (fitted jointly) and write verdicts.json, figures and report.md to --out. "
        "--history DIR...: the trend of every element over earlier outputs (their "
        "verdicts.json), in date order. One of the two is required; `bogie-jax demo` runs the "
        "built-in case.",
    )
    src = p.add_mutually_exclusive_group()
    src.add_argument(
        "--data",
        nargs="+",
        metavar="FILE",
        default=None,
        help="measurement files FILE.csv or FILE.npz (bogie_jax.io), one per run",
    )
    src.add_argument(
        "--history",
        nargs="*",
        metavar="DIR",
        default=None,
        help="earlier output directories or verdicts.json files, oldest first (none with --db)",
    )
    p.add_argument(
        "--db",
        default=None,
        metavar="URL",
        help="--history: read the results of --bogie from a fleet database (a SQLite file or a "
        "postgresql:// URL; `bogie-jax fleet`) instead of folders",
    )
    p.add_argument("--bogie", default=None, metavar="ID", help="--history --db: the bogie's id")
    p.add_argument(
        "--track",
        nargs="+",
        metavar="CSV",
        default=None,
        help="--data: measured track files (one for all runs, or one per file; default: each "
        "file's track reference)",
    )
    p.add_argument("--out", default="monitor_out", help="output directory (default monitor_out)")
    p.add_argument(
        "--date", default=None, help="--data: date of the runs, YYYY-MM-DD (default today)"
    )
    p.add_argument(
        "--vehicle", default="manchester", help="nominal parameter set (default manchester)"
    )
    p.add_argument(
        "--band",
        type=float,
        default=None,
        help="healthy band, relative half-width (default 0.2: nominal +-20 %%, failed below 25 %%)",
    )
    p.add_argument(
        "--false-alarm-rate",
        type=float,
        default=0.05,
        help="probability of any false alarm on a healthy bogie, or of a drift flag on a steady "
        "element (default 0.05)",
    )
    p.add_argument(
        "--track-error",
        type=float,
        default=0.0,
        help="--data: RMS error of the track records per channel [mm], carried into the "
        "intervals (default 0: the records are taken as exact)",
    )
    p.add_argument(
        "--noise",
        choices=names("noise"),
        default="per-channel",
        help="--data: noise model (default per-channel: each channel's noise estimated and the "
        "fit reweighted)",
    )
    p.add_argument(
        "--covariance",
        choices=names("covariance"),
        default=None,
        help="--data: covariance rule (default sandwich, gauss-newton with --track-error)",
    )
    add_contact(p)
    add_fit_model(p)
    add_options(p)
    return p


def run(args, progress) -> int:
    if args.list_elements:
        progress.say(list_elements(lookup("vehicle", args.vehicle)()))
        return 0
    if args.history is None and (args.db is not None or args.bogie is not None):
        raise UsageError("`--db` and `--bogie` go with `--history`")
    if args.data is None and args.history is None:
        raise UsageError(
            "give --data FILE... (measurement files to judge) or --history DIR... (earlier "
            "outputs to trend); `bogie-jax demo` runs the built-in case"
        )
    if args.data is None and args.candidates is not None:
        raise UsageError(
            "`--candidates` goes with `--data` (a trend follows the results' elements)"
        )
    model = (args.contact, args.fit_model, args.wear, args.wheel_profile)
    if args.data is None and model != ("cone", "linear", None, None):
        raise UsageError(
            "`--contact`, `--wear`, `--wheel-profile` and `--fit-model` go with `--data`"
        )
    if not 0 < args.false_alarm_rate < 0.5:
        raise UsageError(f"`--false-alarm-rate` = {args.false_alarm_rate!r} must lie in (0, 0.5)")
    if not 0 <= args.track_error <= 10:
        raise UsageError(f"`--track-error` = {args.track_error!r} mm must lie in [0, 10]")
    if args.history is not None:
        return run_history(args, progress)
    return run_data(args, progress)


# --- --data ----------------------------------------------------------------------------------


def run_data(args, progress) -> int:
    date = _date(args.date)
    params = params_with_contact(args.vehicle, args, vehicle_option="--vehicle")
    candidates = check_candidates(params, args.candidates)
    for f in args.data + (args.track or []):
        if not Path(f).is_file():
            raise UsageError(f"file {f!r} does not exist")
    try:
        measurements = [load_measurement(f) for f in args.data]
        tracks = load_run_tracks(args.data, measurements, args.track)
    except ValueError as e:  # MeasurementError, a bad track file
        raise UsageError(str(e)) from None
    for f, m in zip(args.data, measurements):
        progress.say(
            f"{f}: {float(np.asarray(m.speed)):g} m/s, {len(m.times)} samples at "
            f"{m.sample_rate:g} Hz from {float(np.asarray(m.start_position)):g} m, "
            f"{len(m.channels)} channels, track {m.track.describe() if m.track else 'given'}"
        )
    try:
        options = MonitorOptions(
            candidates=candidates,
            band=args.band,
            false_alarm_rate=args.false_alarm_rate,
            track_error=1e-3 * args.track_error,
            noise=lookup("noise", args.noise),
            covariance=None if args.covariance is None else lookup("covariance", args.covariance),
            model=fit_model(args.fit_model),
            **({"refit_model": None} if args.no_model_refit else {}),
        )
        result = monitor(
            measurements,
            tracks,
            params=params,
            options=options,
            progress=lambda line: progress.say(f"  {line}"),
        )
    except ValueError as e:  # mixed layouts, a zero-width band, ... (before any compile)
        raise UsageError(str(e)) from None
    except RuntimeError as e:  # every run's simulation failed
        progress.say(f"bogie-jax monitor: {e}")
        return 1
    progress.say(verdict_table(result))
    equations = options.fitted_model(result.fit.model_refit)
    fitted = fitted_signals(result, measurements, tracks, params, progress, equations=equations)
    source = "bogie-jax monitor --data " + " ".join(args.data)
    extra = {
        "data": list(args.data), "contact": args.contact, "wear": args.wear,
        "wheel_profile": args.wheel_profile, "flange_back_mm": args.flange_back,
        "fit_model": args.fit_model, "model_refit_allowed": not args.no_model_refit,
    }  # fmt: skip
    paths = write_outputs(
        args.out, result, measurements, fitted, date=date, source=source, notes=[],
        extra=extra, progress=progress,
    )  # fmt: skip
    progress.say("wrote " + ", ".join(str(p) for p in paths))
    return 0 if result.explained else NOT_EXPLAINED


def _date(text):
    try:
        return check_date(text)
    except ValueError as e:
        raise UsageError(str(e).replace("`date`", "`--date`")) from None


# --- --history -------------------------------------------------------------------------------


def _candidates(record) -> tuple[str, ...]:
    return tuple(sorted(e["name"] for e in record.get("elements", [])))


def history_trends(records, false_alarm_rate):
    """Per verdict name, the `trend` over the records that estimate it (in the given order:
    the library refuses unsorted or duplicate dates) and, for a group, weigh its members as the
    latest of them does (`same_measure`). Returns `(trends, skipped, left_out)`: `trends` a
    list of `(Trend, unit, band, dates left out)`, `skipped` the names with fewer than two
    such estimates, `left_out` one note per name whose other estimates were left out.

    **Raises:** `ValueError` for mixed layouts (other candidate elements or units) and what
    `trend` and `ToleranceBand` raise."""
    first = records[0]
    for r in records[1:]:
        if _candidates(r) != _candidates(first):
            raise ValueError(
                f"mixed layouts: {r['path']} judges {', '.join(_candidates(r))}; "
                f"{first['path']} judges {', '.join(_candidates(first))}: trend one bogie layout"
            )
    order, series = [], {}
    for r in records:
        for row in r["verdicts"]:
            if row["name"] not in series:
                order.append(row["name"])
                series[row["name"]] = []
            series[row["name"]].append((r["date"], row))
    trends, skipped, left_out = [], [], []
    for name in order:
        rows = series[name]
        units = {row["unit"] for _, row in rows}
        if len(units) > 1:
            raise ValueError(f"mixed layouts: `{name}` has units {', '.join(sorted(units))}")
        known, other = comparable_estimates(rows)
        if other:
            left_out.append(
                f"{name}: left out {', '.join(other)}: there its estimate weighed the members "
                "otherwise than in the latest result (`member_weights`)"
            )
        if len(known) < 2:
            skipped.append(name)
            continue
        t = trend_of_rows(name, known, false_alarm_rate)
        trends.append((t, units.pop(), band_of_row(known[-1][1]), other))
    return trends, skipped, left_out


def _trend_figure(path, trends):
    import matplotlib.pyplot as plt

    from ..plot import plot_trend

    n = len(trends)
    cols = 2 if n > 1 else 1
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(
        rows, cols, figsize=(6.0 * cols, 2.9 * rows + 0.4), squeeze=False, layout="constrained"
    )
    for ax, (t, unit, band, _) in zip(axes.flat, trends):
        plot_trend(t, band=band, unit=unit, ax=ax)
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _history_records(args) -> list[dict]:
    """The `verdicts.json` records of `--history DIR...`, or of `--bogie` in `--db`."""
    if args.db is None:
        if args.bogie is not None:
            raise UsageError("`--bogie` needs `--db URL`")
        if not args.history:
            raise UsageError("`--history` needs DIR... or `--db URL --bogie ID`")
        return [read_verdicts(p) for p in args.history]
    if args.history:
        raise UsageError("give `--history DIR...` or `--history --db URL --bogie ID`, not both")
    if args.bogie is None:
        raise UsageError("`--history --db URL` needs `--bogie ID`")
    from .fleet import open_fleet_store

    with open_fleet_store(args.db) as store:
        rows = store.judgements(args.bogie)
    if not rows:
        raise UsageError(f"`--bogie` {args.bogie!r}: no results in {args.db}")
    return [dict(r["record"], path=f"{args.db} ({args.bogie}, {r['date']})") for r in rows]


def run_history(args, progress) -> int:
    try:
        records = _history_records(args)
        trends, skipped, left_out = history_trends(records, args.false_alarm_rate)
    except ValueError as e:  # unreadable, unsorted or duplicate dates, mixed layouts, bad band
        raise UsageError(str(e)) from None
    if not trends:
        raise UsageError(
            f"no element has an estimate in two or more of the {len(records)} results: a trend "
            "needs at least two"
        )
    rows = [
        ("element", "runs", "level", "slope [unit/day]", "se(slope)", "drift", "p",
         "days to band edge", "unit"),
    ]  # fmt: skip
    for t, unit, _, _ in trends:
        rows.append(
            (
                t.name, len(t.dates), f"{t.level:.4g}", f"{t.slope:+.3g}",
                f"{t.slope_std_error:.3g}", "DRIFT" if t.drift else "no",
                "< 1e-6" if t.p_value < 1e-6 else f"{t.p_value:.2g}",
                "-" if t.days_to_band_edge is None else f"{t.days_to_band_edge:.3g}", unit,
            )
        )  # fmt: skip
    progress.say(
        f"trends over {len(records)} results ({records[0]['date']} to {records[-1]['date']})"
    )
    progress.say(text_table(rows))
    notes = list(left_out)
    if skipped:
        notes.append(f"no trend (fewer than two comparable estimates): {', '.join(skipped)}")
    for note in notes:
        progress.say(note)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    _trend_figure(out / "trends.png", trends)
    items = [
        dict(t.to_dict(), unit=unit, times_days=[float(x) for x in t.times], left_out=other)
        for t, unit, _, other in trends
    ]
    paths = [
        write_trends(out / "trends.json", items, false_alarm_rate=args.false_alarm_rate,
                     sources=[r["path"] for r in records]),
        out / "trends.png",
        write_trend_report(
            out / "trends.md", items, sources=[(r["date"], r["path"]) for r in records],
            figure="trends.png",
            notes=notes,
        ),
    ]  # fmt: skip
    progress.say("wrote " + ", ".join(str(p) for p in paths))
    return 0
