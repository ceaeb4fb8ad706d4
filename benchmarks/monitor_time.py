"""Wall time of `monitor` on one bogie with two 8 s runs (issue 48, item 1), cold, warm and with
its programs in memory, against the code at an earlier commit measured in the same run.

**A case** is one of `benchmarks/detection.py`'s (seed 0, default imperfections: the records'
0.3 mm error and offset, speed error, sensor bias; two 8 s runs at 100 Hz, the 16 default
candidates, run corrections, `track_error` 0.3 mm told to `monitor`).

**Per case**, each in a fresh process, one after another (the machine's cores are the
benchmark's alone; `monitor` runs its track-record refits in one thread per core):
- `cold`: an empty persistent compilation cache (`bogie_jax.use_compilation_cache`, as the
  command line sets it up), then the same case again in the same process (`in memory`: the
  programs compiled, so the figure is evaluation only);
- `warm`: a new process on the cache the cold one filled (what a second `bogie-jax monitor` on
  data of the same shapes pays);
- `baseline` (the first `--baseline-cases` cases): the package at `--baseline` (a git commit,
  checked out into a temporary worktree) on the same case, in memory (its second call), so the
  speed-up is a ratio of two figures measured in this run with compile time apart.
Each process prints `monitor`'s own `timings` (first Jacobian, fit, track-record term, verdicts,
total), the process's wall time around the call and the persistent cache's hits and misses
during it (a miss is a program XLA compiled: none in a warm process).

Run (from the repository root):
    python benchmarks/monitor_time.py                        # 5 cases, baseline on 3
    python benchmarks/monitor_time.py --cases 1 --baseline-cases 0
Writes `results/monitor_time/two_8s_runs.json` and `.md`.
"""

import argparse
import contextlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
PHASES = ("first_jacobian_s", "fit_s", "track_error_s", "verdicts_s", "total_s")


def _detection():
    """This checkout's `benchmarks/detection.py` (its case generator), whichever package the
    process imports."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "detection_cases", ROOT / "benchmarks" / "detection.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def one_case(index: int, cache: str, calls: int, duration: float = 8.0) -> None:
    """Child process: case `index` judged `calls` times with the cache in `cache`; prints one
    JSON line per call (`monitor`'s timings, wall time, verdicts)."""
    os.environ.setdefault("EQX_ON_ERROR", "nan")
    detection = _detection()  # sets its own cache folder: replaced below
    import jax
    from jax import monitoring

    jax.config.update("jax_enable_x64", True)
    events = []  # the persistent cache's hits and misses (a miss: a program XLA compiled)
    monitoring.register_event_listener(lambda name, **kw: events.append(name))
    try:
        from bogie_jax import use_compilation_cache

        use_compilation_cache(cache)
    except ImportError:  # an older package: the cache by JAX's own settings
        jax.config.update("jax_compilation_cache_dir", cache)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    from bogie_jax.monitor import monitor

    # the detection benchmark's own defaults (seed 0, default imperfections), 0.3 mm told
    args = detection.parse_args(["--duration", f"{duration}", "--track-error", "0.3"])
    inputs = detection.case_inputs(detection.config_of(args), index)
    for _ in range(calls):
        events.clear()
        t0 = time.perf_counter()
        result = monitor(
            inputs["runs"], inputs["tracks"], params=inputs["nominal"], options=inputs["options"]
        )
        wall = time.perf_counter() - t0
        verdicts = {v.name: [v.verdict, v.estimate, v.std_error] for v in result.verdicts}
        cache = {k: events.count(f"/jax/compilation_cache/cache_{k}") for k in ("hits", "misses")}
        line = {"timings": dict(result.timings), "wall_s": wall, "verdicts": verdicts, **cache}
        print("RESULT " + json.dumps(line), flush=True)


def _child(index: int, cache: str, calls: int, source: Path, duration: float) -> list[dict]:
    """Run `one_case` in a fresh interpreter with the package from `source`."""
    env = {**os.environ, "PYTHONPATH": str(source), "EQX_ON_ERROR": "nan"}
    code = (
        f"import sys, importlib.util as u; sys.path.insert(0, {str(source)!r}); "
        f"s = u.spec_from_file_location('monitor_time', {__file__!r}); "
        f"m = u.module_from_spec(s); s.loader.exec_module(m); m.one_case({index}, {cache!r}, "
        f"{calls}, {duration})"
    )
    load = os.getloadavg()[0]
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=False
    )
    lines = [json.loads(x[7:]) for x in out.stdout.splitlines() if x.startswith("RESULT ")]
    if len(lines) != calls:
        raise RuntimeError(f"case {index} from {source} failed:\n{out.stderr[-3000:]}")
    return [{**line, "load_1min": load} for line in lines]


def measure(cases: int, baseline: str | None, baseline_cases: int, duration: float) -> list[dict]:
    sys.path.insert(0, str(ROOT))
    from benchmarks._common import git_worktree

    records = []
    with contextlib.ExitStack() as stack:
        tmp = Path(stack.enter_context(tempfile.TemporaryDirectory()))
        old = stack.enter_context(git_worktree(baseline, tmp / "base")) if baseline_cases else None
        for index in range(1, cases + 1):
            cache = str(tmp / f"cache{index}")
            cold, again = _child(index, cache, 2, ROOT, duration)
            (warm,) = _child(index, cache, 1, ROOT, duration)
            record = {"case": index, "duration_s": duration, "cold": cold, "in_memory": again,
                      "warm": warm}  # fmt: skip
            if old is not None and index <= baseline_cases:
                base_cache = str(tmp / f"base{index}")
                record["baseline"] = _child(index, base_cache, 2, old, duration)[1]
            records.append(record)
            print(json.dumps({k: _brief(v) for k, v in record.items()}), flush=True)
    return records


def _brief(v):
    return round(v["timings"]["total_s"], 1) if isinstance(v, dict) else v


def _median(records, mode: str, phase: str) -> float:
    values = [r[mode]["timings"].get(phase, 0.0) for r in records if mode in r]
    return statistics.median(values) if values else float("nan")


def _same_verdicts(records) -> str:
    paired = [r for r in records if "baseline" in r]
    same = sum(
        all(r["in_memory"]["verdicts"][n][0] == v[0] for n, v in r["baseline"]["verdicts"].items())
        for r in paired
    )
    shifts = [
        abs(r["in_memory"]["verdicts"][n][1] - v[1]) / v[2]
        for r in paired
        for n, v in r["baseline"]["verdicts"].items()
        if v[1] is not None and v[2]
    ]
    worst = max(shifts, default=float("nan"))
    med = statistics.median(shifts) if shifts else float("nan")
    return (
        f"Verdicts the same as the baseline's in {same} of {len(paired)} cases; estimates moved "
        f"by a median {med:.2f} and at most {worst:.2f} of the baseline's standard errors."
    )


def markdown(records, baseline: str | None) -> str:
    modes = ["cold", "warm", "in_memory"] + (
        ["baseline"] if any("baseline" in r for r in records) else []
    )
    head = "| mode | cases | " + " | ".join(p.removesuffix("_s") + " [s]" for p in PHASES) + " |"
    lines = [
        f"# monitor on two {records[0].get('duration_s', 8):g} s runs: cold, warm, in memory",
        "",
        f"Medians over the cases (detection benchmark cases 1-{len(records)}, seed 0, default "
        "imperfections, `track_error` 0.3 mm); each mode a fresh process, one at a time.",
        "",
        head,
        "| --- | ---: | " + " | ".join("---:" for _ in PHASES) + " |",
    ]
    for mode in modes:
        n = sum(mode in r for r in records)
        cells = " | ".join(f"{_median(records, mode, p):.1f}" for p in PHASES)
        name = f"baseline ({baseline}, in memory)" if mode == "baseline" else mode
        lines.append(f"| {name} | {n} | {cells} |")
    compile_s = _median(records, "cold", "total_s") - _median(records, "in_memory", "total_s")
    warm_compile = _median(records, "warm", "total_s") - _median(records, "in_memory", "total_s")
    lines += [
        "",
        f"Compile (cold minus in memory): {compile_s:.1f} s; what a warm process still pays "
        f"(tracing, cache reads): {warm_compile:.1f} s.",
    ]
    warm = [r["warm"] for r in records if "misses" in r.get("warm", {})]
    if warm:
        misses = sum(w["misses"] for w in warm)
        lines += [
            "",
            f"Programs the warm processes compiled (persistent-cache misses): {misses}, against "
            f"{sum(w['hits'] for w in warm)} read from the cache ({len(warm)} processes; the cold "
            f"ones: {sum(r['cold']['misses'] for r in records)} compiled).",
        ]
    paired = [r for r in records if "baseline" in r]
    if paired:
        ratio = statistics.median(
            r["baseline"]["timings"]["total_s"] / r["in_memory"]["timings"]["total_s"]
            for r in paired
        )
        lines += ["", f"Speed-up in memory over the baseline: **{ratio:.2f}x** (median of the "
                  f"{len(paired)} paired cases' ratios).", "", _same_verdicts(records)]  # fmt: skip
    return "\n".join(lines)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", type=int, default=5)
    p.add_argument("--baseline", default="9dd128d", help="git commit of the baseline")
    p.add_argument("--baseline-cases", type=int, default=3)
    p.add_argument("--duration", type=float, default=8.0, help="[s] of each run (default 8)")
    p.add_argument("--name", default="two_8s_runs")
    args = p.parse_args(argv)
    if args.cases < 1 or not 0 <= args.baseline_cases <= args.cases:
        raise SystemExit("--cases must be >= 1 and --baseline-cases in [0, --cases]")
    records = measure(args.cases, args.baseline, args.baseline_cases, args.duration)
    from benchmarks._common import write_outputs

    extra = {"baseline": args.baseline, "cpu_count": os.cpu_count()}
    write_outputs(f"monitor_time/{args.name}", records, markdown(records, args.baseline), extra)


if __name__ == "__main__":
    main()
