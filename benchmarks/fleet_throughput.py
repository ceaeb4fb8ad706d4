"""Fleet throughput: bogie-dates judged per minute by `bogie-jax fleet run` in one process
(`--engine serial`) against a local Dask cluster of `--workers` processes (default: one per
core), each pinned to its share of the cores, on the same synthetic fleet and machine (issue 50
item 2, issue 48 item 3).

Each configuration runs the command line in a fresh process into a fresh database, timed from
the process's start to its end and at each finished bogie-date (the progress lines, stamped as
they arrive): `cold` with `--no-cache` (every process compiles the monitor programs once, as on
a new machine), `warm` with a persistent compilation cache that an earlier run of the same
configuration filled (as on the next day: the programs are read from disk). The steady rate
counts from the first finished bogie-date to the last (every worker's programs ready). The
fleet: `--bogies` bogies of the synthetic scenarios (healthy and defects in turn), each with two
half-second runs on one date, four candidate elements.

    python benchmarks/fleet_throughput.py --bogies 8 [--workers N]
    python benchmarks/fleet_throughput.py --bogies 6 --duration 8 --candidates default \
        --track-error 0.3 --warm-only          # bogies as `monitor_time` judges them

Writes `results/fleet_throughput/serial_vs_dask.{json,md}` (two 0.5 s runs, four candidates),
or `serial_vs_dask_two_<D>s_runs` for runs of `--duration` D seconds, through
`_common.write_outputs`. With `--warm-only`, only the warm configurations run, each on a cache
that a one-bogie fleet of the same shapes filled (the compiled programs are the same).
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
_DONE = re.compile(r"bogie-dates (\d+)/(\d+) done.*?, ([0-9.]+) (s|min)(?:,|$)", re.M)


def make_fleet(folder: Path, n: int, duration: float, candidates, track_error_mm: float) -> Path:
    """`n` synthetic bogies (the `SCENARIOS` in turn), each with two runs of `duration` [s] at 30
    and 50 m/s, judged on `candidates` (`()`: `monitor`'s default ones)."""
    import jax

    jax.config.update("jax_enable_x64", True)
    from bogie_jax.fleet import SyntheticBogie, write_synthetic_fleet
    from bogie_jax.monitor import RunSpec

    runs = (RunSpec(speed=30.0, duration=duration, seed=1),
            RunSpec(speed=50.0, duration=duration, seed=2))  # fmt: skip
    bogies = [SyntheticBogie(f"bogie-{k:02d}", SCENARIOS[k % len(SCENARIOS)]) for k in range(n)]
    return write_synthetic_fleet(folder, bogies, runs=runs, candidates=candidates,
                                 track_error_mm=track_error_mm)  # fmt: skip


def run(inventory: Path, db: Path, engine_args: list[str], cache: Path | None) -> dict:
    """One `fleet run` in a fresh process: its wall time and when each bogie-date finished."""
    flags = ["--no-cache"] if cache is None else []
    cmd = [sys.executable, "-m", "bogie_jax.cli", *flags, "fleet", "run",
           "--inventory", str(inventory), "--db", str(db), *engine_args]  # fmt: skip
    env = dict(os.environ, **({"BOGIE_JAX_CACHE_DIR": str(cache)} if cache else {}))
    tic = time.perf_counter()
    times, lines = [], []
    with subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          env=env) as proc:  # fmt: skip
        for line in proc.stdout:
            lines.append(line)
            if _DONE.search(line):
                times.append(time.perf_counter() - tic)
    wall = time.perf_counter() - tic
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{''.join(lines)[-4000:]}")
    n = len(times)
    steady = (n - 1) / (times[-1] - times[0]) * 60 if n > 1 else None
    return {"bogie_dates": n, "wall_s": wall, "first_done_s": times[0], "last_done_s": times[-1],
            "per_min_overall": n / wall * 60, "per_min_steady": steady}  # fmt: skip


def configurations(workers: int, warm_only: bool):
    serial, dask = ["--engine", "serial"], ["--workers", str(workers)]
    cold = (
        ("serial (one process), cold", serial, False),
        (f"dask, {workers} workers, cold", dask, False),
    )
    warm = (
        ("serial (one process), warm", serial, True),
        (f"dask, {workers} workers, warm", dask, True),
    )
    return warm if warm_only else cold + warm


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--bogies", type=int, default=8)
    p.add_argument("--workers", type=int, default=len(os.sched_getaffinity(0)))
    p.add_argument("--duration", type=float, default=0.5, help="[s] of each of the two runs")
    p.add_argument("--candidates", choices=("four", "default"), default="four",
                   help="four (`CANDIDATES`) or `monitor`'s 16 default ones")  # fmt: skip
    p.add_argument("--track-error", type=float, default=0.0, help="[mm] told to `monitor`")
    p.add_argument("--warm-only", action="store_true")
    args = p.parse_args()
    candidates = CANDIDATES if args.candidates == "four" else ()
    fleet = lambda folder, n: make_fleet(folder, n, args.duration, candidates, args.track_error)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        inventory = fleet(tmp / "fleet", args.bogies)
        # the cache's filling: the same fleet, or (`--warm-only`) one bogie of the same shapes
        filling = fleet(tmp / "one", 1) if args.warm_only else inventory
        records = []
        for label, engine, warm in configurations(args.workers, args.warm_only):
            key = label.split()[0].rstrip(",")  # serial or dask: a cache of its own
            cache = tmp / f"cache-{key}" if warm else None
            if warm:
                run(filling, tmp / f"fill-{key}.db", engine, cache)
            r = run(inventory, tmp / f"{len(records)}.db", engine, cache)
            records.append({"engine": label, **r})
            print(label, r, flush=True)
    write_result(args, records)


def write_result(args, records) -> None:
    serial = {
        ("warm" in r["engine"]): r["per_min_overall"] for r in records if "serial" in r["engine"]
    }
    rows = [
        "| engine | bogie-dates | wall [s] | first done [s] | per min (overall) | "
        "per min (steady) | against serial (overall) |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in records:
        r_base = serial["warm" in r["engine"]]
        steady = "-" if r["per_min_steady"] is None else f"{r['per_min_steady']:.1f}"
        rows.append(f"| {r['engine']} | {r['bogie_dates']} | {r['wall_s']:.0f} | "
                    f"{r['first_done_s']:.0f} | {r['per_min_overall']:.2f} | {steady} | "
                    f"{r['per_min_overall'] / r_base:.2f} |")  # fmt: skip
    n_candidates = len(CANDIDATES) if args.candidates == "four" else "the 16 default"
    filled = ("a one-bogie fleet of the same shapes, judged first" if args.warm_only
              else "an earlier run of the same configuration")  # fmt: skip
    md = (
        f"# Fleet throughput: one process against a local Dask cluster\n\n"
        f"{args.bogies} synthetic bogies (two {args.duration:g} s runs, {n_candidates} "
        f"candidates, track-record error {args.track_error:g} mm told); the local cluster's "
        f"workers each run one task at a time, pinned to their share of the cores; cold: "
        f"`--no-cache` (each process compiles once); warm: a compilation cache filled by "
        f"{filled}. Times from the process's start.\n\n" + "\n".join(rows) + "\n"
    )
    stem = (
        "serial_vs_dask" if args.duration == 0.5 else f"serial_vs_dask_two_{args.duration:g}s_runs"
    )
    extra = {"bogies": args.bogies, "workers": args.workers, "duration_s": args.duration,
             "candidates": args.candidates, "track_error_mm": args.track_error}  # fmt: skip
    write_outputs(f"fleet_throughput/{stem}", records, md, extra=extra)


if __name__ == "__main__":
    main()
