"""`FleetStore`: the fleet's history in a database (SQLite by default, PostgreSQL by URL), through
SQLAlchemy Core. Every write is one transaction: a judgement with its verdicts and fit, a
failure, a run's start or end; a writer killed mid-transaction leaves nothing of it."""

import datetime
import json
import socket

import sqlalchemy as sa

from . import _schema as s
from ._code_version import code_version
from ._migrations import MIGRATIONS, check_version, latest_version, migrate
from ._rows import fit_row, judgement_row, verdict_rows
from ._url import StoreError, database_url, make_engine, safe, sqlite_file


def _now() -> str:
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")


class FleetStore:
    """The fleet database at one URL (open it with `open_store`)."""

    def __init__(self, engine: sa.Engine, where: str):
        self.engine = engine
        self.where = where

    # --- runs ------------------------------------------------------------------------------

    def start_run(self, command: str, engine: str) -> int:
        """A new `runs` row; returns its id."""
        row = dict(started_at=_now(), code_version=code_version(), command=command,
                   engine=engine, host=socket.gethostname(), judged=0, failed=0)  # fmt: skip
        with self.engine.begin() as c:
            return int(c.execute(sa.insert(s.runs).values(**row)).inserted_primary_key[0])

    def finish_run(self, run_id: int, *, judged: int, failed: int) -> None:
        with self.engine.begin() as c:
            c.execute(
                sa.update(s.runs)
                .where(s.runs.c.id == run_id)
                .values(finished_at=_now(), judged=judged, failed=failed)
            )

    def runs(self) -> list[dict]:
        with self.engine.connect() as c:
            return [dict(r._mapping) for r in c.execute(sa.select(s.runs).order_by(s.runs.c.id))]

    # --- judgements ------------------------------------------------------------------------

    def judged(self) -> set[tuple[str, str]]:
        """`(bogie_id, date)` of every stored judgement."""
        q = sa.select(s.judgements.c.bogie_id, s.judgements.c.date)
        with self.engine.connect() as c:
            return {(b, d) for b, d in c.execute(q)}

    def write_judgement(self, record: dict, *, bogie_id: str, date: str, vehicle: str,
                        layout: str, run_id: int | None, wall_s: float | None = None,
                        version: str | None = None) -> int:  # fmt: skip
        """Store one judgement (its `verdicts.json` `record`), its verdicts and its fit in one
        transaction; returns its id. **Raises:** `sqlalchemy.exc.IntegrityError` when the bogie
        and date are already stored (nothing of this one is written)."""
        row = judgement_row(record)
        row.update(bogie_id=bogie_id, date=date, vehicle=vehicle, layout=layout,
                   run_id=run_id, wall_s=wall_s, created_at=_now(),
                   code_version=version or code_version())  # fmt: skip
        with self.engine.begin() as c:
            jid = int(c.execute(sa.insert(s.judgements).values(**row)).inserted_primary_key[0])
            rows = [dict(v, judgement_id=jid) for v in verdict_rows(record)]
            if rows:
                c.execute(sa.insert(s.verdicts), rows)
            c.execute(sa.insert(s.fits).values(judgement_id=jid, **fit_row(record)))
        return jid

    def write_failure(self, *, bogie_id: str, date: str, error: str, run_id: int | None) -> None:
        row = dict(bogie_id=bogie_id, date=date, error=error, run_id=run_id,
                   created_at=_now(), code_version=code_version())  # fmt: skip
        with self.engine.begin() as c:
            c.execute(sa.insert(s.failures).values(**row))

    # --- reading ---------------------------------------------------------------------------

    def judgements(self, bogie_id: str | None = None) -> list[dict]:
        """Every judgement (a dict of its columns, `record` parsed), by bogie and date."""
        q = sa.select(s.judgements).order_by(s.judgements.c.bogie_id, s.judgements.c.date)
        if bogie_id is not None:
            q = q.where(s.judgements.c.bogie_id == bogie_id)
        with self.engine.connect() as c:
            rows = [dict(r._mapping) for r in c.execute(q)]
        for r in rows:
            r["record"] = json.loads(r["record"])
        return rows

    def verdict_rows(self) -> list[dict]:
        """Every stored verdict row, with its judgement's bogie and date."""
        j, v = s.judgements, s.verdicts
        q = (
            sa.select(v, j.c.bogie_id, j.c.date)
            .join(j, v.c.judgement_id == j.c.id)
            .order_by(j.c.bogie_id, j.c.date, v.c.position)
        )
        with self.engine.connect() as c:
            return [dict(r._mapping) for r in c.execute(q)]

    def failures(self) -> list[dict]:
        q = sa.select(s.failures).order_by(s.failures.c.id)
        with self.engine.connect() as c:
            return [dict(r._mapping) for r in c.execute(q)]

    def counts(self) -> dict[str, int]:
        """Rows per table (what a test accounts for)."""
        tables = (s.runs, s.judgements, s.verdicts, s.fits, s.failures)
        with self.engine.connect() as c:
            return {t.name: int(c.execute(sa.select(sa.func.count()).select_from(t)).scalar())
                    for t in tables}  # fmt: skip

    def migrate(self, steps=MIGRATIONS) -> int:
        """Bring the database to the latest schema (`_migrations.py`); returns the version."""
        return migrate(self.engine, self.where, steps)

    def close(self) -> None:
        """Close every pooled connection."""
        self.engine.dispose()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def open_store(text: str, *, create: bool) -> FleetStore:
    """The fleet database at `text` (a URL or a SQLite file path), checked and not yet written:
    reachable, and of a schema this code knows. `create`: a new or older database is allowed
    (`fleet run` and `fleet import` call `FleetStore.migrate` when they are ready to write; a
    new SQLite file is made only then); otherwise (`trend`, `report`) it must exist at the
    latest schema.

    **Raises:** `StoreError` (one line: unreachable, not a fleet database, a newer schema
    (`SchemaError`), a missing driver) before anything is written."""
    url = database_url(text)
    where = safe(url)
    path = sqlite_file(url)
    if path is not None and not path.is_file():
        if not create:
            raise StoreError(f"no fleet database at {where}: `fleet run` or `import` makes one")
        if not path.parent.is_dir():
            raise StoreError(f"cannot make database {where}: no folder {str(path.parent)!r}")
        return FleetStore(make_engine(url), where)
    engine = make_engine(url)
    try:
        version = _version(engine, where)
    except StoreError:
        engine.dispose()
        raise
    if not create and version != latest_version():
        engine.dispose()
        raise StoreError(
            f"{where} is not a fleet database of schema {latest_version()} (found version "
            f"{version}): `fleet run` or `fleet import` brings it up to date"
        )
    return FleetStore(engine, where)


def _version(engine: sa.Engine, where: str) -> int:
    try:
        with engine.connect() as c:
            return check_version(c, where)
    except sa.exc.DBAPIError as e:
        first = str(e.orig).strip().splitlines()[0] if e.orig else type(e).__name__
        raise StoreError(f"cannot open database {where}: {first}") from None
