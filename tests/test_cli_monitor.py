"""`bogie-jax demo` and `bogie-jax monitor` (issue 19 items 5 and 7 at the command line):
`--history` trends of synthetic results, and bad input (one-line errors, exit code 2, before
anything is compiled). Everything here reads and writes small files and compiles nothing; the
choices of what is fitted are in tests/test_cli_monitor_choices.py.

The demo end to end, its `verdicts.json` schema, its report and `monitor --data` replaying it
are in tests/test_monitor.py: its runs have that module's run shapes, so in one process the
demo reuses the simulation and residual-Jacobian programs the module's `monitor` tests compile.
"""

import json
import math

import numpy as np
import pytest

from bogie_jax.cli import main
from bogie_jax.io import read_verdicts, write_report, write_verdicts
from bogie_jax.monitor import ToleranceBand, decision_z, judge, same_measure


try:
    from cli_files import blank_file, exit_code
except ImportError:  # tests/ imported as a package
    from tests.cli_files import blank_file, exit_code


ALARMS = ("degraded", "failed")


# --- --history -------------------------------------------------------------------------------

NAMES = ("yaw_dampers.left.c", "primary.1L.kz")
UNITS = {"yaw_dampers.left.c": "N s/m", "primary.1L.kz": "N/m"}
NOMINAL = {"yaw_dampers.left.c": 400e3, "primary.1L.kz": 1.22e6}


def _record(estimates, std_errors, *, bands=None):
    """A `verdicts.json` body of two elements judged by the library's `judge`."""
    z = decision_z(0.05, len(NAMES))
    rows = []
    for name in NAMES:
        band = (bands or {}).get(name) or ToleranceBand.relative(
            NOMINAL[name], 0.2, unit=UNITS[name]
        )
        rows.append(judge(name, estimates[name], std_errors[name], band, z=z).to_dict())
    return {
        "verdicts": rows,
        "elements": [{"name": n} for n in NAMES],
        "false_alarm_rate": 0.05,
    }


DATES = ("2026-01-05", "2026-02-05", "2026-03-08")
DRIFTING = (400e3, 370e3, 341e3)  # the left damper loses about 1 kN s/m a day
STEADY = (1.220e6, 1.224e6, 1.218e6)  # primary.1L.kz scatters by less than its error


def _history(tmp_path, dates=DATES, *, drifting=DRIFTING, steady=STEADY):
    dirs = []
    for k, date in enumerate(dates):
        d = tmp_path / f"run{k}"
        write_verdicts(
            d,
            _record(
                {"yaw_dampers.left.c": drifting[k], "primary.1L.kz": steady[k]},
                {"yaw_dampers.left.c": 4e3, "primary.1L.kz": 5e3},
            ),
            date=date,
        )
        dirs.append(str(d))
    return dirs


def test_history_gives_trends_with_a_drift_flag(tmp_path, capsys):
    dirs = _history(tmp_path)
    out = tmp_path / "trend"
    assert main(["monitor", "--history", *dirs, "--out", str(out)]) == 0
    record = json.loads((out / "trends.json").read_text())
    trends = {t["name"]: t for t in record["trends"]}
    assert set(trends) == set(NAMES)
    left, kz = trends["yaw_dampers.left.c"], trends["primary.1L.kz"]
    # oracle: with equal standard errors the weighted slope is the ordinary least-squares slope
    days = np.array([0.0, 31.0, 62.0])
    slope, intercept = np.polyfit(days, DRIFTING, 1)
    assert left["slope_per_day"] == pytest.approx(slope, rel=1e-9)
    level = intercept + slope * days[-1]  # the line at the last run
    assert left["level"] == pytest.approx(level, rel=1e-9)
    # the line leaves the healthy band [320, 480] kN s/m at its lower edge
    assert left["days_to_band_edge"] == pytest.approx((320e3 - level) / slope, rel=1e-9)
    assert left["times_days"] == pytest.approx(days)
    assert left["drift"] is True and left["unit"] == "N s/m"
    assert kz["drift"] is False
    assert left["dates"][0].startswith("2026-01-05")
    assert (out / "trends.png").stat().st_size > 5000
    report = (out / "trends.md").read_text()
    assert "](trends.png)" in report and "**drift**" in report
    text = capsys.readouterr().out
    assert "DRIFT" in text and "yaw_dampers.left.c" in text


@pytest.mark.parametrize(
    "dates, message",
    [
        (("2026-02-05", "2026-01-05", "2026-03-08"), "unsorted date"),
        (("2026-01-05", "2026-01-05", "2026-03-08"), "duplicate date"),
        (("2026-01-05",), "at least two"),
    ],
)
def test_history_refuses_bad_dates(tmp_path, capsys, dates, message):
    dirs = _history(tmp_path, dates)
    assert exit_code(["monitor", "--history", *dirs, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "o").exists()


def test_history_refuses_mixed_layouts_and_bad_files(tmp_path, capsys):
    dirs = _history(tmp_path)
    other = json.loads((tmp_path / "run2" / "verdicts.json").read_text())
    other["elements"] = [{"name": "secondary.left.cy"}]
    (tmp_path / "run2" / "verdicts.json").write_text(json.dumps(other))
    assert exit_code(["monitor", "--history", *dirs]) == 2
    assert "mixed layouts" in capsys.readouterr().err
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "something else"}')
    assert exit_code(["monitor", "--history", dirs[0], str(bad)]) == 2
    assert "is not 'bogie_jax.verdicts/1'" in capsys.readouterr().err
    assert exit_code(["monitor", "--history", str(tmp_path / "nowhere")]) == 2
    assert "no such verdicts file" in capsys.readouterr().err


def test_history_refuses_a_zero_width_band(tmp_path, capsys):
    dirs = _history(tmp_path)
    record = json.loads((tmp_path / "run2" / "verdicts.json").read_text())
    record["verdicts"][0]["tolerance_band"]["healthy"] = [4e5, 4e5]
    (tmp_path / "run2" / "verdicts.json").write_text(json.dumps(record))
    assert exit_code(["monitor", "--history", *dirs]) == 2
    assert "zero width" in capsys.readouterr().err


def test_history_trends_a_group_only_where_it_weighs_its_members_alike(tmp_path, capsys):
    """A group's estimate measures its members' weighted mean (`member_weights`): the trend
    leaves out the results that weighed them otherwise than the latest one, and says so."""
    dates = ("2026-01-05", "2026-02-05", "2026-03-08", "2026-04-08")
    values = (30e3, 29e3, 27.5e3, 26.6e3)  # N s/m
    weights = ((0.2, 0.8), (0.5, 0.5), (0.53, 0.47), (0.5, 0.5))  # left, right
    band = ToleranceBand.relative(32e3, 0.2, unit="N s/m")
    dirs = []
    for k, date in enumerate(dates):
        body = _record(dict(zip(NAMES, (400e3, 1.22e6))), dict.fromkeys(NAMES, 5e3))
        row = judge("secondary.cy", values[k], 400.0, band, z=decision_z(0.05, 3)).to_dict()
        row["evidence"]["member_weights"] = {
            f"secondary.{side}.cy": w for side, w in zip(("left", "right"), weights[k])
        }
        body["verdicts"].append(row)
        write_verdicts(tmp_path / f"run{k}", body, date=date)
        dirs.append(str(tmp_path / f"run{k}"))
    out = tmp_path / "trend"
    assert main(["monitor", "--history", *dirs, "--out", str(out)]) == 0
    trends = {t["name"]: t for t in json.loads((out / "trends.json").read_text())["trends"]}
    cy = trends["secondary.cy"]
    # oracle: equal standard errors, so the ordinary least-squares slope of the last three
    days = np.array([31.0, 62.0, 93.0])
    assert cy["slope_per_day"] == pytest.approx(np.polyfit(days, values[1:], 1)[0], rel=1e-9)
    assert len(cy["dates"]) == 3 and cy["left_out"] == ["2026-01-05"]
    assert trends["yaw_dampers.left.c"]["left_out"] == []
    assert len(trends["primary.1L.kz"]["dates"]) == 4
    note = "secondary.cy: left out 2026-01-05"
    assert note in capsys.readouterr().out and note in (out / "trends.md").read_text()


def test_same_measure_compares_members_and_their_weights():
    half = {"a": 0.5, "b": 0.5}
    assert same_measure(half, {"a": 0.54, "b": 0.46}) and same_measure(None, None)
    assert not same_measure(half, {"a": 0.56, "b": 0.44})
    assert not same_measure(half, {"a": 0.5, "c": 0.5}) and not same_measure(half, None)


# --- bad input at the command line -------------------------------------------------------------


@pytest.mark.parametrize(
    "argv, message",
    [
        (["monitor"], "give --data FILE..."),
        (["monitor", "--history"], "`--history` needs DIR... or `--db URL --bogie ID`"),
        (["monitor", "--history", "x", "--bogie", "b"], "`--bogie` needs `--db URL`"),
        (["monitor", "--history", "x", "--db", "f.db", "--bogie", "b"], "not both"),
        (["monitor", "--history", "--db", "f.db"], "needs `--bogie ID`"),
        (["monitor", "--db", "f.db", "--bogie", "b"], "go with `--history`"),
        (["monitor", "--data"], "expected at least one argument"),
        (["monitor", "--data", "missing.csv"], "file 'missing.csv' does not exist"),
        (["monitor", "--data", "a.csv", "--history", "b"], "not allowed with argument"),
        (["monitor", "--history", "x", "--false-alarm-rate", "0.7"], "must lie in (0, 0.5)"),
        (["monitor", "--history", "x", "--track-error", "-1"], "`--track-error` = -1.0 mm"),
        (["demo", "--speeds", ""], "`--speeds` is empty"),
        (["demo", "--speeds", "30,fast"], "comma-separated numbers"),
        (["demo", "--speeds", "30,500"], "speed"),
        (["demo", "--date", "2026-13-01"], "is not a date YYYY-MM-DD"),
        (["demo", "--scenario", "squeaky"], "unknown `--scenario` 'squeaky'"),
        (["demo", "--track-noise", "-1"], "`--track-noise`"),
        (["demo", "--duration", "0"], "duration"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(argv, message, capsys):
    assert exit_code(argv) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1, err


def test_monitor_data_refuses_bad_input_before_fitting(tmp_path, capsys):
    a = blank_file(tmp_path / "a.csv")
    b = blank_file(tmp_path / "b.npz", speed=50.0)
    frame = blank_file(tmp_path / "frame.csv", channels=["frame_1L_y", "frame_1L_z"])
    cases = [
        (["--data", a, frame], "mix sensor layouts"),
        (["--data", a, b, "--band", "0"], "band"),
        (["--data", a, b, "--track", "t1.csv", "t2.csv", "t3.csv"], "does not exist"),
        (["--data", a, b, "--date", "03/04/2026"], "`--date` = '03/04/2026' is not a date"),
        (["--data", a, b, "--vehicle", "tgv"], "unknown `--vehicle` 'tgv'"),
    ]
    for argv, message in cases:
        assert exit_code(["monitor", *argv, "--out", str(tmp_path / "o")]) == 2, argv
        err = capsys.readouterr().err.strip()
        assert message in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "o").exists()


def test_verdicts_reader_rejects_what_it_cannot_use(tmp_path):
    path = write_verdicts(
        tmp_path,
        _record(dict(zip(NAMES, (2e5, 1.2e6))), dict.fromkeys(NAMES, 1e3)),
        date="2026-01-01",
    )
    record = read_verdicts(path)
    assert [r["name"] for r in record["verdicts"]] == list(NAMES)
    assert record["verdicts"][0]["verdict"] in ALARMS  # 200 kN s/m +- 1 kN s/m: far below 320
    body = json.loads(path.read_text())
    for change, message in [
        ({"date": "yesterday"}, "not a date"),
        ({"verdicts": []}, "non-empty list"),
        ({"verdicts": [{"name": "x"}]}, "lacks verdict, estimate"),
    ]:
        path.write_text(json.dumps({**body, **change}))
        with pytest.raises(ValueError, match=message):
            read_verdicts(path)
    path.write_text("{not json")
    with pytest.raises(ValueError, match="not a JSON file"):
        read_verdicts(tmp_path)
    assert math.isfinite(body["verdicts"][0]["std_error"])


def test_report_marks_an_element_on_watch(tmp_path):
    """95 % interval 481-529 kN s/m above the band's 480, Wald at the edge 2.1 < z = 2.24:
    healthy, on watch; the report says so in its summary, its table and a note."""
    body = _record(dict(zip(NAMES, (505e3, 1.22e6))), dict(zip(NAMES, (12e3, 5e3))))
    record = read_verdicts(write_verdicts(tmp_path, body, date="2026-01-01"))
    assert [r["evidence"].get("watch") for r in record["verdicts"]] == ["above", None]
    text = write_report(tmp_path / "report.md", record).read_text()
    assert "Watch: `yaw_dampers.left.c` (95 % interval above its band)" in text
    assert "| `yaw_dampers.left.c` | healthy\\* |" in text
    assert "\\* watch: the 95 % interval lies outside the healthy band" in text
