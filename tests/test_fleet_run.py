"""`bogie-jax fleet run` (issue 50 items 1 and 2): resumable runs, a failing bogie-date recorded
with the rest going on, progress lines, a local Dask cluster of two workers (a worker that dies
included), and one real judgement end to end through the command line.

The bookkeeping tests pass `run_fleet` a stand-in for the monitor fit (`stand_in`, below): their
point is the engine and the database, and a real fit costs a minute of compile per process. The
last test is the one real fit of the default suite (a two-run, half-second bogie with a lost
anti-yaw damper, four candidates); the six-bogie fleet on Dask is the heavy test in
tests/test_fleet_page.py.
"""

import os
import pathlib
import subprocess
import sys
import time

import dask
import distributed  # noqa: F401  (its config defaults loaded before `dask.config.set` below)
import pytest

from bogie_jax.cli import main
from bogie_jax.fleet import (
    DaskEngine,
    SerialEngine,
    SyntheticBogie,
    can_pin,
    open_store,
    read_inventory,
    run_fleet,
    write_synthetic_fleet,
)


TESTS = pathlib.Path(__file__).resolve().parent
CANDIDATES = (
    "yaw_dampers.left.c",
    "yaw_dampers.right.c",
    "secondary.left.cy",
    "secondary.right.cy",
)


def stand_in(task):
    """The judgement of a bogie-date without a fit: `broken*` bogies raise, `crash*` bogies end
    their worker process, `slow*` bogies take a second; the record has one healthy element."""
    if task.bogie_id.startswith("broken"):
        raise ValueError("a stand-in failure")
    if task.bogie_id.startswith("crash"):
        os._exit(3)
    if task.bogie_id.startswith("slow"):
        time.sleep(1.0)
    band = {"healthy": [0.8, 1.2], "failed_below": 0.25, "failed_above": None, "unit": ""}
    row = {"name": "x", "verdict": "healthy", "estimate": 1.0, "std_error": 0.01,
           "ci95": [0.98, 1.02], "tolerance_band": band, "unit": "", "evidence": {}}  # fmt: skip
    return {"format": "bogie_jax.verdicts/1", "date": task.date, "source": "stand-in",
            "verdicts": [row], "fit": {"status": "converged", "explains_data": True},
            "runs": [{"index": 0, "used": True}], "pid": os.getpid(),
            "cores": _cores()}  # fmt: skip


def _cores() -> list[int]:
    return sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []


def _inventory(tmp_path, bogies, dates=("2026-11-01",)):
    (tmp_path / "run.csv").write_text("")  # the stand-in reads no file; the inventory checks it
    lines = ['format = "bogie_jax.fleet/1"']
    for b in bogies:
        lines += ["[[bogie]]", f'id = "{b}"']
        for d in dates:
            lines += ["[[bogie.measurement]]", f"date = {d}", 'files = ["run.csv"]']
    path = tmp_path / "inventory.toml"
    path.write_text("\n".join(lines) + "\n")
    return read_inventory(path)


@pytest.fixture
def store(tmp_path):
    with open_store(str(tmp_path / "fleet.db"), create=True) as s:
        s.migrate()
        yield s


class Interrupt(BaseException):
    """Stands in for Ctrl-C in the middle of a run."""


def test_a_run_resumes_where_it_stopped_and_never_redoes_a_judgement(tmp_path, store):
    inv = _inventory(tmp_path, ["a", "b", "c"], ("2026-11-01", "2026-11-08"))
    calls = []

    def interrupted(task):
        if len(calls) == 2:
            raise Interrupt
        calls.append(task.key)
        return stand_in(task)

    with pytest.raises(Interrupt):
        run_fleet(inv, store, SerialEngine(), judge=interrupted, say=lambda line: None)
    assert len(store.judged()) == 2  # what finished before the stop is kept
    assert store.runs()[0]["finished_at"] is not None and store.runs()[0]["judged"] == 2
    calls.clear()
    counted = lambda task: calls.append(task.key) or stand_in(task)
    summary = run_fleet(inv, store, SerialEngine(), judge=counted, say=lambda line: None)
    assert (summary.before, summary.judged, summary.failed) == (2, 4, 0)
    assert len(calls) == 4 and not set(calls) & {("a", "2026-11-01"), ("a", "2026-11-08")}
    calls.clear()
    assert run_fleet(inv, store, SerialEngine(), judge=counted, say=lambda line: None).judged == 0
    assert calls == [] and store.counts()["judgements"] == 6


def test_a_failing_bogie_is_recorded_and_the_rest_go_on(tmp_path, store):
    inv = _inventory(tmp_path, ["a", "broken-1", "b"], ("2026-11-01", "2026-11-08"))
    lines = []
    summary = run_fleet(inv, store, SerialEngine(), judge=stand_in, say=lines.append)
    assert (summary.judged, summary.failed) == (4, 2)
    failures = store.failures()
    assert {(f["bogie_id"], f["date"]) for f in failures} == {
        ("broken-1", "2026-11-01"), ("broken-1", "2026-11-08"),
    }  # fmt: skip
    assert all(f["error"].startswith("ValueError: a stand-in failure (at ") for f in failures)
    assert any("FAILED: ValueError: a stand-in failure" in line for line in lines)
    assert "bogie-dates 6/6 done, bogies 3/3, 2 failed" in lines[-1]
    assert any("ETA" in line and "per min" in line for line in lines)
    again = run_fleet(inv, store, SerialEngine(), judge=stand_in, say=lambda line: None)
    assert (again.before, again.judged, again.failed) == (4, 0, 2)  # a failure is tried again
    assert len(store.failures()) == 4


def test_a_local_dask_cluster_of_two_workers_judges_and_survives_a_dead_worker(
    tmp_path, store, monkeypatch
):
    monkeypatch.setenv("PYTHONPATH", str(TESTS))  # the workers import this module's stand-in
    inv = _inventory(tmp_path, ["slow-1", "slow-2", "slow-3", "slow-4", "crash-1"])
    lines = []
    one_each = {
        "distributed.scheduler.allowed-failures": 0,
        "distributed.scheduler.worker-saturation": 1.0,
    }
    with dask.config.set(one_each):  # no task queued behind the one that kills its worker
        with DaskEngine(workers=2) as engine:
            assert engine.name == "local dask cluster of 2 worker processes"
            summary = run_fleet(inv, store, engine, judge=stand_in, say=lines.append)
    assert (summary.judged, summary.failed) == (4, 1)
    (failure,) = store.failures()
    assert failure["bogie_id"] == "crash-1" and "KilledWorker" in failure["error"]
    pids = {j["record"]["pid"] for j in store.judgements()}
    # both workers (a worker restarted after the crash has a new pid), neither of them this one
    assert len(pids) >= 2 and os.getpid() not in pids
    if can_pin():  # each worker on its half of this process's cores (`_pinning.py`)
        cores = [j["record"]["cores"] for j in store.judgements()]
        size = max(1, len(_cores()) // 2)
        assert all(len(c) == size and set(c) <= set(_cores()) for c in cores), cores
    assert "bogie-dates 5/5 done" in lines[-1]


@pytest.mark.skipif(not can_pin(), reason="pinning needs Linux's sched_setaffinity")
def test_a_pinned_process_and_every_thread_it_starts_run_on_one_core():
    """`pin_process` (what each local Dask worker runs as it starts) in a fresh process
    (pinning this one would slow the suite): a thread started before it and one after both
    report the one core."""
    code = (
        "import os, threading\n"
        "from bogie_jax.fleet import pin_process\n"
        "seen, go = [], threading.Event()\n"
        "affinity = lambda: seen.append(sorted(os.sched_getaffinity(0)))\n"
        "before = threading.Thread(target=lambda: (go.wait(), affinity()))\n"
        "before.start()\n"
        f"pin_process([{_cores()[-1]}])\n"
        "go.set(); before.join()\n"
        "after = threading.Thread(target=affinity)\n"
        "after.start(); after.join(); affinity()\n"
        "print(seen)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == str([[_cores()[-1]]] * 3)


def test_a_local_cluster_has_one_worker_per_two_cores_by_default():
    """`monitor` keeps two cores busy itself (`CORES_PER_WORKER`)."""
    expected = max(1, len(_cores() or range(os.cpu_count() or 1)) // 2)
    assert DaskEngine().name == f"local dask cluster of {expected} worker processes"
    assert DaskEngine(workers=3).name == "local dask cluster of 3 worker processes"


def test_an_unreachable_scheduler_is_one_line_before_anything(tmp_path, capsys):
    inv = tmp_path / "inventory.toml"
    _inventory(tmp_path, ["a"])
    db = tmp_path / "fleet.db"
    code = main(["fleet", "run", "--inventory", str(inv), "--db", str(db),
                 "--scheduler", "tcp://127.0.0.1:1"])  # fmt: skip
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot reach the dask scheduler" in err[0]
    assert not db.exists()


def test_one_bogie_judged_for_real_through_the_command_line(tmp_path, capsys):
    """The default suite's one real fit: `monitor` through `_judge.py` (the fleet's one call
    of it) in this process (`--engine serial`); the lost left anti-yaw damper is `failed`."""
    inv = write_synthetic_fleet(
        tmp_path, [SyntheticBogie("unit-1", "yaw-damper-left-0")], candidates=CANDIDATES
    )
    db = str(tmp_path / "fleet.db")
    assert main(["fleet", "run", "--inventory", str(inv), "--db", db, "--engine", "serial"]) == 0
    out = capsys.readouterr().out
    assert "1 to judge on serial (this process)" in out and "bogie-dates 1/1 done" in out
    with open_store(db, create=False) as store:
        (j,) = store.judgements()
        rows = {r["name"]: r for r in store.verdict_rows()}
    assert (j["bogie_id"], j["date"], j["layout"]) == ("unit-1", "2026-11-01", "default")
    assert rows["yaw_dampers.left.c"]["verdict"] == "failed"
    assert rows["yaw_dampers.right.c"]["verdict"] == "healthy"
    assert j["record"]["data"][0].endswith("data/unit-1/2026-11-01/run0.npz")
    assert main(["fleet", "run", "--inventory", str(inv), "--db", db, "--engine", "serial"]) == 0
    assert "1 judged before; 0 to judge" in capsys.readouterr().out
