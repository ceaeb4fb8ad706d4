"""Fleet throughput: bogie-dates judged per minute by `bogie-jax fleet run` in one process
(`--engine serial`) against a local Dask cluster of one worker process per core, on the same
synthetic fleet and machine (issue 50 item 2).

Each configuration runs the command line in a fresh process with `--no-cache` (no persistent
compilation cache: every process compiles the monitor programs once, as on a new machine) into
a fresh database, and is timed from start to end (compile included) and in its steady state
(from the first finished bogie-date to the last: warm programs). The fleet: `--bogies` bogies
of `bogie_jax.fleet`'s synthetic scenarios (healthy and the defects of DEFECT_SCENARIOS in
turn), each with two half-second runs on one date, four candidate elements.

    python benchmarks/fleet_throughput.py --bogies 8 [--workers N]

Writes `results/fleet_throughput/serial_vs_dask.{json,md}` through `_common.write_outputs`.
"""

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import write_outputs


SCENARIOS = ("healthy", "yaw-damper-left-0", "healthy", "secondary-lateral-damper-left-failed")
CANDIDATES = (
    "yaw_dampers.left.c",
    "yaw_dampers.right.c",
    "secondary.left.cy",
    "secondary.right.cy",
)
_DONE = re.compile(r"bogie-dates (\d+)/(\d+) done.*?, ([0-9.]+) (s|min)(?:,|$)")


def make_fleet(folder: Path, n: int) -> Path:
    import jax

    jax.config.update("jax_enable_x64", True)
    from bogie_jax.fleet import SyntheticBogie, write_synthetic_fleet

    bogies = [SyntheticBogie(f"bogie-{k:02d}", SCENARIOS[k % len(SCENARIOS)]) for k in range(n)]
    return write_synthetic_fleet(folder, bogies, candidates=CANDIDATES)


def run(inventory: Path, db: Path, engine_args: list[str]) -> dict:
    """One `fleet run` in a fresh process: wall time and the elapsed time of each outcome."""
    cmd = [sys.executable, "-m", "bogie_jax.cli", "--no-cache", "fleet", "run",
           "--inventory", str(inventory), "--db", str(db), *engine_args]  # fmt: skip
    tic = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - tic
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    times = []
    for m in _DONE.finditer(proc.stdout):
        times.append(float(m.group(3)) * (60.0 if m.group(4) == "min" else 1.0))
    n = len(times)
    steady = (n - 1) / (times[-1] - times[0]) * 60 if n > 1 and times[-1] > times[0] else None
    return {"bogie_dates": n, "wall_s": wall, "first_done_s": times[0], "last_done_s": times[-1],
            "per_min_overall": n / wall * 60, "per_min_steady": steady}  # fmt: skip


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--bogies", type=int, default=8)
    p.add_argument("--workers", type=int, default=len(os.sched_getaffinity(0)))
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        inventory = make_fleet(tmp / "fleet", args.bogies)
        records = []
        engines = (
            ("serial (one process)", ["--engine", "serial"]),
            (f"dask, {args.workers} workers", ["--workers", str(args.workers)]),
        )
        for label, engine in engines:
            r = run(inventory, tmp / f"{len(records)}.db", engine)
            records.append({"engine": label, **r})
            print(label, r, flush=True)
    base = records[0]["per_min_overall"]
    rows = ["| engine | bogie-dates | wall [s] | first done [s] | per min (overall) | "
            "per min (steady) | speed-up (overall) |", "|---|---|---|---|---|---|---|"]  # fmt: skip
    for r in records:
        steady = "-" if r["per_min_steady"] is None else f"{r['per_min_steady']:.1f}"
        rows.append(f"| {r['engine']} | {r['bogie_dates']} | {r['wall_s']:.0f} | "
                    f"{r['first_done_s']:.0f} | {r['per_min_overall']:.2f} | {steady} | "
                    f"{r['per_min_overall'] / base:.2f} |")  # fmt: skip
    md = (
        f"# Fleet throughput: one process against a local Dask cluster\n\n"
        f"{args.bogies} synthetic bogies (two 0.5 s runs, 4 candidates), `--no-cache` "
        f"(each process compiles once).\n\n" + "\n".join(rows) + "\n"
    )
    write_outputs("fleet_throughput/serial_vs_dask", records, md,
                  extra={"bogies": args.bogies, "workers": args.workers})  # fmt: skip


if __name__ == "__main__":
    main()
