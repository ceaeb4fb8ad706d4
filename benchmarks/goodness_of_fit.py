"""Goodness-of-fit benchmark: the false-alarm rate of `monitor`'s test "the fit explains the data"
(`bogie_jax/monitor/_goodness.py`) on data the model explains, and its power on data it does not.

**A case** (drawn from `numpy.random.default_rng([seed, index])`): two runs of `--duration` s
at `--sample-rate` Hz, speeds uniform in [30, 60] m/s, each on its own ERRI-low track section;
Gaussian sensor noise of 1-3 % of each channel's RMS, declared in the layout; a bias per channel
of up to 5 % of its RMS; each run's stated speed wrong by up to 1 %; the fit's track a record of
the true one with `--track-noise` mm RMS error and an offset of up to 0.5 m (as
`benchmarks/detection.py`'s default imperfections); `monitor` told the record's error
(`--track-error`, default: the true one).

**Kinds** (`--kind`):
- `matched`: the package's own model; the bogie healthy for even indices, else the left
  anti-yaw damper at 50 % (a candidate: the fit explains it): every rejection is a false alarm;
- `secondary-damper`: the left secondary vertical damper (`secondary.left.cz`, not a candidate)
  at `FAILED_FLOOR`: a rejection is a detection;
- `nonlinear`: data simulated with creep saturation and blow-off anti-yaw dampers
  (`nonlinear_options()`), fitted with the linear model.

Each case's record (the goodness-of-fit tests, suspects, alarms, timings) is appended to
`results/goodness_of_fit/<stem>.jsonl` (a re-run skips the cases found there); the summary is
written to `results/goodness_of_fit/<stem>.json` and `.md`; `<stem>` is the kind, with
`-exact_track` where the track record has no error (`--track-noise 0`).

Run (from the repository root):
    python benchmarks/goodness_of_fit.py --kind matched --cases 16
    python benchmarks/goodness_of_fit.py --kind secondary-damper --cases 8
    python benchmarks/goodness_of_fit.py --kind matched --cases 8 --track-noise 0
"""

import argparse
import json
import sys
import time
from pathlib import Path


sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import numpy as np  # noqa: E402

# detection.py sets up the process its cases need (runtime errors as NaN, x64, the persistent
# compilation cache) before the package loads; these cases are built as its cases are
from benchmarks import detection  # noqa: E402, F401
from benchmarks._cases import (  # noqa: E402
    clean_runs,
    record_tracks,
    spoiled_runs,
    track_length,
    track_references,
    value,
)
from benchmarks._common import RESULTS, wilson, write_outputs  # noqa: E402
from bogie_jax.monitor import (  # noqa: E402
    DEFECT_SCENARIOS,
    FAILED_FLOOR,
    DefectScenario,
    MonitorOptions,
    monitor,
    nonlinear_options,
)
from bogie_jax.params import ModelOptions, manchester_benchmark  # noqa: E402


FOLDER = RESULTS / "goodness_of_fit"
KINDS = ("matched", "secondary-damper", "nonlinear")
SECONDARY = DefectScenario("secondary-damper", factors={"secondary.left.cz": FAILED_FLOOR})


def case_data(kind: str, index: int, args):
    """The runs, track records and scenario name of case `index` (module docstring)."""
    rng = np.random.default_rng([args.seed, index])
    if kind == "secondary-damper":
        scenario = SECONDARY
    elif kind == "matched" and index % 2:
        scenario = DEFECT_SCENARIOS["yaw-damper-left-50"]
    else:
        scenario = DEFECT_SCENARIOS["healthy"]
    nominal = manchester_benchmark()
    model = nonlinear_options() if kind == "nonlinear" else ModelOptions()
    speeds = rng.uniform(30.0, 60.0, 2)
    refs = track_references(
        "erri-low", rng.integers(0, 2**31 - 10_000, 2), track_length(nominal, 60.0, args.duration)
    )
    clean = clean_runs(
        scenario.true_params(nominal), refs, speeds, duration=args.duration,
        sample_rate=args.sample_rate, model=model,
    )  # fmt: skip
    noise = float(rng.uniform(0.01, 0.03))
    noise_seed = int(rng.integers(0, 2**31))
    bias = rng.uniform(-0.05, 0.05, len(clean[0].channels))
    runs = spoiled_runs(
        clean, noise, noise_seed, bias=bias, speed_errors=rng.uniform(-0.01, 0.01, 2)
    )
    tracks = record_tracks(
        refs, noise=1e-3 * args.track_noise, offsets=rng.uniform(-0.5, 0.5, 2),
        semi_distance=value(nominal, "contact.contact_semi_distance"),
    )  # fmt: skip
    return runs, tracks, nominal, scenario.name


def run_case(kind: str, index: int, args) -> dict:
    runs, tracks, nominal, scenario = case_data(kind, index, args)
    track_error = args.track_noise if args.track_error is None else args.track_error
    options = MonitorOptions(track_error=1e-3 * track_error)
    t0 = time.perf_counter()
    result = monitor(runs, tracks, params=nominal, options=options)
    g = result.goodness
    return {
        "index": index,
        "kind": kind,
        "scenario": scenario,
        "explained": result.explained,
        "goodness_of_fit": None if g is None else g.to_dict(),
        "alarms": [[v.name, v.verdict] for v in result.alarms],
        "withheld": [v.name for v in result.verdicts if v.evidence.get("not_explained")],
        "monitor_s": time.perf_counter() - t0,
        "suspects_s": result.timings.get("suspects_s"),
    }


def load(path: Path) -> dict[int, dict]:
    out = {}
    if path.exists():
        for line in path.read_text().splitlines():
            if line.strip():
                rec = json.loads(line)
                out[rec["index"]] = rec
    return out


def _wilson(k: int, n: int) -> str:
    """The Wilson 95 % interval of a rate k / n (`_common.wilson`), as `[lo, hi] %`."""
    if not n:
        return "-"
    lo, hi = wilson(k, n)
    return f"[{100 * lo:.1f}, {100 * hi:.1f}] %"


def summary(records: list[dict], args) -> tuple[dict, str]:
    """Rejection rates per case and per run-group test; the mean low-band ratio."""
    n = len(records)
    rejected = sum(not r["explained"] for r in records)
    tests = [t for r in records for t in (r["goodness_of_fit"] or {}).get("tests", [])]
    by_group: dict[str, list] = {}
    for t in tests:
        by_group.setdefault(t["group"], []).append(t)
    lines = [
        f"# Goodness of fit: {args.kind}" + ("" if args.track_noise else ", exact track record"),
        "",
        f"{n} cases of two {args.duration:g} s runs at {args.sample_rate:g} Hz (track record "
        f"error {args.track_noise:g} mm, given to monitor); the data are called not explained "
        f"in {rejected} of {n} cases ({rejected / max(n, 1):.0%}, Wilson 95 % interval "
        f"{_wilson(rejected, n)}), at the family-wise rate 0.05 over "
        f"{len(tests) // max(n, 1)} run-group tests per case; "
        f"{sum(t['rejected'] for t in tests)} of {len(tests)} run-group tests rejected.",
        "",
        "| group | tests | rejected | median T / expected | max T / expected |",
        "| --- | --- | --- | --- | --- |",
    ]
    for group, ts in by_group.items():
        ratios = [t["ratio"] for t in ts]
        lines.append(
            f"| {group} | {len(ts)} | {sum(t['rejected'] for t in ts)} | "
            f"{np.median(ratios):.2f} | {max(ratios):.2f} |"
        )
    suspects = [r["goodness_of_fit"]["suspects"] for r in records if not r["explained"]]
    top = [s[0]["name"] for s in suspects if s]
    if top:
        names = {name: top.count(name) for name in top}
        lines += ["", "Top suspect where not explained: " + ", ".join(
            f"{k} ({v})" for k, v in sorted(names.items(), key=lambda kv: -kv[1]))]  # fmt: skip
    alarms = sum(bool(r["alarms"]) for r in records)
    withheld = sum(bool(r["withheld"]) for r in records)
    wall = np.median([r["monitor_s"] for r in records])
    lines += ["", f"Cases with an alarm: {alarms}; with an alarm withheld (not explained): "
              f"{withheld}. Median monitor time {wall:.0f} s."]  # fmt: skip
    out = {"cases": n, "not_explained": rejected, "tests": len(tests), "alarms": alarms,
           "withheld": withheld}  # fmt: skip
    return out, "\n".join(lines)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--kind", choices=KINDS, default="matched")
    p.add_argument("--cases", type=int, default=16)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--duration", type=float, default=1.0, help="run duration [s]")
    p.add_argument("--sample-rate", type=float, default=100.0, help="[Hz]")
    p.add_argument("--track-noise", type=float, default=0.3, help="record error RMS [mm]")
    p.add_argument("--track-error", type=float, default=None, help="given to monitor [mm]")
    p.add_argument("--report", action="store_true", help="only summarise the records")
    args = p.parse_args(argv)
    FOLDER.mkdir(parents=True, exist_ok=True)
    stem = args.kind if args.track_noise else f"{args.kind}-exact_track"
    path = FOLDER / f"{stem}.jsonl"
    done = load(path)
    for index in range(args.cases):
        if args.report or index in done:
            continue
        rec = run_case(args.kind, index, args)
        print(json.dumps({k: rec[k] for k in ("index", "explained", "alarms", "monitor_s")}))
        with path.open("a") as f:
            f.write(json.dumps(rec) + "\n")
        done[index] = rec
    records = [done[k] for k in sorted(done) if k < args.cases]
    out, md = summary(records, args)
    previous = FOLDER / f"{stem}.json"  # --report: the environment of the measuring run
    env = None
    if args.report and previous.exists():
        env = json.loads(previous.read_text()).get("environment")
    write_outputs(f"goodness_of_fit/{stem}", records, md, extra={"summary": out,
                  "config": vars(args)}, env=env)  # fmt: skip


if __name__ == "__main__":
    main()
