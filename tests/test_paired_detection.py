"""`benchmarks/_paired.compare`: the detection benchmark's case-by-case comparison of two runs,
on hand-made records whose differences are known."""

import sys
from pathlib import Path


sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._paired import compare, side_by_side  # noqa: E402


def _record(index, verdicts, extra_inputs=None, seconds=100.0):
    case = {"index": index, "speeds": [40.0 + index, 50.0], **(extra_inputs or {})}
    return {
        "case": case,
        "monitor_s": seconds,
        "verdicts": [
            {"name": n, "verdict": v, "estimate": e, "std_error": s} for n, v, e, s in verdicts
        ],
    }


def test_verdict_changes_estimate_moves_and_other_inputs_are_told_apart():
    old = {
        0: _record(0, [("a", "healthy", 100.0, 10.0), ("b", "degraded", 50.0, 5.0)]),
        1: _record(1, [("a", "healthy", 100.0, 10.0)]),
        2: _record(2, [("a", "healthy", 100.0, 10.0)]),
    }
    new = {
        # a later benchmark draws more per case: an extra input keeps the case the same
        0: _record(
            0,
            [("a", "healthy", 101.0, 9.0), ("b", "failed", 50.0, 5.0)],
            {"white_rms_m": 1e-4},
            seconds=50.0,
        ),
        1: _record(1, [("a", "healthy", 103.0, 10.0)], seconds=50.0),
        2: {**_record(2, [("a", "healthy", 100.0, 10.0)]), "case": {"index": 2, "speeds": [0.0]}},
        3: _record(3, [("a", "healthy", 100.0, 10.0)]),
    }
    summary, lines = compare(new, old, "test")
    assert summary["cases"] == 2 and summary["inputs_differ"] == [2]
    assert summary["same_verdicts"] == 1
    assert summary["verdict_changes"] == [[0, "b", "degraded", "failed"]]
    moves = summary["estimate_move_se"]  # 0.1 (a, case 0), 0 (b), 0.3 (a, case 1)
    assert moves["elements"] == 3 and moves["above_0.1"] == 1
    assert abs(moves["max"] - 0.3) < 1e-12 and abs(moves["median"] - 0.1) < 1e-12
    assert summary["time_ratio_median"] == 0.5
    assert "| 0 | b | degraded | failed |" in lines


def test_side_by_side_puts_both_runs_figures_in_one_table():
    def summary(covered, alarms_free, found, unexplained, size):
        return {
            "mismatch": {
                "cases": 20, "no_healthy_alarm": alarms_free, "headline_found": found,
                "headline_cases": 4, "not_explained": unexplained, "explained_known": 20,
                "size_mae": size, "coverage": {"a": 0.85, "b": 1.0},
            },
            "by_element": {"all elements (alone)": {"covered": covered, "judged": 200}},
        }  # fmt: skip

    lines = side_by_side(summary(190, 20, 4, 12, 0.021), summary(172, 19, 2, 9, None), "2 s")
    assert "| this run | 20 | 190/200 | 85-100 % | 20/20 | 4/4 | 12/20 | 2.1 |" in lines
    assert "| earlier | 20 | 172/200 | 85-100 % | 19/20 | 2/4 | 9/20 | - |" in lines
    assert any("in 2 s:" in line for line in lines)
