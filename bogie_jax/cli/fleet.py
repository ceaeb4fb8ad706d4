"""`bogie-jax fleet`: many bogies from an inventory, their history in a database, one page.

- `fleet run --inventory FILE --db URL`: judge every bogie and date of the inventory that the
  database does not hold yet (resumable), on a local Dask cluster (every core), an existing one
  (`--scheduler ADDRESS`) or this process (`--engine serial`); progress after each bogie-date.
- `fleet import --db URL DIR...`: earlier `monitor` / `demo` output folders into the database.
- `fleet trend --db URL`: per bogie, the trend of every element over its judgements.
- `fleet report --db URL --out DIR`: `DIR/index.html`, one static page.

The database is SQLite (a file path or `sqlite:///PATH`) or PostgreSQL (`postgresql://...`);
`docs/fleet.md` has the inventory format. Bad input (a missing file, a repeated id, a bad date,
a database of a newer schema or out of reach) is one line and exit code 2, before any fit and
with nothing written. Needs the `fleet` extra: `pip install "bogie-jax[fleet]"`.
"""

import json
import sys
from pathlib import Path

from ._common import UsageError, text_table


def add_parser(sub):
    p = sub.add_parser(
        "fleet",
        help="judge a fleet from an inventory; its history in a database; trends; one HTML page",
        description="Subcommands: run, import, trend, report (`bogie-jax fleet run --help`).",
    )
    fleet = p.add_subparsers(dest="fleet_command", required=True, parser_class=type(p))
    _run_parser(fleet)
    _import_parser(fleet)
    _trend_parser(fleet)
    _report_parser(fleet)
    return p


def _db(p):
    p.add_argument(
        "--db",
        default="fleet.db",
        help="database: a SQLite file path or sqlite:///PATH, or postgresql://USER@HOST:PORT/DB "
        "(default fleet.db)",
    )


def _run_parser(fleet):
    p = fleet.add_parser("run", help="judge every bogie and date not yet in the database")
    p.add_argument("--inventory", required=True, metavar="FILE", help="fleet inventory (TOML)")
    _db(p)
    p.add_argument(
        "--engine",
        choices=("dask", "serial"),
        default="dask",
        help="dask: a Dask cluster (default: a local one, one worker process per core); serial: "
        "one bogie after another in this process",
    )
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="--engine dask: address of a running Dask scheduler, e.g. tcp://10.0.0.5:8786 "
        "(default: start a local cluster)",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        help="local cluster: worker processes (default: one per two cores)",
    )


def _import_parser(fleet):
    p = fleet.add_parser("import", help="earlier monitor output folders into the database")
    p.add_argument("folders", nargs="+", metavar="DIR", help="output folders or verdicts.json")
    _db(p)
    p.add_argument(
        "--bogie", default=None, help="bogie id of every folder (default: each record's own)"
    )
    p.add_argument(
        "--vehicle", default="manchester", help="vehicle parameter set (default manchester)"
    )
    p.add_argument("--layout", default="default", help="sensor layout name (default default)")


def _trend_parser(fleet):
    p = fleet.add_parser("trend", help="per bogie, the trend of every element over its judgements")
    _db(p)
    p.add_argument("--bogie", nargs="+", default=None, help="only these bogies (default: all)")
    p.add_argument("--out", default=None, help="also write DIR/trends.json")
    p.add_argument(
        "--false-alarm-rate", type=float, default=0.05, help="drift test level (default 0.05)"
    )


def _report_parser(fleet):
    p = fleet.add_parser("report", help="one static HTML page of the fleet")
    _db(p)
    p.add_argument("--out", default="fleet_report", help="output folder (default fleet_report)")


def _fleet():
    try:
        import bogie_jax.fleet as fleet
    except ModuleNotFoundError as e:
        raise UsageError(
            f'`bogie-jax fleet` needs {e.name!r}: pip install "bogie-jax[fleet]"'
        ) from None
    return fleet


def open_fleet_store(url: str):
    """The fleet database at `url`, opened for reading (`UsageError` if it is not there, out
    of reach or of a newer schema)."""
    fleet = _fleet()
    try:
        return fleet.open_store(url, create=False)
    except fleet.StoreError as e:
        raise UsageError(str(e)) from None


def run(args, progress) -> int:
    fleet = _fleet()
    handlers = {"run": _run, "import": _import, "trend": _trend, "report": _report}
    try:
        return handlers[args.fleet_command](fleet, args, progress)
    except (fleet.InventoryError, fleet.StoreError, fleet.EngineError, fleet.ImportProblem) as e:
        raise UsageError(str(e)) from None


def _command() -> str:
    return "bogie-jax " + " ".join(sys.argv[1:])


def _cache_dir() -> str | None:
    import jax

    if not jax.config.jax_enable_compilation_cache:
        return None
    return jax.config.jax_compilation_cache_dir


def _engine(fleet, args):
    if args.engine == "serial":
        if args.scheduler or args.workers:
            raise UsageError("`--scheduler` and `--workers` need `--engine dask`")
        return fleet.SerialEngine()
    return fleet.DaskEngine(address=args.scheduler, workers=args.workers)


def _run(fleet, args, progress) -> int:
    inventory = fleet.read_inventory(args.inventory)
    store = fleet.open_store(args.db, create=True)
    engine = _engine(fleet, args)
    with store, engine:
        store.migrate()
        summary = fleet.run_fleet(
            inventory, store, engine, command=_command(), cache_dir=_cache_dir(),
            say=progress.say,
        )  # fmt: skip
    progress.say(
        f"run {summary.run_id}: {summary.judged} judged, {summary.failed} failed, "
        f"{summary.before} judged before, of {summary.total}, in {summary.wall_s:.0f} s; "
        f"stored in {store.where}"
    )
    return 1 if summary.failed else 0


def _import(fleet, args, progress) -> int:
    results = fleet.read_results(args.folders, args.bogie)
    with fleet.open_store(args.db, create=True) as store:
        store.migrate()
        summary = fleet.import_results(
            store, results, vehicle=args.vehicle, layout=args.layout, command=_command(),
            say=progress.say,
        )  # fmt: skip
    progress.say(
        f"imported {summary.imported}, skipped {len(summary.skipped)} already stored, into "
        f"{store.where}"
    )
    return 0


def _trend(fleet, args, progress) -> int:
    if not 0 < args.false_alarm_rate < 0.5:
        raise UsageError(f"`--false-alarm-rate` = {args.false_alarm_rate!r} must lie in (0, 0.5)")
    with fleet.open_store(args.db, create=False) as store:
        judgements, where = store.judgements(), store.where
    by_bogie = {}
    for j in judgements:
        by_bogie.setdefault(j["bogie_id"], []).append(j["record"])
    unknown = sorted(set(args.bogie or ()) - set(by_bogie))
    if unknown:
        raise UsageError(f"`--bogie` {', '.join(unknown)}: not in {where}")
    items = []
    for bogie in args.bogie or sorted(by_bogie):
        series = fleet.element_trends(bogie, by_bogie[bogie], args.false_alarm_rate)
        progress.say(_trend_table(bogie, by_bogie[bogie], series))
        items += [_trend_item(s) for s in series if s.trend is not None]
    if args.out:
        path = Path(args.out) / "trends.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        body = {"format": "bogie_jax.fleet_trends/1", "false_alarm_rate": args.false_alarm_rate,
                "trends": items}  # fmt: skip
        path.write_text(json.dumps(body, indent=1) + "\n", encoding="utf-8")
        progress.say(f"wrote {path}")
    return 0


def _trend_item(s) -> dict:
    d = s.trend.to_dict()
    return {"bogie_id": s.bogie_id, "unit": s.unit, **d}


def _trend_table(bogie, records, series) -> str:
    rows = [("element", "judgements", "level", "slope [unit/day]", "se(slope)", "drift",
             "days to band edge", "unit")]  # fmt: skip
    for s in series:
        t = s.trend
        if t is None:
            rows.append((s.name, len(s.points), "-", "-", "-", "-", "-", s.unit))
            continue
        rows.append((
            s.name, len(t.dates), f"{t.level:.4g}", f"{t.slope:+.3g}", f"{t.slope_std_error:.3g}",
            "DRIFT" if t.drift else "no",
            "-" if t.days_to_band_edge is None else f"{t.days_to_band_edge:.3g}", s.unit,
        ))  # fmt: skip
    dates = sorted(r["date"] for r in records)
    return f"{bogie}: {len(records)} judgements, {dates[0]} to {dates[-1]}\n{text_table(rows)}"


def _report(fleet, args, progress) -> int:
    with fleet.open_store(args.db, create=False) as store:
        path = fleet.write_fleet_page(store, args.out)
    progress.say(f"wrote {path}")
    return 0
