"""The detection benchmark's paired comparison: the same cases judged by two versions of
`monitor` (this run's records against an earlier run's, `detection.py --paired-with`).

A case is the same case when its drawn inputs (`record["case"]`: scenario, speeds, seeds,
noise, offsets, errors; those both records have) are equal, whatever the commit, so each
difference below is the code's.
Per case: the verdict of every element (the same or not, and which changed), and each
element's estimate moved, in the earlier run's standard errors of it; and the time per case.
"""

import json
import subprocess
from pathlib import Path

import numpy as np


def committed_records(commit: str, folder: Path, out: str) -> dict[int, dict]:
    """The records of `<out>.jsonl` and `<out>.shard*.jsonl` in `folder` as committed at
    `commit` (git), by case index; `SystemExit` naming the commit where it has none."""
    root = Path(__file__).resolve().parents[1]
    where = folder.resolve().relative_to(root).as_posix()
    git = lambda *a: subprocess.run(
        ["git", *a], cwd=root, capture_output=True, text=True, check=True
    ).stdout  # fmt: skip
    try:
        names = git("ls-tree", "--name-only", commit, f"{where}/").split()
    except subprocess.CalledProcessError as e:
        raise SystemExit(f"--paired-with = {commit!r}: {e.stderr.strip()}") from None
    mine = [n for n in names if Path(n).name == f"{out}.jsonl"
            or (Path(n).name.startswith(f"{out}.shard") and n.endswith(".jsonl"))]  # fmt: skip
    if not mine:
        raise SystemExit(f"--paired-with = {commit!r}: no {where}/{out}*.jsonl at that commit")
    records = {}
    for name in sorted(mine):
        for line in git("show", f"{commit}:{name}").splitlines():
            if line.strip():
                rec = json.loads(line)
                records[rec["case"]["index"]] = rec
    return records


def _same_inputs(a: dict, b: dict) -> bool:
    """Equal draws where both records have them (a later version of the benchmark draws more
    per case, for modes the other did not have, without changing the earlier draws)."""
    return all(a[k] == b[k] for k in a.keys() & b.keys())


def _by_name(rec: dict) -> dict[str, dict]:
    return {v["name"]: v for v in rec["verdicts"]}


def _moves(new: dict, old: dict) -> list[float]:
    """|new estimate - old estimate| / old standard error per element judged in both."""
    out, now_by_name = [], _by_name(new)
    for name, was in _by_name(old).items():
        now = now_by_name.get(name)
        se = was.get("std_error")
        if now is None or not se or not np.isfinite(se) or now["estimate"] is None:
            continue
        out.append(abs(now["estimate"] - was["estimate"]) / se)
    return out


def compare(new: dict[int, dict], old: dict[int, dict], old_name: str) -> tuple[dict, list[str]]:
    """(summary, markdown lines) of the cases in both `new` and `old` (by index) whose inputs
    are equal; `old_name` says where the earlier records come from."""
    both = sorted(new.keys() & old.keys())
    shared = [k for k in both if _same_inputs(new[k]["case"], old[k]["case"])]
    differ = [k for k in both if k not in shared]
    changed, moves, ratios = [], [], []
    for k in shared:
        was, now = _by_name(old[k]), _by_name(new[k])
        for name in sorted(was.keys() | now.keys()):
            a = was.get(name, {}).get("verdict")
            b = now.get(name, {}).get("verdict")
            if a != b:
                changed.append((k, name, a, b))
        moves += _moves(new[k], old[k])
        if old[k].get("monitor_s") and new[k].get("monitor_s"):
            ratios.append(new[k]["monitor_s"] / old[k]["monitor_s"])
    moves = np.array(moves)
    same = len(shared) - len({k for k, *_ in changed})
    summary = {
        "paired_with": old_name, "cases": len(shared), "shared": shared, "inputs_differ": differ,
        "same_verdicts": same, "verdict_changes": [list(c) for c in changed],
        "estimate_move_se": {
            "elements": int(moves.size),
            "median": float(np.median(moves)) if moves.size else None,
            "p95": float(np.percentile(moves, 95)) if moves.size else None,
            "max": float(moves.max()) if moves.size else None,
            "above_0.1": int(np.sum(moves > 0.1)),
        },
        "time_ratio_median": float(np.median(ratios)) if ratios else None,
    }  # fmt: skip
    lines = [
        f"## Paired with {old_name}",
        "",
        f"The same {len(shared)} cases (equal drawn inputs"
        + (f"; {len(differ)} with other inputs left out" if differ else "")
        + f"): the same verdict on every element in {same} of {len(shared)}.",
    ]
    if moves.size:
        lines.append(
            f"Estimates moved by a median {np.median(moves):.3f}, a 95th percentile "
            f"{np.percentile(moves, 95):.3f} and at most {moves.max():.3f} of the earlier "
            f"standard errors ({moves.size} element estimates; {int(np.sum(moves > 0.1))} "
            "above 0.1)."
        )
    if ratios:
        lines.append(
            f"Time per case, this run over the earlier: median {np.median(ratios):.2f} (other "
            "machines' loads: a rough figure)."
        )
    if changed:
        lines += ["", "| case | element | earlier | now |", "| ---: | --- | --- | --- |"]
        lines += [f"| {k} | {name} | {a} | {b} |" for k, name, a, b in changed]
    return summary, lines


def side_by_side(now: dict, before: dict, before_name: str) -> list[str]:
    """Markdown lines: issue 51's figures (`detection.aggregate`'s summaries, their "mismatch"
    and "by_element" parts) of this run and of the earlier records of the same cases, one row
    each: how the figures move with what changed between the runs (a record length, the
    code)."""

    def row(name: str, s: dict) -> str:
        m, every = s["mismatch"], s["by_element"].get("all elements (alone)", {})
        cover = list(m["coverage"].values())
        span = f"{100 * min(cover):.0f}-{100 * max(cover):.0f} %" if cover else "-"
        size = f"{100 * m['size_mae']:.1f}" if m["size_mae"] is not None else "-"
        return (
            f"| {name} | {m['cases']} | {every.get('covered', 0)}/{every.get('judged', 0)} | "
            f"{span} | {m['no_healthy_alarm']}/{m['cases']} | "
            f"{m['headline_found']}/{m['headline_cases']} | "
            f"{m['not_explained']}/{m['explained_known']} | {size} |"
        )

    return [
        "",
        f"The same cases in this run and in {before_name}:",
        "",
        "| records | cases | intervals holding the truth (elements alone) | coverage per "
        "element and group | no alarm on a healthy element | 50 % damper found | not explained "
        "| size error [%] |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
        row("this run", now),
        row("earlier", before),
    ]
