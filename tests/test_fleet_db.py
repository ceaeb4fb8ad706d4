"""The fleet database (`bogie_jax.fleet`, issue 50 item 3) on SQLite and on a real PostgreSQL
server: rows of a judgement, the schema's versions and migrations, several processes writing
at once (every row accounted for), a writer killed mid-transaction (nothing of it stored), and
`fleet import` / `fleet trend` on the command line.

The point here is the storage, so the records are built directly from the library's verdict
rule (`bogie_jax.monitor.judge`, `bogie_jax.io.verdicts_record`): no monitor fit. PostgreSQL:
`.ci/run` starts a server and sets `BOGIE_JAX_TEST_POSTGRES_URL`; without it these tests fail
under CI (`CI=true`) and are skipped elsewhere, with the reason.
"""

import json
import os
import signal
import subprocess
import sys
import time
import uuid

import pytest
import sqlalchemy as sa

from bogie_jax.cli import main
from bogie_jax.fleet import (
    MIGRATIONS,
    Migration,
    SchemaError,
    StoreError,
    current_version,
    latest_version,
    open_store,
)
from bogie_jax.io import verdicts_record, write_verdicts
from bogie_jax.monitor import ToleranceBand, decision_z, judge


PG_ENV = "BOGIE_JAX_TEST_POSTGRES_URL"
NOMINAL = {"yaw_dampers.left.c": (400e3, "N s/m"), "secondary.cy": (32e3, "N s/m")}


def record(date: str, estimates=None, *, explains=True) -> dict:
    """A `verdicts.json` record of two elements judged by `judge` (no fit)."""
    estimates = estimates or {name: nominal for name, (nominal, _) in NOMINAL.items()}
    z = decision_z(0.05, len(NOMINAL))
    rows = []
    for name, (nominal, unit) in NOMINAL.items():
        band = ToleranceBand.relative(nominal, 0.2, unit=unit)
        rows.append(judge(name, estimates[name], 0.02 * nominal, band, z=z).to_dict())
    body = {
        "verdicts": rows,
        "elements": [{"name": n} for n in NOMINAL],
        "fit": {"status": "converged", "steps": 5, "misfit_ratio": 1.0 if explains else 9.0,
                "explains_data": explains},
        "runs": [{"index": 0, "used": True, "reason": ""}],
        "false_alarm_rate": 0.05,
        "timings": {},
    }  # fmt: skip
    return verdicts_record(body, date=date, source="test")


def postgres_admin_url() -> str:
    url = os.environ.get(PG_ENV)
    if not url:
        if os.environ.get("CI") == "true":
            pytest.fail(f"{PG_ENV} is not set: .ci/run starts a PostgreSQL server and sets it")
        pytest.skip(f"{PG_ENV} is not set: no PostgreSQL server to test against (.ci/run has one)")
    return url


@pytest.fixture
def postgres_url():
    """A new, empty PostgreSQL database on the test server (dropped afterwards)."""
    admin = sa.make_url(postgres_admin_url()).set(drivername="postgresql+psycopg")
    name = f"bogie_jax_test_{uuid.uuid4().hex[:12]}"
    engine = sa.create_engine(admin, isolation_level="AUTOCOMMIT")
    with engine.connect() as c:
        c.execute(sa.text(f'CREATE DATABASE "{name}"'))
    yield admin.set(database=name).render_as_string(hide_password=False)
    with engine.connect() as c:
        c.execute(sa.text(f'DROP DATABASE "{name}" WITH (FORCE)'))
    engine.dispose()


@pytest.fixture(params=["sqlite", "postgresql"])
def db_url(request, tmp_path):
    if request.param == "sqlite":
        return str(tmp_path / "fleet.db")
    return request.getfixturevalue("postgres_url")


_OPEN = []


@pytest.fixture(autouse=True)
def _close_stores():
    yield
    while _OPEN:
        _OPEN.pop().close()


def _store(url, *, migrate=True):
    """An open store, closed after the test."""
    store = open_store(url, create=True)
    _OPEN.append(store)
    if migrate:
        store.migrate()
    return store


def _exit_code(argv, capsys=None):
    try:
        return main(argv)
    except SystemExit as e:
        return e.code


# --- rows -------------------------------------------------------------------------------------


def test_a_judgement_is_stored_with_its_verdicts_and_fit(db_url):
    store = _store(db_url)
    run = store.start_run("test", "none")
    failing = record("2026-11-02", {"yaw_dampers.left.c": 4e3, "secondary.cy": 32e3})
    store.write_judgement(failing, bogie_id="b1", date="2026-11-02", vehicle="manchester",
                          layout="default", run_id=run, wall_s=1.5)  # fmt: skip
    store.finish_run(run, judged=1, failed=0)
    assert store.counts() == {"runs": 1, "judgements": 1, "verdicts": 2, "fits": 1, "failures": 0}
    (j,) = store.judgements()
    assert (j["bogie_id"], j["date"], j["n_alarms"], j["explains_data"]) == (
        "b1", "2026-11-02", 1, True,
    )  # fmt: skip
    assert j["record"]["verdicts"][0]["verdict"] == "failed"
    assert j["code_version"].startswith(store.runs()[0]["code_version"][:5])
    rows = {r["name"]: r for r in store.verdict_rows()}
    assert rows["yaw_dampers.left.c"]["verdict"] == "failed"
    assert rows["yaw_dampers.left.c"]["ci_lo"] < 4e3 < rows["yaw_dampers.left.c"]["ci_hi"]
    assert rows["secondary.cy"]["band_lo"] == pytest.approx(0.8 * 32e3)
    assert store.runs()[0]["finished_at"] is not None
    with pytest.raises(sa.exc.IntegrityError):  # one judgement per bogie and date
        store.write_judgement(failing, bogie_id="b1", date="2026-11-02", vehicle="manchester",
                              layout="default", run_id=run)  # fmt: skip
    assert store.counts()["verdicts"] == 2  # the refused one left nothing


# --- schema versions ----------------------------------------------------------------------------


def _set_version(store, version):
    with store.engine.begin() as c:
        c.execute(sa.text("UPDATE schema_version SET version = :v"), {"v": version})


def test_a_new_database_gets_the_latest_schema_and_a_newer_one_is_refused(db_url, capsys):
    store = _store(db_url)
    with store.engine.connect() as c:
        assert current_version(c) == latest_version()
    _set_version(store, latest_version() + 1)
    before = store.counts()
    with pytest.raises(SchemaError, match="newer than this bogie-jax"):
        open_store(db_url, create=True)
    code = _exit_code(["fleet", "report", "--db", db_url, "--out", "unused"])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "schema version" in err[0] and "newer" in err[0]
    assert store.counts() == before


def test_an_older_database_is_migrated_and_keeps_its_rows(db_url):
    """The mechanism, with a second step added for the test: a v1 database with a judgement is
    brought to v2 in one transaction and keeps its rows; this code (v1) then refuses it."""
    store = _store(db_url)
    store.write_judgement(record("2026-11-01"), bogie_id="b1", date="2026-11-01",
                          vehicle="manchester", layout="default", run_id=None)  # fmt: skip

    def add_note(connection):
        connection.execute(sa.text("ALTER TABLE judgements ADD COLUMN note TEXT"))

    steps = (*MIGRATIONS, Migration(2, "a note per judgement", add_note))
    assert store.migrate(steps) == 2
    with store.engine.connect() as c:
        assert current_version(c) == 2
        assert c.execute(sa.text("SELECT bogie_id, note FROM judgements")).all() == [("b1", None)]
    assert store.migrate(steps) == 2  # nothing left to do
    with pytest.raises(SchemaError, match="schema version 2, newer"):
        open_store(db_url, create=True)


def test_a_missing_or_unreachable_database_is_one_line_and_nothing_is_made(tmp_path):
    missing = tmp_path / "none.db"
    with pytest.raises(StoreError, match="no fleet database"):
        open_store(str(missing), create=False)
    assert not missing.exists()
    with pytest.raises(StoreError, match="no folder"):
        open_store(str(tmp_path / "no" / "such" / "fleet.db"), create=True)
    port = _free_port()
    started = time.perf_counter()
    with pytest.raises(StoreError, match="cannot open database") as e:
        open_store(f"postgresql://nobody:secret@127.0.0.1:{port}/fleet", create=True)
    assert "secret" not in str(e.value) and "\n" not in str(e.value)
    assert time.perf_counter() - started < 30
    with pytest.raises(StoreError, match="not supported"):
        open_store("mysql://localhost/fleet", create=True)


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# --- concurrent writers and a crash -------------------------------------------------------------

WRITER = r"""
import json, sys, time
from pathlib import Path
from bogie_jax.fleet import open_store
import sqlalchemy as sa
url, rec_path, k, n, go = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
rec = json.loads(Path(rec_path).read_text())
store = open_store(url, create=True)
while not Path(go).exists():
    time.sleep(0.01)
stored = refused = 0
for i in range(n):
    for bogie in (f"w{k}-b{i}", "shared"):
        try:
            store.write_judgement(rec, bogie_id=bogie, date="2026-11-01", vehicle="manchester",
                                  layout="default", run_id=None)
            stored += 1
        except sa.exc.IntegrityError:
            refused += 1
print(json.dumps({"stored": stored, "refused": refused}))
"""


def test_concurrent_writers_lose_nothing(db_url, tmp_path):
    """Four processes write 12 judgements each of their own at once, and all try the same
    bogie-date 12 times: every row is stored once, the shared one exactly once."""
    store = _store(db_url)
    rec = tmp_path / "record.json"
    rec.write_text(json.dumps(record("2026-11-01")))
    go, writers, n = tmp_path / "go", 4, 12
    procs = [
        subprocess.Popen([sys.executable, "-c", WRITER, db_url, str(rec), str(k), str(n), str(go)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for k in range(writers)
    ]  # fmt: skip
    time.sleep(1.0)
    go.touch()
    results = []
    for p in procs:
        out, err = p.communicate(timeout=300)
        assert p.returncode == 0, err
        results.append(json.loads(out.strip().splitlines()[-1]))
    stored = sum(r["stored"] for r in results)
    assert stored == writers * n + 1
    assert sum(r["refused"] for r in results) == writers * n - 1
    assert store.counts() == {"runs": 0, "judgements": stored, "verdicts": 2 * stored,
                              "fits": stored, "failures": 0}  # fmt: skip
    assert len(store.judged()) == stored


CRASHER = r"""
import json, sys, time
from pathlib import Path
import sqlalchemy as sa
from bogie_jax.fleet import open_store
url, rec_path, marker = sys.argv[1], sys.argv[2], sys.argv[3]
store = open_store(url, create=True)

@sa.event.listens_for(store.engine, "commit")
def _hang(connection):  # inside the transaction, after every insert, before COMMIT
    Path(marker).touch()
    time.sleep(600)

store.write_judgement(json.loads(Path(rec_path).read_text()), bogie_id="crash",
                      date="2026-11-01", vehicle="manchester", layout="default", run_id=None)
"""


def test_a_writer_killed_mid_transaction_leaves_no_half_record(db_url, tmp_path):
    store = _store(db_url)
    rec = tmp_path / "record.json"
    rec.write_text(json.dumps(record("2026-11-01")))
    marker = tmp_path / "inside"
    p = subprocess.Popen([sys.executable, "-c", CRASHER, db_url, str(rec), str(marker)],
                         stderr=subprocess.PIPE, text=True)  # fmt: skip
    deadline = time.time() + 120
    while not marker.exists():
        assert p.poll() is None, p.stderr.read()
        assert time.time() < deadline, "the writer never reached its commit"
        time.sleep(0.05)
    os.kill(p.pid, signal.SIGKILL)
    p.communicate(timeout=30)  # reaped, its pipe closed
    assert store.counts() == {"runs": 0, "judgements": 0, "verdicts": 0, "fits": 0, "failures": 0}
    store.write_judgement(record("2026-11-01"), bogie_id="crash", date="2026-11-01",
                          vehicle="manchester", layout="default", run_id=None)  # fmt: skip
    assert store.counts()["verdicts"] == 2  # the database is usable and the key is free


# --- import and trend on the command line ---------------------------------------------------------

DRIFT = {"2026-10-01": 400e3, "2026-10-15": 360e3, "2026-11-01": 318e3}


def _folders(tmp_path):
    out = []
    for date, value in DRIFT.items():
        folder = tmp_path / f"out-{date}"
        rec = record(date, {"yaw_dampers.left.c": value, "secondary.cy": 32e3})
        body = {k: v for k, v in rec.items() if k not in ("date", "source", "format")}
        write_verdicts(folder, body, date=date)
        out.append(str(folder))
    return out


def test_import_then_trend_from_the_database(tmp_path, capsys):
    db = str(tmp_path / "fleet.db")
    folders = _folders(tmp_path)
    assert _exit_code(["fleet", "import", "--db", db, "--bogie", "unit-7", *folders]) == 0
    assert _exit_code(["fleet", "import", "--db", db, "--bogie", "unit-7", folders[0]]) == 0
    out = capsys.readouterr().out
    assert "imported 3" in out and "skipped 1 already stored" in out
    with open_store(db, create=False) as store:
        judged = store.judgements()
    assert [j["date"] for j in judged] == sorted(DRIFT)
    assert _exit_code(["fleet", "trend", "--db", db, "--out", str(tmp_path / "t")]) == 0
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.startswith("yaw_dampers.left.c"))
    assert "DRIFT" in line
    assert "DRIFT" not in next(x for x in out.splitlines() if x.startswith("secondary.cy"))
    trends = json.loads((tmp_path / "t" / "trends.json").read_text())["trends"]
    assert {t["name"] for t in trends} == set(NOMINAL)


def test_monitor_history_reads_the_same_trends_from_the_database(tmp_path, capsys):
    """`monitor --history --db URL --bogie ID` gives what `monitor --history DIR...` gives for
    the folders imported into that database; an unknown bogie is one line and exit code 2."""
    db = str(tmp_path / "fleet.db")
    folders = _folders(tmp_path)
    assert _exit_code(["fleet", "import", "--db", db, "--bogie", "unit-7", *folders]) == 0
    from_db, from_folders = tmp_path / "from_db", tmp_path / "from_folders"
    argv = ["monitor", "--history", "--db", db, "--bogie", "unit-7", "--out", str(from_db)]
    assert _exit_code(argv) == 0
    assert _exit_code(["monitor", "--history", *folders, "--out", str(from_folders)]) == 0
    read = lambda folder: json.loads((folder / "trends.json").read_text())["trends"]
    trends = [read(from_db), read(from_folders)]
    assert trends[0] == trends[1] and {t["name"] for t in trends[0]} == set(NOMINAL)
    capsys.readouterr()
    assert _exit_code(["monitor", "--history", "--db", db, "--bogie", "unit-8"]) == 2
    assert "'unit-8': no results in" in capsys.readouterr().err


def test_import_refuses_bad_folders_before_writing(tmp_path, capsys):
    db = tmp_path / "fleet.db"
    folders = _folders(tmp_path)
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "verdicts.json").write_text("{not json")
    assert _exit_code(["fleet", "import", "--db", str(db), "--bogie", "u", *folders, str(bad)]) == 2
    assert _exit_code(["fleet", "import", "--db", str(db), folders[0]]) == 2  # no bogie id
    assert _exit_code(["fleet", "import", "--db", str(db), "--bogie", "u", folders[0],
                       folders[0]]) == 2  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 3 and "not a JSON file" in err[0] and "--bogie" in err[1]
    assert not db.exists()
