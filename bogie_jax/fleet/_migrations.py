"""The schema's versions and the steps between them, in a table of our own (`schema_version`).

Why not alembic: the schema is a handful of tables created by one program; a list of
numbered steps, each a function run in the same transaction as the version update, is all the
migration machinery it needs, and it lets `open_store` refuse a database of a newer schema
before anything is written (alembic would bring its own configuration files and its own
command line for what is one list here).

A database is at version 0 (no `schema_version` table), at one of `MIGRATIONS`' versions, or
newer than this code (`SchemaError`: upgrade bogie-jax). `migrate` applies the missing steps
in one transaction; on PostgreSQL it takes a transaction-level advisory lock first, so two
processes opening a new database do not both create its tables (SQLite's `BEGIN IMMEDIATE`
serialises them already).
"""

import dataclasses
from collections.abc import Callable

import sqlalchemy as sa

from . import _schema
from ._url import StoreError


class SchemaError(StoreError):
    """A database whose schema this code cannot use."""


@dataclasses.dataclass(frozen=True)
class Migration:
    """Step to `version`: `apply(connection)` inside the migration's transaction."""

    version: int
    description: str
    apply: Callable[[sa.Connection], None]


def _create_v1(connection: sa.Connection) -> None:
    tables = [t for t in _schema.metadata.sorted_tables if t.name != "schema_version"]
    _schema.metadata.create_all(connection, tables=tables)


MIGRATIONS: tuple[Migration, ...] = (
    Migration(1, "runs, judgements, verdicts, fits, failures", _create_v1),
)
_LOCK_KEY = 0x0B0A1E  # PostgreSQL advisory lock of the migrations


def latest_version(steps=MIGRATIONS) -> int:
    """The version `steps` (default: this code's migrations) lead to."""
    return steps[-1].version


def current_version(connection: sa.Connection) -> int:
    """The database's schema version (0: no `schema_version` table, a new database)."""
    if not sa.inspect(connection).has_table("schema_version"):
        return 0
    value = connection.execute(sa.select(sa.func.max(_schema.schema_version.c.version))).scalar()
    return int(value or 0)


def check_version(connection: sa.Connection, where: str, steps=MIGRATIONS) -> int:
    """The version, after refusing one newer than `steps` lead to (`SchemaError`)."""
    version = current_version(connection)
    if version > latest_version(steps):
        raise SchemaError(
            f"database {where} has schema version {version}, newer than this bogie-jax's "
            f"{latest_version(steps)}: upgrade bogie-jax (nothing was written)"
        )
    return version


def migrate(engine: sa.Engine, where: str, steps=MIGRATIONS) -> int:
    """Bring the database to `latest_version(steps)` in one transaction; returns the version.
    `steps`: this code's `MIGRATIONS` (a test passes more, to exercise an upgrade)."""
    with engine.begin() as connection:
        if connection.dialect.name == "postgresql":
            connection.execute(sa.text("SELECT pg_advisory_xact_lock(:k)"), {"k": _LOCK_KEY})
        version = check_version(connection, where, steps)
        if version == 0:
            _schema.schema_version.create(connection, checkfirst=True)
            connection.execute(sa.insert(_schema.schema_version).values(version=0))
        for step in steps:
            if step.version > version:
                step.apply(connection)
                connection.execute(sa.update(_schema.schema_version).values(version=step.version))
                version = step.version
        return version
