"""The fleet page (`bogie-jax fleet report`, issue 50 item 4): one static HTML file, checked in
a real headless browser (Debian's `chromium`): it loads from disk with no console message and
lists the alarms; alarms and watches come first, "data not explained" next, then the bogies.

The default tests build the database from records made directly with the library's verdict rule
(the point is the page, not the fit). The heavy test runs a six-bogie synthetic fleet for real
on a local Dask cluster of two workers (three healthy bogies and three with one known defect
each) and checks the page lists exactly the defective bogies' alarms. `chromium`: `.ci/run`
installs it; without it these tests fail under CI (`CI=true`) and are skipped elsewhere.
"""

import os
import re
import shutil
import subprocess

import pytest

from bogie_jax.cli import main
from bogie_jax.fleet import open_store, write_fleet_page
from bogie_jax.io import verdicts_record
from bogie_jax.monitor import ToleranceBand, decision_z, judge


NOMINAL = {
    "yaw_dampers.left.c": (400e3, "N s/m"),
    "yaw_dampers.right.c": (400e3, "N s/m"),
    "secondary.cy": (32e3, "N s/m"),
}


def _record(date, factors=None, *, se=0.02, explains=True, left_out=False):
    factors = factors or {}
    z = decision_z(0.05, len(NOMINAL))
    rows = []
    for name, (nominal, unit) in NOMINAL.items():
        band = ToleranceBand.relative(nominal, 0.2, unit=unit)
        value = factors.get(name, 1.0) * nominal
        rows.append(judge(name, value, se * nominal, band, z=z).to_dict())
    runs = [
        {"index": 0, "used": True, "reason": ""},
        {"index": 1, "used": not left_out, "reason": "not explained" if left_out else ""},
    ]
    body = {"verdicts": rows, "elements": [], "runs": runs, "false_alarm_rate": 0.05,
            "fit": {"status": "converged", "misfit_ratio": 1.0 if explains else 7.5,
                    "explains_data": explains}, "timings": {}}  # fmt: skip
    return verdicts_record(body, date=date, source="test")


FLEET = {  # bogie -> records by date
    "healthy-1": [_record("2026-10-01"), _record("2026-11-01")],
    "healthy-2": [_record("2026-11-01")],
    "worn": [_record("2026-10-01", {"yaw_dampers.left.c": 0.9}),
             _record("2026-10-15", {"yaw_dampers.left.c": 0.7}),
             _record("2026-11-01", {"yaw_dampers.left.c": 0.5})],
    "lost-damper": [_record("2026-11-01", {"secondary.cy": 0.1})],
    "edge": [_record("2026-11-01", {"yaw_dampers.right.c": 1.22}, se=0.01)],  # a watch
    "odd-data": [_record("2026-11-01", explains=False, left_out=True)],
}  # fmt: skip
ALARMS = {("worn", "yaw_dampers.left.c"): "degraded", ("lost-damper", "secondary.cy"): "failed"}


def _database(tmp_path):
    db = str(tmp_path / "fleet.db")
    with open_store(db, create=True) as store:
        store.migrate()
        for bogie, records in FLEET.items():
            for r in records:
                store.write_judgement(r, bogie_id=bogie, date=r["date"], vehicle="manchester",
                                      layout="default", run_id=None)  # fmt: skip
        store.write_failure(bogie_id="broken", date="2026-11-01", error="ValueError: bad file",
                            run_id=None)  # fmt: skip
    return db


def chromium():
    exe = shutil.which("chromium")
    if exe is None:
        if os.environ.get("CI") == "true":
            pytest.fail(
                "`chromium` is not installed: .ci/run installs it (apt-get install chromium)"
            )
        pytest.skip("`chromium` is not installed (apt-get install chromium; .ci/run does)")
    return exe


def load(path, tmp_path):
    """`(DOM after the page's scripts ran, console lines)` of the file in headless chromium."""
    profile = tmp_path / f"chromium-profile-{len(list(tmp_path.iterdir()))}"
    proc = subprocess.run(
        [chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
         f"--user-data-dir={profile}", "--enable-logging=stderr", "--v=0",
         "--virtual-time-budget=5000", "--dump-dom", path.resolve().as_uri()],
        capture_output=True, text=True, timeout=180,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    console = [line for line in proc.stderr.splitlines() if ":CONSOLE" in line]
    return proc.stdout, console


def _alarm_rows(dom):
    """`{(bogie, element): verdict}` of the alarms-and-watches table."""
    table = re.search(r'<table class="sortable" id="alarms">(.*?)</table>', dom, re.S).group(1)
    out = {}
    for row in re.findall(r"<tr>(.*?)</tr>", table.split("<tbody>")[1], re.S):
        cells = [
            re.sub(r"<[^>]+>", "", c).strip() for c in re.findall(r"<td[^>]*>(.*?)</td>", row, re.S)
        ]
        if len(cells) > 3:
            out[(cells[0], cells[2])] = cells[3]
    return out


def test_the_page_orders_alarms_then_unexplained_data_then_bogies(tmp_path):
    db = _database(tmp_path)
    assert main(["fleet", "report", "--db", db, "--out", str(tmp_path / "report")]) == 0
    html = (tmp_path / "report" / "index.html").read_text()
    order = [
        html.index(h) for h in ('id="alarms-and-watches"', 'id="data-not-explained"', 'id="fleet"')
    ]
    assert order == sorted(order)
    rows = _alarm_rows(html)
    assert rows == {**ALARMS, ("edge", "yaw_dampers.right.c"): "watch"}
    assert list(rows)[0] == ("lost-damper", "secondary.cy")  # failed before degraded
    unexplained = html[order[1] : order[2]]
    assert "odd-data" in unexplained and "run 1 left out (not explained)" in unexplained
    assert "broken" in unexplained and "ValueError: bad file" in unexplained
    sections = re.findall(r'<section class="bogie" id="bogie-([^"]+)"', html)
    assert sections[:2] == ["lost-damper", "worn"] and set(sections) == set(FLEET)
    worn = html[html.index('id="bogie-worn"') :]
    worn = worn[: worn.index("</section>")]
    assert worn.count('class="chart trend"') == 3  # every element over its three judgements
    assert "DRIFT" in worn
    assert "http://" not in html.replace(
        'xmlns="http://www.w3.org/2000/svg"', ""
    )  # nothing fetched


def test_the_page_loads_in_headless_chromium_without_a_console_message(tmp_path):
    db = _database(tmp_path)
    with open_store(db, create=False) as store:
        page = write_fleet_page(store, tmp_path / "report")
    dom, console = load(page, tmp_path)
    assert console == []
    assert '<body data-ready="yes">' in dom  # the page's script ran to its end
    assert _alarm_rows(dom) == {**ALARMS, ("edge", "yaw_dampers.right.c"): "watch"}


def test_the_browser_check_sees_a_console_error(tmp_path):
    """The check above can fail: a page with a script error is caught."""
    bad = tmp_path / "bad.html"
    bad.write_text('<!DOCTYPE html><html><body><script>console.error("x"); nope();</script>'
                   "</body></html>")  # fmt: skip
    _, console = load(bad, tmp_path)
    assert len(console) == 2 and "Uncaught ReferenceError" in console[1]


SIX = (
    ("healthy-1", "healthy", ("2026-10-01", "2026-11-01")),
    ("healthy-2", "healthy", ("2026-11-01",)),
    ("healthy-3", "healthy", ("2026-11-01",)),
    ("yaw-lost", "yaw-damper-left-0", ("2026-11-01",)),
    ("yaw-half", "yaw-damper-left-50", ("2026-11-01",)),
    ("lateral-lost", "secondary-lateral-damper-left-failed", ("2026-11-01",)),
)
DEFECTS = {  # one known defect per defective bogie: the element (or group) that must alarm
    ("yaw-lost", "yaw_dampers.left.c"),
    ("yaw-half", "yaw_dampers.left.c"),
    ("lateral-lost", "secondary.cy"),  # the left and right lateral dampers, judged as a group
}


@pytest.mark.heavy
def test_a_six_bogie_fleet_on_two_dask_workers_and_its_page_in_chromium(tmp_path, capsys):
    """Six synthetic bogies (two half-second runs each, four candidates), judged on a local
    Dask cluster of two workers; the page in headless chromium lists exactly the alarms of the
    three defective bogies. Two workers each compile the monitor programs once."""
    from bogie_jax.fleet import SyntheticBogie, write_synthetic_fleet

    chromium()  # before the minutes of fitting
    bogies = [SyntheticBogie(i, s, d) for i, s, d in SIX]
    candidates = ("yaw_dampers.left.c", "yaw_dampers.right.c", "secondary.left.cy",
                  "secondary.right.cy")  # fmt: skip
    inv = write_synthetic_fleet(tmp_path / "fleet", bogies, candidates=candidates)
    db = str(tmp_path / "fleet.db")
    assert main(["fleet", "run", "--inventory", str(inv), "--db", db, "--workers", "2"]) == 0
    out = capsys.readouterr().out
    assert "local dask cluster of 2 worker processes" in out and "bogie-dates 7/7 done" in out
    assert main(["fleet", "report", "--db", db, "--out", str(tmp_path / "report")]) == 0
    dom, console = load(tmp_path / "report" / "index.html", tmp_path)
    assert console == []
    assert '<body data-ready="yes">' in dom
    alarms = {k for k, v in _alarm_rows(dom).items() if v in ("failed", "degraded")}
    assert alarms == DEFECTS
    with open_store(db, create=False) as store:
        assert store.counts()["judgements"] == 7 and store.failures() == []
