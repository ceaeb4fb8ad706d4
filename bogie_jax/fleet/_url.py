"""Database URLs: a plain path is a SQLite file, `postgresql://` a PostgreSQL server (through
psycopg 3); the SQLAlchemy engine of each with what concurrent writers need."""

from pathlib import Path

import sqlalchemy as sa


class StoreError(ValueError):
    """A database that cannot be used (one line, password hidden)."""


SCHEMES = ("sqlite", "postgresql")
SQLITE_TIMEOUT_S = 120.0  # a writer waits this long for another's transaction
CONNECT_TIMEOUT_S = 5  # a PostgreSQL server that does not answer in this time is unreachable


def database_url(text: str) -> sa.URL:
    """`text` (a URL or a SQLite file path) as a SQLAlchemy URL with its driver.
    **Raises:** `StoreError` for another scheme or a malformed URL."""
    if "://" not in text:
        return sa.make_url("sqlite:///" + str(Path(text).expanduser().resolve()))
    try:
        url = sa.make_url(text)
    except sa.exc.ArgumentError:
        raise StoreError(f"`--db` = {text!r} is not a database URL or a file path") from None
    backend = url.get_backend_name()
    if backend == "postgres":
        backend = "postgresql"
    if backend not in SCHEMES:
        raise StoreError(
            f"`--db` scheme {backend!r} is not supported; use a SQLite path, sqlite:///PATH or "
            "postgresql://USER@HOST:PORT/DB"
        )
    if backend == "postgresql":
        url = url.set(drivername="postgresql+psycopg")
    return url


def safe(url: sa.URL) -> str:
    """The URL as text without its password."""
    return url.render_as_string(hide_password=True)


def sqlite_file(url: sa.URL) -> Path | None:
    """The file of a SQLite URL (None for another backend or an in-memory database)."""
    if url.get_backend_name() != "sqlite" or not url.database or url.database == ":memory:":
        return None
    return Path(url.database)


def make_engine(url: sa.URL) -> sa.Engine:
    """The engine of `url`: SQLite with a busy timeout, foreign keys and `BEGIN IMMEDIATE`
    transactions (a writer takes the write lock when it begins, so two writers queue instead of
    failing on a lock upgrade); PostgreSQL with a connect timeout.
    **Raises:** `StoreError` when the driver is not installed."""
    try:
        if url.get_backend_name() == "sqlite":
            return _sqlite_engine(url)
        return sa.create_engine(
            url, connect_args={"connect_timeout": CONNECT_TIMEOUT_S}, pool_pre_ping=True
        )
    except ModuleNotFoundError as e:
        raise StoreError(
            f'the database driver {e.name!r} is not installed: pip install "bogie-jax[fleet]"'
        ) from None


def _sqlite_engine(url: sa.URL) -> sa.Engine:
    engine = sa.create_engine(url, connect_args={"timeout": SQLITE_TIMEOUT_S})

    @sa.event.listens_for(engine, "connect")
    def _connect(dbapi_connection, _record):
        dbapi_connection.isolation_level = None  # transactions begin below, not in pysqlite
        dbapi_connection.execute("PRAGMA foreign_keys = ON")

    @sa.event.listens_for(engine, "begin")
    def _begin(connection):
        connection.exec_driver_sql("BEGIN IMMEDIATE")

    return engine
