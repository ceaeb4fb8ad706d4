"""Wall time of `bogie-jax demo` from a fresh process (issue 48, item 2), cold and warm, against
the package at an earlier commit measured in the same run.

**A repeat** runs, one after another, each in a fresh process: this checkout's demo `cold` (an
empty cache directory: every program compiled), then `warm` (the same cache directory again:
programs read from disk), then the same two for the `--baseline` commit (checked out into a
temporary worktree); the two packages alternate, so that a drift of the machine falls on both.
The wall time runs from starting the interpreter to its exit (imports, simulation, compiling,
`monitor`, figures and files). Each run's last lines give the verdicts against the hidden
truth, compared between the two packages.

Run (from the repository root, on an otherwise idle machine):
    python benchmarks/demo_time.py --baseline d256b53 --repeats 3
Writes `results/demo_time/cold_and_warm.json` and `.md`.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
TRUTH = "Against the hidden truth:"


def run_demo(source: Path, cache: Path, out: Path) -> dict:
    """One `bogie-jax demo` in a fresh interpreter with the package from `source`: its wall
    time, process CPU time and the verdicts' line against the truth."""
    env = {**os.environ, "PYTHONPATH": str(source), "BOGIE_JAX_CACHE_DIR": str(cache)}
    cmd = [sys.executable, "-m", "bogie_jax.cli", "demo", "--out", str(out)]
    load = os.getloadavg()[0]
    tic = time.perf_counter()
    done = subprocess.run(cmd, env=env, cwd=source, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - tic
    if done.returncode != 0:
        raise RuntimeError(f"the demo from {source} failed:\n{done.stderr[-3000:]}")
    truth = next((x for x in done.stdout.splitlines() if x.startswith(TRUTH)), "")
    return {"wall_s": wall, "truth": truth, "load_1min": load}


def measure(baseline: str, repeats: int) -> list[dict]:
    sys.path.insert(0, str(ROOT))
    from benchmarks._common import git_worktree

    records = []
    with tempfile.TemporaryDirectory() as tmp, git_worktree(baseline, Path(tmp) / "base") as old:
        for k in range(repeats):
            record = {"repeat": k}
            for label, source in (("now", ROOT), ("baseline", old)):
                cache, out = Path(tmp) / f"cache-{label}-{k}", Path(tmp) / f"out-{label}"
                record[label] = {
                    "cold": run_demo(source, cache, out),
                    "warm": run_demo(source, cache, out),
                }
            records.append(record)
            print(json.dumps(record), flush=True)
    return records


def _median(records, label: str, mode: str) -> float:
    return statistics.median(r[label][mode]["wall_s"] for r in records)


def markdown(records, baseline: str) -> str:
    rows = []
    for label, name in (("now", "this commit"), ("baseline", f"baseline ({baseline})")):
        cold, warm = _median(records, label, "cold"), _median(records, label, "warm")
        rows.append(f"| {name} | {len(records)} | {cold:.1f} | {warm:.1f} | {cold - warm:.1f} |")
    ratios = [r["now"]["cold"]["wall_s"] / r["baseline"]["cold"]["wall_s"] for r in records]
    same = sum(r["now"]["cold"]["truth"] == r["baseline"]["cold"]["truth"] for r in records)
    loads = [r[label][mode]["load_1min"] for r in records for label in ("now", "baseline")
             for mode in ("cold", "warm")]  # fmt: skip
    return "\n".join([
        "# `bogie-jax demo`: wall time from a fresh process, cold and warm",
        "",
        "Medians over the repeats; each run a fresh interpreter, one at a time, the two "
        "packages alternating. Cold: an empty cache directory; warm: the cold run's cache "
        "(compiled programs read from disk). Wall time from starting the interpreter to its exit.",
        "",
        "| package | repeats | cold [s] | warm [s] | cold minus warm [s] |",
        "| --- | ---: | ---: | ---: | ---: |",
        *rows,
        "",
        f"Cold, this commit over the baseline: **{statistics.median(ratios):.2f}x** (median of "
        f"the {len(ratios)} paired repeats' ratios; {min(ratios):.2f}-{max(ratios):.2f}).",
        "",
        f"The verdicts' line against the hidden truth the same as the baseline's in {same} of "
        f"{len(records)} repeats: {records[0]['now']['cold']['truth']}",
        "",
        f"1-minute load average before the runs: {min(loads):.2f}-{max(loads):.2f}.",
    ])  # fmt: skip


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--baseline", default="d256b53", help="git commit of the baseline")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--name", default="cold_and_warm")
    args = p.parse_args(argv)
    if args.repeats < 1:
        raise SystemExit(f"--repeats = {args.repeats} must be >= 1")
    records = measure(args.baseline, args.repeats)
    from benchmarks._common import write_outputs

    extra = {"baseline": args.baseline, "cpu_count": os.cpu_count()}
    write_outputs(f"demo_time/{args.name}", records, markdown(records, args.baseline), extra)


if __name__ == "__main__":
    main()
