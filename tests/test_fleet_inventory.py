"""The fleet inventory (`bogie_jax.fleet.read_inventory`, issue 50 items 1 and 5) and the bad
input of `bogie-jax fleet run`: one line, exit code 2, before any fit, nothing written.

Nothing is fitted here: the measurement files are empty placeholders (the inventory checks that
they exist; reading them is the worker's job), and every refused run stops before that."""

import sqlite3

import pytest

from bogie_jax.cli import main
from bogie_jax.contact import measured_wheel, shipped_profile
from bogie_jax.fleet import InventoryError, JudgeTask, open_store, read_inventory


GOOD = """
format = "bogie_jax.fleet/1"

[defaults]
vehicle = "manchester"

[monitor]
false_alarm_rate = 0.05
track_error_mm = 0.3
candidates = ["yaw_dampers.left.c", "secondary.left.cy"]

[[bogie]]
id = "401-A"
layout = "default"

  [[bogie.measurement]]
  date = 2026-11-08
  files = ["data/a2-0.csv", "data/a2-1.csv"]
  tracks = ["tracks/line.csv"]
  wheel_profile = "wheels/a2.prw"

  [[bogie.measurement]]
  date = "2026-11-01"
  files = ["data/a1-0.csv"]

[[bogie]]
id = "401-B"
vehicle = "manchester"

  [[bogie.measurement]]
  date = 2026-11-01
  files = ["data/b1-0.npz"]
"""


S1002 = shipped_profile("MBench_S1002_v3.prw")


def _files(folder):
    for name in ("data/a2-0.csv", "data/a2-1.csv", "data/a1-0.csv", "data/b1-0.npz",
                 "tracks/line.csv"):  # fmt: skip
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("")
    wheels = folder / "wheels"
    wheels.mkdir(exist_ok=True)
    (wheels / "a2.prw").write_bytes(S1002.read_bytes())
    (wheels / "rail.prr").write_bytes(shipped_profile("MBench_UIC60_v3.prr").read_bytes())


def _inventory(tmp_path, text=GOOD, files=True):
    if files:
        _files(tmp_path)
    path = tmp_path / "inventory.toml"
    path.write_text(text)
    return path


def test_an_inventory_reads_into_bogies_and_dated_visits(tmp_path):
    inv = read_inventory(_inventory(tmp_path))
    assert [b.id for b in inv.bogies] == ["401-A", "401-B"]
    a = inv.bogies[0]
    assert (a.vehicle, a.layout) == ("manchester", "default")
    assert [v.date for v in a.visits] == ["2026-11-01", "2026-11-08"]  # sorted by date
    assert a.visits[1].files == (str(tmp_path / "data/a2-0.csv"), str(tmp_path / "data/a2-1.csv"))
    assert a.visits[1].tracks == (str(tmp_path / "tracks/line.csv"),)
    # the wheels measured at the visit: their contact reaches the parameters each task fits
    s1002 = measured_wheel(tmp_path / "wheels/a2.prw", -0.070)
    assert [v.contact for v in a.visits] == ["cone", s1002]
    tasks = [JudgeTask.of(a, v, inv.settings) for v in a.visits]
    assert [t.params().contact_geometry for t in tasks] == ["cone", s1002]
    assert inv.settings.track_error_mm == 0.3
    assert inv.settings.candidates == ("yaw_dampers.left.c", "secondary.left.cy")
    assert len(inv.visits) == 3


BAD = [
    ("a missing file", GOOD.replace("data/b1-0.npz", "data/nope.npz"), "does not exist"),
    ("one id twice", GOOD.replace('"401-B"', '"401-A"'), "bogie id '401-A' appears twice"),
    ("a date that is no date", GOOD.replace("2026-11-08", '"2026-13-45"'), "is not a date"),
    ("a date as a number", GOOD.replace('"2026-11-01"', "20261101"), "is not a date"),
    ("one date twice", GOOD.replace("2026-11-08", "2026-11-01"), "appears twice"),
    ("an unknown vehicle", GOOD.replace('vehicle = "manchester"\n\n  [[', 'vehicle = "x"\n\n  [['),
     "`vehicle` = 'x' must be one of"),
    ("an unknown layout", GOOD.replace('layout = "default"', 'layout = "all"'), "`layout`"),
    ("an unknown element", GOOD.replace('"secondary.left.cy"', '"secondary.left.cq"'),
     "candidates"),
    ("a false-alarm rate", GOOD.replace("= 0.05", "= 0.5"), "`false_alarm_rate` = 0.5"),
    ("tracks that fit no file count",
     GOOD.replace('files = ["data/a1-0.csv"]',
                  'files = ["data/a1-0.csv"]\n  tracks = ["tracks/line.csv", "tracks/line.csv"]'),
     "2 `tracks` for 1 `files`"),
    ("a misspelt key", GOOD.replace("files = [\"data/b1-0.npz\"]", "file = [\"data/b1-0.npz\"]"),
     "unknown key(s) file"),
    ("another format", GOOD.replace("fleet/1", "fleet/9"), "`format`"),
    ("a rail as the wheel", GOOD.replace("wheels/a2.prw", "wheels/rail.prr"),
     "`wheel_profile`: "),
    ("a missing wheel profile", GOOD.replace("wheels/a2.prw", "wheels/no.prw"),
     "`wheel_profile` file 'wheels/no.prw' does not exist"),
    ("a wheel profile on another vehicle",
     GOOD.replace('id = "401-A"', 'id = "401-A"\nvehicle = "crh380a"'),
     "`wheel_profile` needs vehicle = 'manchester'"),
    ("a flange back out of range",
     GOOD.replace('wheel_profile = "wheels/a2.prw"',
                  'wheel_profile = "wheels/a2.prw"\n  flange_back_mm = 700'),
     "`flange_back_mm` = 700 must be a number in [-500, 500)"),
    ("a flange back alone", GOOD.replace('wheel_profile = "wheels/a2.prw"', "flange_back_mm = 0"),
     "`flange_back_mm` goes with `wheel_profile`"),
    ("no bogie", GOOD.split("[[bogie]]")[0], "no `[[bogie]]`"),
    ("not TOML", "format = ", "not a TOML file"),
]  # fmt: skip


@pytest.mark.parametrize("what, text, message", BAD, ids=[b[0] for b in BAD])
def test_bad_inventories_are_refused_naming_the_problem(tmp_path, what, text, message):
    with pytest.raises(InventoryError) as e:
        read_inventory(_inventory(tmp_path, text))
    assert message in str(e.value) and "\n" not in str(e.value)


def _exit_code(argv):
    try:
        return main(argv)
    except SystemExit as e:
        return e.code


@pytest.mark.parametrize("what, text, message", BAD[:4], ids=[b[0] for b in BAD[:4]])
def test_fleet_run_refuses_a_bad_inventory_before_anything(tmp_path, capsys, what, text, message):
    db = tmp_path / "fleet.db"
    code = _exit_code(["fleet", "run", "--inventory", str(_inventory(tmp_path, text)),
                       "--db", str(db), "--engine", "serial"])  # fmt: skip
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("bogie-jax fleet: error:") and message in err[0]
    assert not db.exists()


def test_fleet_run_refuses_a_database_it_cannot_use(tmp_path, capsys):
    inv = str(_inventory(tmp_path))
    newer = tmp_path / "newer.db"
    with open_store(str(newer), create=True) as store:
        store.migrate()
        with store.engine.begin() as c:
            c.exec_driver_sql("UPDATE schema_version SET version = 999")
        before = store.counts()
    cases = [
        (str(newer), "schema version 999"),
        ("postgresql://fleet@127.0.0.1:1/fleet", "cannot open database"),
        (str(tmp_path / "no" / "dir" / "fleet.db"), "no folder"),
    ]
    for db, message in cases:
        assert (
            _exit_code(["fleet", "run", "--inventory", inv, "--db", db, "--engine", "serial"]) == 2
        )
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], err
    with sqlite3.connect(newer) as c:  # as it was: this code refuses to open it
        assert c.execute("SELECT version FROM schema_version").fetchone() == (999,)
        tables = ("runs", "judgements", "verdicts", "fits", "failures")
        counts = {t: c.execute(f"SELECT count(*) FROM {t}").fetchone()[0] for t in tables}
    c.close()
    assert counts == before
    assert not (tmp_path / "no").exists()


def test_the_read_commands_need_an_existing_database(tmp_path, capsys):
    db = tmp_path / "none.db"
    assert _exit_code(["fleet", "report", "--db", str(db), "--out", str(tmp_path / "r")]) == 2
    assert _exit_code(["fleet", "trend", "--db", str(db)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all("no fleet database" in line for line in err)
    assert not db.exists() and not (tmp_path / "r").exists()
