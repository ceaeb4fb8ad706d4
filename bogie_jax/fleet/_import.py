"""`import_results`: earlier `bogie-jax monitor` (or `demo`) output folders into the fleet
database, each as the judgement of one bogie on its `verdicts.json` date. Every folder is read
and checked before anything is written; a bogie-date already stored is left as it is."""

import dataclasses

from ..io import read_verdicts
from ._store import FleetStore


class ImportProblem(ValueError):
    """Folders that cannot be imported (one line)."""


@dataclasses.dataclass(frozen=True)
class ImportSummary:
    run_id: int
    imported: int
    skipped: tuple[tuple[str, str], ...]


def read_results(paths, bogie_id: str | None) -> list[tuple[str, dict]]:
    """`(bogie id, record)` of every folder (or `verdicts.json`): the id `bogie_id`, else the
    record's own `bogie_id` (a fleet run's). **Raises:** `ImportProblem` for an unreadable
    folder, a record without an id when `bogie_id` is None, or one bogie-date twice."""
    out, seen = [], {}
    for p in paths:
        try:
            record = read_verdicts(p)
        except ValueError as e:
            raise ImportProblem(str(e)) from None
        bid = bogie_id or record.get("bogie_id")
        if not bid:
            raise ImportProblem(f"{record['path']} names no bogie: give `--bogie ID`")
        key = (bid, record["date"])
        if key in seen:
            raise ImportProblem(
                f"{record['path']} and {seen[key]} are both bogie {bid!r} on {key[1]}: import one"
            )
        seen[key] = record["path"]
        out.append((bid, record))
    return out


def import_results(store: FleetStore, results, *, vehicle: str, layout: str,
                   command: str = "", say=print) -> ImportSummary:  # fmt: skip
    """Store `read_results`' records (migrated `store`); a stored bogie-date is skipped."""
    judged = store.judged()
    run_id = store.start_run(command, "import")
    skipped, n = [], 0
    try:
        for bid, record in results:
            key = (bid, record["date"])
            if key in judged:
                skipped.append(key)
                say(f"  {bid} {key[1]}: already stored, skipped ({record['path']})")
                continue
            body = {k: v for k, v in record.items() if k != "path"}
            store.write_judgement(body, bogie_id=bid, date=key[1],
                                  vehicle=record.get("vehicle", vehicle),
                                  layout=record.get("layout", layout), run_id=run_id)  # fmt: skip
            n += 1
            say(f"  {bid} {key[1]}: imported from {record['path']}")
    finally:
        store.finish_run(run_id, judged=n, failed=0)
    return ImportSummary(run_id, n, tuple(skipped))
