# long: one driver for the case generator, the parallel runner with its resumable record,
# and the aggregate tables; they share the case record's fields.
"""Detection benchmark (issue 19, item 6): `bogie_jax.monitor.monitor` as a black box on
random synthetic cases with the imperfections of real data (item 4).

**A case** (all of it drawn from `numpy.random.default_rng([seed, index])`, so a case is the
same whatever the shard, worker, order or imperfection mode):
- the bogie: healthy for every third case (index % 3 == 0: a third of the cases plus one at
  most), else a defect scenario of `bogie_jax.monitor.DEFECT_SCENARIOS` (type and size from the
  library) drawn with weight 3 for `yaw-damper-left-50` (the headline target, a 50 % loss of one
  anti-yaw damper) and 1 for each of the six others;
- two runs at speeds drawn uniformly in [30, 60] m/s, each on its own random track section
  (ERRI-low spectrum, random seed), from rest at the track start, `--duration` s at
  `--sample-rate` Hz, the 13 channels of the default sensor layout;
- sensor noise: Gaussian, standard deviation f times each channel's RMS (over both runs of the
  case), f drawn uniformly in [1 %, 3 %] per case ("noise 1-3 %"); the sensor layout states these
  levels (the fit's weights are right) unless the `channel-noise` imperfection is on.
Every run has the same shape (duration, sample rate, channels, track length: the longest run
at the highest speed plus the wheelbase and 50 m), so one compiled simulation and one compiled
joint Jacobian serve every case of a process (speeds, seeds and values are traced).

**Imperfections** (`--imperfection`, comma-separated; `default` = `track,speed,bias`, items
4 (a)-(c)), each with its value drawn per case whether on or not:
- `track` (a): the fit's track is a recording of the true one (`recorded_track`): 0.3 mm RMS
  error per channel and a distance offset uniform in [-0.5, 0.5] m, per run;
- `speed` (b): the fit is told each run's speed times 1 + e, e uniform in [-1 %, 1 %];
- `bias` (c): a constant bias per channel, uniform in [-5 %, 5 %] of the channel's RMS, the
  same on both runs, unknown to the fit;
- `nonlinear` (d): data from the model with creep saturation and blow-off anti-yaw dampers;
- `channel-noise` (e): the layout keeps the sensors' nominal noise levels (the fit's weights
  are wrong by the ratio of the true f * RMS to the nominal noise_std, channel by channel);
- `worn-wheels` (f): the true cone slope is nominal times a factor uniform in [0.7, 1.3];
- model mismatch (issue 51; `benchmarks/_mismatch.py` defines each): `real-profile` (g: data
  from the S1002/UIC60 1:40 contact table, the fit on the cone), `worn-profile` (h: data from
  the measured worn wheel, the fit on the new S1002 profile; `half-worn-profile`: from a wheel
  halfway between the two profiles), `track-white` (i: the record's
  error white within 3-70 m wavelengths at 0.1-0.3 mm RMS), `track-drift` (i: a long-wave
  record error, 70-200 m at 0.3-1 mm RMS; in both the monitor is told only the RMS),
  `unjudged-defect` (j: a defect of an element that is not a candidate, in half of the
  defective cases together with the candidate defect), `nonlinear-laws` (d', with `nonlinear`:
  the data's friction coefficient and anti-yaw damper relief laws unlike the monitor's
  nonlinear model's);
- `none`: no imperfection; `all`: (a)-(f); `offset` is another name of `track`.

**Per case** (`monitor(measurements, tracks=<recorded tracks>, params=nominal (on the mode's
contact of the fit, or --fit-contact's; with --fit-wear a wheel wear it fits),
options=MonitorOptions(track_error=<the records' error RMS: --track-error's and the track
modes'>, model=<--fit-model's: the linear model by default>))`, default options otherwise):
truth, verdicts (with every `std_error_*` component of their evidence, and whether an alarm
was withheld as not explained), estimates (and, with a track error, the fitted values before
its bias is removed), standard errors, 95 % intervals,
fit status (with the horizon stages fitted, the misfit ratio, the per-channel noise
estimates and the nuisance parameters' fitted values, `FitSummary`), whether the data are
explained (`MonitorResult.explained`) with the goodness-of-fit tests, the misfit run-groups
and the suspects, each run's fitted speed factor and track position against their true
values, the mismatch applied (with the unjudged defect's change of the signals over the
noise), wall times; each finished case is appended as one line of
`results/detection/<out>.jsonl` (per shard: `<out>.shard<i>of<n>.jsonl`) and a re-run skips
the cases found there.

**Aggregates** (over every record of `<out>*.jsonl`): per defect type the detection rate (any
element degraded or failed), the correct-element rate among detected cases (an alarm on a
changed element or on a group holding one), wrong-element alarms, the absolute error of the
estimated relative change of the changed element; the false-alarm rate on healthy bogies; per
element the mean absolute error of the estimated relative change (estimate / nominal - 1
against truth / nominal - 1; a group: the weighted mean of its members' true values relative
to nominal, with the weights its verdict reports, `member_weights`, what its estimate measures
(`bogie_jax.monitor._elements.group_weights`; records made before the weights were reported:
equal weights, the members' mean) where it is identifiable alone, and
the coverage of its 95 % interval, and the mean absolute error its standard errors imply:
sqrt(2 / pi) times the mean relative standard error (E|e| of a normal error e with that
deviation; the Gauss-Newton standard error is the Cramer-Rao bound of an unbiased estimate
from these data and this track record), in all and of its residual term alone (without the
track record's error); the same per group, and for the groups whose members' true values are
equal apart from those whose members differ (where the weights matter); issue 51's figures
(`_mismatch_report.report`): no alarm on a healthy element, the 50 % anti-yaw damper found,
the "not explained" rate, coverage per element, size error, and for `unjudged-defect` the "not
explained" rate where the unjudged defect changes the signals by more than the noise. Rates
carry Wilson 95 % intervals.

Run (from the repository root):
    python benchmarks/detection.py --workers 16               # 100 cases, items 4 (a)-(c)
    python benchmarks/detection.py --imperfection speed        # 30 cases, one imperfection
    python benchmarks/detection.py --imperfection unjudged-defect --duration 2 --cases 50 \
        --workers 2                                            # a model-mismatch mode
    python benchmarks/detection.py --shard 0/2 --workers 16    # half the cases (other: 1/2)
    python benchmarks/detection.py --report                    # tables from the records only
    python benchmarks/detection.py --duration 8 --track-error 0.3 --out two_8s_runs
                        # the records' 0.3 mm error in the intervals, its bias removed
    python benchmarks/detection.py --imperfection worn-wheels --duration 2 --nuisance none \
        --out worn-wheels_no_nuisance         # without the contact's model-form nuisance
    python benchmarks/detection.py --imperfection real-profile --fit-contact s1002-uic60 \
        --duration 2 --cases 20 --workers 2 --out real-profile_profile_fit  # the table fitted
    python benchmarks/detection.py --imperfection half-worn-profile --fit-wear 0.5 \
        --duration 2 --cases 20 --workers 2 --out half-worn-profile_wear_fit  # wear fitted
Writes results/detection/<out>.json (records + aggregates + environment) and
results/detection/<out>.md; <out> is `default_imperfections` for the default imperfections,
else the imperfections' names joined by `-`.
"""

import os


# Runtime checks become NaNs rather than host callbacks, so the persistent compilation cache
# keeps every program and a resumed run skips compiling (as identification.py).
os.environ.setdefault("EQX_ON_ERROR", "nan")

import argparse
import dataclasses
import hashlib
import json
import math
import sys
import time
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)
jax.config.update(
    "jax_compilation_cache_dir", str(Path(__file__).resolve().parents[1] / ".jax_cache")
)
jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)

import numpy as np

from bogie_jax.measure import default_sensor_layout
from bogie_jax.monitor import (
    DEFAULT_CANDIDATES,
    DEFECT_SCENARIOS,
    MonitorOptions,
    group_value,
    interval_outside,
    monitor,
    nonlinear_options,
)
from bogie_jax.params import ModelOptions, manchester_benchmark


# after the package: a process given another checkout's package (monitor_time.py) keeps it
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks import _mismatch, _mismatch_report, _paired  # noqa: E402
from benchmarks._cases import (  # noqa: E402
    clean_runs,
    record_tracks,
    spoiled_runs,
    track_length,
    track_references,
    value,
)
from benchmarks._common import RESULTS, coverage_reading, rate, write_outputs  # noqa: E402


FOLDER = RESULTS / "detection"


MATCHED_MODES = ("track", "speed", "bias", "nonlinear", "channel-noise", "worn-wheels")
IMPERFECTIONS = (*MATCHED_MODES, *_mismatch.MODES)
ALIASES = {
    "default": ("track", "speed", "bias"),
    "all": MATCHED_MODES,
    "none": (),
    "offset": ("track",),  # the track record: its error and its offset
}
HEADLINE = "yaw-damper-left-50"
DEFECTS = tuple(n for n in DEFECT_SCENARIOS if n != "healthy")
WEIGHTS = np.array([3.0 if n == HEADLINE else 1.0 for n in DEFECTS])
ALARMS = ("degraded", "failed")
N_CHANNELS = len(default_sensor_layout(manchester_benchmark()))


def parse_imperfections(text: str) -> tuple[str, ...]:
    out: list[str] = []
    for name in (t.strip() for t in text.split(",") if t.strip()):
        if name not in IMPERFECTIONS and name not in ALIASES:
            raise SystemExit(
                f"--imperfection: unknown {name!r}; valid: {', '.join((*IMPERFECTIONS, *ALIASES))}"
            )
        out += ALIASES.get(name, (name,))
    _mismatch.check_modes(out)
    return tuple(n for n in IMPERFECTIONS if n in out)


def stem(imperfections: tuple[str, ...]) -> str:
    if imperfections == ALIASES["default"]:
        return "default_imperfections"
    return "-".join(imperfections) if imperfections else "none"


def config_of(args) -> dict:
    """Everything a case depends on: records of another configuration are not mixed in."""
    return {
        "seed": args.seed,
        "imperfections": list(args.imperfections),
        "duration_s": args.duration,
        "sample_rate_hz": args.sample_rate,
        "speed_range_m_s": list(args.speed_range),
        "noise_range": list(args.noise_range),
        "track_spectrum": args.track_spectrum,
        "track_noise_mm": args.track_noise,
        "max_offset_m": args.max_offset,
        "max_speed_error": args.max_speed_error,
        "bias_fraction": args.bias,
        "max_wear": args.max_wear,
        "false_alarm_rate": args.false_alarm_rate,
        # only when given: records written before the option existed keep their configuration
        **({"track_error_mm": float(args.track_error)} if args.track_error else {}),
        **({"nuisance": list(args.nuisance)} if args.nuisance is not None else {}),
        **({"fit_model": args.fit_model} if args.fit_model != "linear" else {}),
        **({"fit_contact": args.fit_contact} if args.fit_contact is not None else {}),
        **({"fit_wear": args.fit_wear} if args.fit_wear is not None else {}),
        **({"jacobian": args.jacobian} if args.jacobian != "full" else {}),
        **({"refit_model": args.refit_model} if args.refit_model != "none" else {}),
        **_mismatch.config(args.imperfections, args.drift_band),
    }


def draw_case(cfg: dict, index: int) -> dict:
    """The random draws of case `index` (module docstring), every imperfection's included."""
    rng = np.random.default_rng([cfg["seed"], index])
    healthy = index % 3 == 0
    defect = DEFECTS[rng.choice(len(DEFECTS), p=WEIGHTS / WEIGHTS.sum())]
    lo, hi = cfg["speed_range_m_s"]
    n_lo, n_hi = cfg["noise_range"]
    return {
        "index": index,
        "scenario": "healthy" if healthy else defect,
        "speeds": rng.uniform(lo, hi, 2).tolist(),
        "track_seeds": rng.integers(0, 2**31 - 10_000, 2).tolist(),
        "noise_fraction": float(rng.uniform(n_lo, n_hi)),
        "noise_seed": int(rng.integers(0, 2**31)),
        "offsets_m": rng.uniform(-cfg["max_offset_m"], cfg["max_offset_m"], 2).tolist(),
        "speed_errors": rng.uniform(-cfg["max_speed_error"], cfg["max_speed_error"], 2).tolist(),
        "bias_fractions": rng.uniform(
            -cfg["bias_fraction"], cfg["bias_fraction"], N_CHANNELS
        ).tolist(),
        "cone_slope_factor": float(rng.uniform(1 - cfg["max_wear"], 1 + cfg["max_wear"])),
        **_mismatch.draw(rng),  # after the others: their values stay those of earlier records
    }


def _jacobian_option(jacobian: str) -> dict:
    """`MonitorOptions`' `jacobian` keyword; none for a package without it (an earlier commit
    measured as a baseline, whose Jacobians are all the full model's, whatever `jacobian`)."""
    known = {f.name for f in dataclasses.fields(MonitorOptions)}
    return {"jacobian": jacobian} if "jacobian" in known else {}


def _refit_option(refit: str) -> dict:
    """`MonitorOptions`' `refit_model` keyword (`none`: no refit); none for a package without
    it (an earlier commit, which never refits)."""
    known = {f.name for f in dataclasses.fields(MonitorOptions)}
    if "refit_model" not in known:
        return {}
    return {"refit_model": nonlinear_options() if refit == "nonlinear" else None}


def case_inputs(cfg: dict, index: int) -> dict:
    """Case `index`'s bogie and `monitor`'s input (module docstring): `case` (its draws),
    `nominal` and `truth` parameters, the candidate `scenario`, the `changed` elements, the
    case's `label` (its row in the tables), its `mismatch` record (`_mismatch.bogies`, with
    the unjudged defect's `signal_change` and the record errors' RMS where on), the measured
    `runs`, the recorded `tracks` and the `options`."""
    case = draw_case(cfg, index)
    on = set(cfg["imperfections"])
    bogie = _mismatch.bogies(
        on, case, fit_contact=cfg.get("fit_contact"), fit_wear=cfg.get("fit_wear")
    )
    nominal, truth, mismatch = bogie["nominal"], bogie["truth"], dict(bogie["mismatch"])
    model = nonlinear_options() if "nonlinear" in on else ModelOptions()
    duration = cfg["duration_s"]
    length = track_length(nominal, cfg["speed_range_m_s"][1], duration)
    refs = track_references(cfg["track_spectrum"], case["track_seeds"], length)

    def simulate(params):
        return clean_runs(
            params, refs, case["speeds"], duration=duration, sample_rate=cfg["sample_rate_hz"],
            model=model,
        )  # fmt: skip

    clean = simulate(truth)
    if bogie["without_unjudged"] is not None:
        without = simulate(bogie["without_unjudged"])
        mismatch["signal_change"] = _mismatch.signal_change(clean, without, case["noise_fraction"])
    runs = spoiled_runs(
        clean, case["noise_fraction"], case["noise_seed"], declared="channel-noise" not in on,
        bias=case["bias_fractions"] if "bias" in on else None,
        speed_errors=case["speed_errors"] if "speed" in on else None,
    )  # fmt: skip
    semi = value(nominal, "contact.contact_semi_distance")
    band = cfg.get("mismatch", {}).get("drift_band_m", _mismatch.DRIFT_BAND)
    errors, told, entries = _mismatch.record_errors(on, refs, case, semi, band)
    track_on = "track" in on
    tracks = record_tracks(
        refs, noise=cfg["track_noise_mm"] * 1e-3 if track_on else 0.0,
        offsets=case["offsets_m"] if track_on else [0.0] * len(refs), semi_distance=semi,
        errors=errors,
    )  # fmt: skip
    # the RMS the records' error is said to have: --track-error's and the track modes' together
    track_error = math.hypot(1e-3 * cfg.get("track_error_mm", 0.0), told)
    mismatch.update(entries, **({"track_error_told_m": track_error} if told else {}))
    nuisance = cfg.get("nuisance")  # absent: the monitor's default
    options = MonitorOptions(
        false_alarm_rate=cfg["false_alarm_rate"], track_error=track_error,
        nuisance=None if nuisance is None else tuple(nuisance),
        model=nonlinear_options() if cfg.get("fit_model") == "nonlinear" else ModelOptions(),
        **_jacobian_option(cfg.get("jacobian", "full")),
        **_refit_option(cfg.get("refit_model", "none")),
    )  # fmt: skip
    return dict(
        case=case, nominal=nominal, truth=truth, scenario=bogie["scenario"],
        changed=bogie["changed"], label=bogie["label"], mismatch=mismatch, runs=runs,
        tracks=tracks, options=options,
    )  # fmt: skip


def run_case(cfg: dict, index: int) -> dict:
    """Simulate case `index`, judge it with `monitor`, return its record."""
    on = set(cfg["imperfections"])
    track_on = "track" in on
    tic = time.perf_counter()
    record = {"case": draw_case(cfg, index), "config_hash": config_hash(cfg), "pid": os.getpid()}
    try:
        inputs = case_inputs(cfg, index)
        case, nominal, truth = inputs["case"], inputs["nominal"], inputs["truth"]
        record["simulate_s"] = time.perf_counter() - tic
        t0 = time.perf_counter()
        result = monitor(
            inputs["runs"], inputs["tracks"], params=nominal, options=inputs["options"]
        )
        record["monitor_s"] = time.perf_counter() - t0
    except Exception as e:  # a case that fails is recorded and counted, the run goes on
        record.update(error=f"{type(e).__name__}: {e}", wall_s=time.perf_counter() - tic)
        return record
    record["truth"] = {n: value(truth, n) for n in DEFAULT_CANDIDATES}
    record["nominal"] = {n: value(nominal, n) for n in DEFAULT_CANDIDATES}
    record["changed"] = list(inputs["changed"])
    record["scenario"] = inputs["label"]
    record["candidate_scenario"] = inputs["scenario"].name
    record["mismatch"] = inputs["mismatch"]
    record["verdicts"] = [verdict_record(v) for v in result.verdicts]
    record["explained"] = bool(result.explained)
    record["goodness"] = None if result.goodness is None else result.goodness.to_dict()
    record["fit"] = {
        "status": result.fit.status,
        "steps": result.fit.steps,
        "noise_variance": result.fit.noise_variance,
        "sigma2": result.fit.sigma2,
        "runs_used": result.fit.runs_used,
        "horizons": list(result.fit.horizons),
        "misfit_ratio": result.fit.misfit_ratio,
        "track_error_white_share": result.fit.track_error_white_share,
        "track_error_long_wave_share": result.fit.track_error_long_wave_share,
        "track_records_calibrated": result.fit.track_records_calibrated,
        "model": getattr(result.fit, "model", "linear"),
        "channel_noise": [list(c) for c in result.fit.channel_noise],
        "nuisance": {
            name: {key: float(p[key]) for key in ("estimate", "std_error", "nominal")}
            for name, p in result.fit.nuisance.items()
        },
    }
    record["runs"] = [
        {
            "speed_factor": r.speed_factor,
            "speed_factor_true": 1.0 / (1.0 + e) if "speed" in on else 1.0,
            "position_offset": r.position_offset,
            "position_offset_true": -o if track_on else 0.0,
        }
        for r, e, o in zip(result.runs, case["speed_errors"], case["offsets_m"])
    ]
    record["monitor_timings"] = dict(result.timings)
    record["wall_s"] = time.perf_counter() - tic
    return _finite(record)


EVIDENCE = (  # what a verdict's record keeps of its evidence, besides every std_error_* number
    "ci95_dof", "member_weights", "estimate_fitted", "track_record_bias",
    "track_record_bias_se", "track_record_bias_by_step", "not_explained", "withheld",
)  # fmt: skip


def verdict_record(v) -> dict:
    """A verdict as the record keeps it: name, verdict, estimate, standard error, interval,
    band, members, identifiability, tests, `watch`, the `EVIDENCE` entries and every numeric
    `std_error_*` entry of its evidence (its standard error's components, whichever the monitor
    reports)."""
    ev = v.evidence
    components = {
        k: float(x)
        for k, x in ev.items()
        if k.startswith("std_error_") and isinstance(x, (int, float, np.number))
        and not isinstance(x, bool)
    }  # fmt: skip
    return {
        "name": v.name,
        "verdict": v.verdict,
        "estimate": v.estimate,
        "std_error": v.std_error,
        "ci95": list(v.ci95),
        "healthy_band": list(v.band.healthy),
        "members": list(ev.get("members") or [v.name]),
        "identifiable": ev.get("identifiable", ""),
        "tests": ev.get("tests", []),
        **{k: ev.get(k) for k in EVIDENCE},
        **components,
        "watch": v.watch,
    }


def _finite(x):
    """JSON-safe: non-finite floats as None."""
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def config_hash(cfg: dict) -> str:
    return hashlib.sha256(json.dumps(cfg, sort_keys=True).encode()).hexdigest()[:12]


# --- records on disk: one JSON line per finished case ---


def jsonl_path(out: str, shard: tuple[int, int]) -> Path:
    i, n = shard
    return FOLDER / (f"{out}.jsonl" if n == 1 else f"{out}.shard{i}of{n}.jsonl")


def load_records(out: str, cfg: dict) -> dict[int, dict]:
    """Every record of `<out>.jsonl` and `<out>.shard*.jsonl` (by case index); a record of
    another configuration raises (use another `--out`)."""
    want, records = config_hash(cfg), {}
    for path in sorted(FOLDER.glob(f"{out}.jsonl")) + sorted(FOLDER.glob(f"{out}.shard*.jsonl")):
        for line in path.read_text().splitlines():
            if not line.strip():
                continue
            try:
                rec = json.loads(line)
            except json.JSONDecodeError:
                continue  # a line cut short by a killed process: its case runs again
            if rec.get("config_hash") != want:
                raise SystemExit(
                    f"{path} holds cases of another configuration (hash "
                    f"{rec.get('config_hash')}, this run {want}): pass another --out or move it"
                )
            records[rec["case"]["index"]] = rec
    return records


_DONE_HERE = [0]  # cases this process has run: the first one compiles


def _worker(job):
    cfg, index = job
    _DONE_HERE[0] += 1
    rec = run_case(cfg, index)
    rec["process_case_number"] = _DONE_HERE[0]
    return rec


def _pin_worker(free_cores) -> None:
    """Pool initializer: pin this worker process to the core it takes from `free_cores`.

    With one XLA thread per worker, unpinned workers still migrate across the cores and
    contend with each other; on a 2-core machine they ran 1.6-2x slower than two processes
    pinned with `taskset` (benchmarks/README.md, the 8 s split runs). `None`, or no core left
    (a worker the pool started in place of one that died), leaves it free.
    """
    import queue

    try:
        core = free_cores.get(timeout=5.0)
    except queue.Empty:
        return
    if core is not None:
        os.sched_setaffinity(0, {core})


def _worker_pool(workers: int):
    """A spawn pool of `workers` processes, each pinned to a core of its own where the
    cores this process may use suffice (Linux); otherwise left to the scheduler."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    cores = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_setaffinity") else []
    free_cores = ctx.Queue()
    for k in range(workers):
        free_cores.put(cores[k] if workers <= len(cores) else None)
    return ctx.Pool(workers, initializer=_pin_worker, initargs=(free_cores,))


def run_cases(args, cfg) -> None:
    done = load_records(args.out, cfg)
    i, n = args.shard
    todo = [k for k in range(args.cases) if k % n == i and k not in done]
    if args.scenarios:  # a rerun of the cases drawn with these scenarios alone
        todo = [k for k in todo if draw_case(cfg, k)["scenario"] in args.scenarios]
    if args.only:  # a rerun of these cases alone
        todo = [k for k in todo if k in args.only]
    print(
        f"{args.out}: {len(done)} cases on record, {len(todo)} to run in shard {i}/{n} "
        f"with {args.workers} worker(s); imperfections: {', '.join(args.imperfections) or 'none'}",
        flush=True,
    )
    if not todo:
        return
    path = jsonl_path(args.out, args.shard)
    path.parent.mkdir(parents=True, exist_ok=True)
    tic = time.perf_counter()
    jobs = [(cfg, k) for k in todo]
    with path.open("a") as f:

        def save(rec, count):
            f.write(json.dumps(rec) + "\n")
            f.flush()
            os.fsync(f.fileno())
            c = rec["case"]
            status = rec.get("error") or ", ".join(
                f"{v['name']} {v['verdict']}" for v in rec["verdicts"] if v["verdict"] in ALARMS
            )
            print(
                f"[{count}/{len(todo)} {time.perf_counter() - tic:.0f} s] case {c['index']} "
                f"{c['scenario']}: {status or 'no alarm'} ({rec.get('wall_s', 0):.1f} s)",
                flush=True,
            )

        if args.workers == 1:
            for count, job in enumerate(jobs, start=1):
                save(_worker(job), count)
        else:
            # one XLA thread per worker process, one core per worker: the workers fill the cores
            flags = os.environ.get("XLA_FLAGS", "")
            os.environ["XLA_FLAGS"] = f"{flags} --xla_cpu_multi_thread_eigen=false".strip()
            with _worker_pool(args.workers) as pool:
                for count, rec in enumerate(pool.imap_unordered(_worker, jobs), start=1):
                    save(rec, count)


# --- aggregates ---


def judged(rec: dict):
    """(verdict, relative estimate, relative truth, covered) per judged verdict of a record
    (finite standard error); a group's nominal is its members' mean and its truth that times
    the weighted mean of the members' true values relative to nominal (its `member_weights`,
    else equal weights), and the verdict gets `equal`: whether its members' true values are
    equal (the weights matter only where they are not)."""
    for v in rec["verdicts"]:
        if v["std_error"] is None or v["estimate"] is None:
            continue
        truths = [rec["truth"][m] for m in v["members"]]
        nom = _nominal(rec, v)
        true = group_value(v["members"], rec["truth"], rec["nominal"], v.get("member_weights"))
        lo, hi = v["ci95"]
        v = {**v, "equal": bool(np.ptp(truths) <= 1e-9 * abs(true))}
        yield v, v["estimate"] / nom - 1, true / nom - 1, bool(lo <= true <= hi)


def _nominal(rec: dict, v: dict) -> float:
    return float(np.mean([rec["nominal"][m] for m in v["members"]]))


MEAN_ABS_PER_STD = math.sqrt(2.0 / math.pi)  # E|e| / sigma for a normal error e


def implied_mae(rec: dict, v: dict) -> tuple[float, float]:
    """The absolute error of the relative estimate that the verdict's standard error implies
    (E|e| of a normal error), in all and from its residual (Gauss-Newton) term alone."""
    nom = _nominal(rec, v)
    residual = v.get("std_error_gauss_newton", v["std_error"])
    residual = v["std_error"] if residual is None else residual
    return MEAN_ABS_PER_STD * v["std_error"] / nom, MEAN_ABS_PER_STD * residual / nom


def on_watch(v: dict) -> bool:
    """The verdict's `watch` flag (95 % interval outside the band, no alarm); for records made
    before it was stored, the same rule (`bogie_jax.monitor.judge`) from the stored values."""
    if "watch" in v:
        return bool(v["watch"])
    if v["verdict"] in ALARMS or v["identifiable"] == "no" or v["std_error"] is None:
        return False
    return interval_outside(v["ci95"], v["healthy_band"]) is not None


def case_outcome(rec: dict) -> dict:
    alarms = [v for v in rec["verdicts"] if v["verdict"] in ALARMS]
    watched = [v for v in rec["verdicts"] if on_watch(v)]
    changed = set(rec["changed"])
    right = [v for v in alarms if changed & set(v["members"])]
    wrong = [v for v in alarms if not changed & set(v["members"])]
    size = [abs(e - t) for v, e, t, _ in judged(rec) if changed & set(v["members"])]
    return {
        "alarm": bool(alarms),
        "correct": bool(right),
        "wrong": bool(wrong),
        "watch_changed": any(changed & set(v["members"]) for v in watched),
        "watch_other": any(not changed & set(v["members"]) for v in watched),
        "size_error": float(np.mean(size)) if size else None,
    }


def aggregate(records: dict[int, dict], cfg: dict) -> tuple[dict, str]:
    ok = [r for r in records.values() if "error" not in r]
    failed = [r for r in records.values() if "error" in r]
    by_type: dict[str, list] = {}
    for r in ok:  # the case's label: its scenario, or with an unjudged defect what it holds
        by_type.setdefault(r.get("scenario", r["case"]["scenario"]), []).append(r)
    rows, summary = [], {"by_type": {}, "by_element": {}}
    for name in ("healthy", *DEFECTS, *sorted(set(by_type) - {"healthy", *DEFECTS})):
        recs = by_type.get(name, [])
        if not recs:
            continue
        out = [case_outcome(r) for r in recs]
        n, alarms = len(out), sum(o["alarm"] for o in out)
        correct = sum(o["correct"] for o in out if o["alarm"])
        wrong = sum(o["wrong"] for o in out)
        watch = (sum(o["watch_changed"] for o in out), sum(o["watch_other"] for o in out))
        sizes = [o["size_error"] for o in out if o["size_error"] is not None]
        cover = [c for r in recs for _, _, _, c in judged(r)]
        mae = f"{100 * np.mean(sizes):.1f}" if sizes else "-"
        time_s = float(np.median([r["wall_s"] for r in recs]))
        summary["by_type"][name] = {
            "cases": n, "alarms": alarms, "correct_element": correct,
            "wrong_element_alarms": wrong, "size_mae": float(np.mean(sizes)) if sizes else None,
            "covered": int(sum(cover)), "judged": len(cover), "median_wall_s": time_s,
            "watch_changed": watch[0], "watch_other": watch[1],
        }  # fmt: skip
        if name == "healthy":
            rows.append(
                f"| healthy | {n} | false alarm {rate(alarms, n)} | - | {wrong} | - / {watch[1]} "
                f"| - | {rate(sum(cover), len(cover))} | {time_s:.0f} |"
            )
        else:
            rows.append(
                f"| {name} | {n} | {rate(alarms, n)} | {rate(correct, alarms)} | {wrong} | "
                f"{watch[0]} / {watch[1]} | {mae} |"
                f" {rate(sum(cover), len(cover))} | {time_s:.0f} |"
            )
    elem_rows = []
    group_names = sorted(
        {v["name"] for r in ok for v, *_ in judged(r) if v["identifiable"] != "alone"}
    )
    selections = {
        **{n: lambda v, n=n: v["name"] == n and v["identifiable"] == "alone"
           for n in DEFAULT_CANDIDATES},
        "all elements (alone)": lambda v: v["identifiable"] == "alone",
        "groups (all)": lambda v: v["identifiable"] != "alone",
        **{f"{n} (group)": lambda v, n=n: v["name"] == n for n in group_names},
        "groups, members equal in truth": lambda v: v["identifiable"] != "alone" and v["equal"],
        "groups, members differ in truth": lambda v: v["identifiable"] != "alone"
        and not v["equal"],
    }  # fmt: skip
    for label, chosen in selections.items():
        per = [(r, v, e, t, c) for r in ok for v, e, t, c in judged(r) if chosen(v)]
        if not per:
            continue
        err = [abs(e - t) for _, _, e, t, _ in per]
        cov = sum(c for *_, c in per)
        implied = np.mean([implied_mae(r, v) for r, v, *_ in per], axis=0)
        summary["by_element"][label] = {
            "judged": len(per), "covered": int(cov), "mae": float(np.mean(err)),
            "alarms": sum(v["verdict"] in ALARMS for _, v, *_ in per),
            "mae_implied": float(implied[0]), "mae_implied_residual_term": float(implied[1]),
        }  # fmt: skip
        elem_rows.append(
            f"| {label} | {len(per)} | {100 * np.mean(err):.2f} | {100 * implied[0]:.2f} | "
            f"{100 * implied[1]:.2f} | {rate(cov, len(per))} |"
        )
    walls = [r["wall_s"] for r in ok]
    first = [r["wall_s"] for r in ok if r.get("process_case_number") == 1]
    later = [r["wall_s"] for r in ok if r.get("process_case_number", 1) > 1]
    summary.update(
        cases=len(records), errors=len(failed), median_wall_s=float(np.median(walls or [0])),
        median_first_case_wall_s=float(np.median(first)) if first else None,
        median_later_case_wall_s=float(np.median(later)) if later else None,
    )  # fmt: skip
    imps = ", ".join(cfg["imperfections"]) or "none"
    md_targets = targets(summary)
    summary["mismatch"], mismatch_md = _mismatch_report.report(
        ok, [case_outcome(r) for r in ok], summary["by_element"], HEADLINE, rate
    )
    md = [
        f"# Detection benchmark: {len(records)} cases, imperfections: {imps}",
        "",
        f"Seed {cfg['seed']}; two runs per case of {cfg['duration_s']:g} s at "
        f"{cfg['sample_rate_hz']:g} Hz, speeds {cfg['speed_range_m_s'][0]:g}-"
        f"{cfg['speed_range_m_s'][1]:g} m/s, noise {100 * cfg['noise_range'][0]:g}-"
        f"{100 * cfg['noise_range'][1]:g} % of each channel's RMS, false-alarm rate "
        f"{cfg['false_alarm_rate']:g}"
        + (
            f", the records' {cfg['track_error_mm']:g} mm error given to `monitor` (`track_error`)"
            if cfg.get("track_error_mm")
            else ""
        )
        + f"; {len(failed)} cases failed to run.",
        "",
        "| defect | cases | detected | correct element (of detected) | wrong-element alarms | "
        "on watch: changed / other | size MAE [%] | 95 % coverage | median s |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
        *rows,
        "",
        "Rates with their Wilson 95 % interval in %. Size MAE: mean absolute error of the "
        "estimated relative change of the changed element(s) [percentage points]; coverage: "
        "share of judged elements (finite standard error) whose 95 % interval holds the truth. "
        "On watch: cases with an element flagged `watch` (its 95 % interval outside the band, no "
        "alarm: `Verdict.watch`) among the changed elements / among the others.",
        "",
        "| element (identifiable alone) | judged | MAE [%] | implied by the standard errors [%] "
        "| by their residual term [%] | 95 % coverage |",
        "| --- | ---: | ---: | ---: | ---: | ---: |",
        *elem_rows,
        "",
        "Implied MAE: sqrt(2/pi) times the mean relative standard error (the mean absolute "
        "error of a normal error of that spread); residual term: the Gauss-Newton standard "
        "error alone, without the track record's error (the same where it is not given).",
        "",
        *md_targets,
        "",
        *mismatch_md,
        "",
        f"Wall time per case: median {summary['median_wall_s']:.0f} s; first case of a process "
        f"(compiles) {_s(summary['median_first_case_wall_s'])}, later cases "
        f"{_s(summary['median_later_case_wall_s'])}.",
    ]
    if failed:
        md += ["", "Failed cases: " + "; ".join(
            f"{r['case']['index']} ({r['error'][:120]})" for r in failed)]  # fmt: skip
    return summary, "\n".join(md) + "\n"


def targets(summary: dict) -> list[str]:
    """The targets of issue 19, item 6, each with the measured figure and met / not met."""
    head = summary["by_type"].get(HEADLINE)
    healthy = summary["by_type"].get("healthy")
    alarms = sum(t["alarms"] for n, t in summary["by_type"].items() if n != "healthy")
    correct = sum(t["correct_element"] for n, t in summary["by_type"].items() if n != "healthy")
    alone = {k: v for k, v in summary["by_element"].items() if k in DEFAULT_CANDIDATES}
    allv = summary["by_element"].get("all elements (alone)")
    cover = [v["covered"] / v["judged"] for v in alone.values()]

    def line(what, ok, figure):
        return f"- {what}: {figure}, {'met' if ok else 'not met'}"

    out = [
        "Targets (issue 19, item 6; 'met' compares the point estimate, see the intervals above):",
        "",
    ]
    rows = []  # (target, met, figure, n, note)
    if head:
        rate, n = head["alarms"] / head["cases"], head["cases"]
        rows.append((f"{HEADLINE} detected in >= 95 %", rate >= 0.95, rate, n, ""))
    if healthy:
        rate, n = healthy["alarms"] / healthy["cases"], healthy["cases"]
        rows.append(("false alarms on healthy bogies <= 5 %", rate <= 0.05, rate, n, ""))
    if alarms:
        rate = correct / alarms
        rows.append(("correct element in >= 95 % of detections", rate >= 0.95, rate, alarms, ""))
    if allv:
        what = "MAE of relative changes <= 2.5 % (identifiable alone)"
        note = (
            f"; the standard errors imply {100 * allv['mae_implied']:.1f} %, their residual "
            f"term alone {100 * allv['mae_implied_residual_term']:.1f} %"
        )
        rows.append((what, allv["mae"] <= 0.025, allv["mae"], allv["judged"], note))
    out += [line(what, ok, f"{100 * x:.1f} % (n = {n}{note})") for what, ok, x, n, note in rows]
    if cover:
        ok = all(0.9 <= c <= 0.98 for c in cover)
        counts = {k: (v["covered"], v["judged"]) for k, v in alone.items()}
        figure = (
            f"{100 * min(cover):.0f}-{100 * max(cover):.0f} % over {len(cover)} elements; "
            f"{coverage_reading(counts)}"
        )
        out.append(line("95 % coverage in 90-98 % for every element", ok, figure))
    groups = {k: v for k, v in summary["by_element"].items() if k.endswith(" (group)")}
    if groups:  # a group's verdict is what the engineer reads where the members are tied
        cover = {k.removesuffix(" (group)"): v["covered"] / v["judged"] for k, v in groups.items()}
        ok = all(0.9 <= c <= 0.98 for c in cover.values())
        figure = ", ".join(f"{k} {100 * c:.0f} %" for k, c in cover.items())
        out.append(line("95 % coverage in 90-98 % for every group", ok, figure))
    return out


def _s(x):
    return "-" if x is None else f"{x:.0f} s"


def _indices(text: str) -> tuple[int, ...]:
    """`--only`'s case indices, comma-separated."""
    try:
        return tuple(int(x) for x in text.split(",") if x)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of cases")


def parse_args(argv=None) -> argparse.Namespace:
    """The command line's arguments, checked (`SystemExit` naming one out of range), with the
    imperfections, nuisance names, ranges, case count, results stem and shard resolved."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cases", type=int, default=None, help="cases (default 100; 30 for a mode "
                   "other than default)")  # fmt: skip
    p.add_argument("--seed", type=int, default=0)
    names = ", ".join((*IMPERFECTIONS, *ALIASES))
    p.add_argument(
        "--imperfection", default="default", help=f"comma-separated: {names} (default: default)"
    )
    p.add_argument("--shard", default="0/1", help="i/n: run the cases with index %% n == i")
    p.add_argument(
        "--scenario", dest="scenarios", default="", help="comma-separated: run only the cases "
        f"drawn with these scenarios ({', '.join(DEFECT_SCENARIOS)}; default: every case)",
    )  # fmt: skip
    p.add_argument(
        "--only", type=_indices, default=(), metavar="I,J,...",
        help="run only these cases (default: every case)",
    )  # fmt: skip
    p.add_argument("--workers", type=int, default=1, help="processes (default 1)")
    p.add_argument("--duration", type=float, default=1.0, help="run duration [s] (default 1)")
    p.add_argument("--sample-rate", type=float, default=100.0, help="[Hz] (default 100)")
    p.add_argument("--speed-range", default="30,60", help="[m/s] (default 30,60)")
    p.add_argument("--noise-range", default="0.01,0.03", help="noise std / channel RMS")
    p.add_argument("--track-spectrum", default="erri-low")
    p.add_argument("--track-noise", type=float, default=0.3, help="record error RMS [mm]")
    p.add_argument("--max-offset", type=float, default=0.5, help="record offset bound [m]")
    p.add_argument(
        "--track-error", type=float, default=0.0,
        help="record error RMS [mm] given to monitor, carried into its intervals (default 0: "
        "records taken as exact; --track-noise's value tells it the truth)",
    )  # fmt: skip
    p.add_argument("--max-speed-error", type=float, default=0.01, help="relative bound")
    p.add_argument("--bias", type=float, default=0.05, help="bias bound / channel RMS")
    p.add_argument("--max-wear", type=float, default=0.3, help="cone slope factor 1 +- this")
    p.add_argument(
        "--nuisance", default=None, help="monitor's nuisance parameters: comma-separated names, "
        "or `none` (default: the monitor's, the contact's model-form parameters)",
    )  # fmt: skip
    p.add_argument(
        "--fit-model", choices=("linear", "nonlinear"), default="linear",
        help="the monitor's model: `linear` (default, `ModelOptions()`) or `nonlinear` (creep "
        "saturation and blow-off anti-yaw dampers, `nonlinear_options()`)",
    )  # fmt: skip
    p.add_argument(
        "--fit-contact", choices=_mismatch.CONTACT_NAMES, default=None,
        help="the contact of the monitor's model (default: the mode's, the cone unless "
        "worn-profile or half-worn-profile: s1002-uic60)",
    )  # fmt: skip
    p.add_argument(
        "--fit-wear", type=float, default=None, metavar="LEVEL",
        help="the monitor's model carries a wheel wear at LEVEL in (0, 1] (the s1002-uic60 "
        "table blended towards the worn wheel's), which it fits (default: none)",
    )  # fmt: skip
    p.add_argument(
        "--drift-band", type=_band, default=None, metavar="LO,HI",
        help="[m] the track-drift mode's wavelength band (default 70,200: EN 13848 D3)",
    )  # fmt: skip
    p.add_argument(
        "--jacobian", choices=("small-motion", "full"), default="small-motion",
        help="the model of the monitor's Jacobians (`MonitorOptions.jacobian`; records without "
        "this key in their configuration were judged with `full`)",
    )  # fmt: skip
    p.add_argument(
        "--refit-model", choices=("nonlinear", "none"), default="nonlinear",
        help="the model fitted where the first fit does not explain the data "
        "(`MonitorOptions.refit_model`; records without this key in their configuration: none)",
    )  # fmt: skip
    p.add_argument("--false-alarm-rate", type=float, default=0.05)
    p.add_argument("--out", default=None, help="results stem (default from the imperfections)")
    p.add_argument("--report", action="store_true", help="only aggregate the records")
    p.add_argument(
        "--paired-with", default=None, metavar="COMMIT[:OUT]",
        help="compare case by case with the records of OUT (default: --out) committed at COMMIT",
    )  # fmt: skip
    args = p.parse_args(argv)
    args.imperfections = parse_imperfections(args.imperfection)
    if args.nuisance is not None:
        args.nuisance = () if args.nuisance == "none" else tuple(args.nuisance.split(","))
    args.speed_range = tuple(float(x) for x in args.speed_range.split(","))
    args.noise_range = tuple(float(x) for x in args.noise_range.split(","))
    default_mode = args.imperfections == ALIASES["default"]
    args.cases = args.cases if args.cases is not None else (100 if default_mode else 30)
    args.out = args.out or stem(args.imperfections)
    try:
        i, n = (int(x) for x in args.shard.split("/"))
        assert 0 <= i < n
    except (ValueError, AssertionError):
        raise SystemExit(f"--shard = {args.shard!r} must be i/n with 0 <= i < n") from None
    args.shard = (i, n)
    args.scenarios = tuple(x for x in args.scenarios.split(",") if x)
    unknown = [x for x in args.scenarios if x not in DEFECT_SCENARIOS]
    if unknown:
        raise SystemExit(f"--scenario {unknown[0]!r} is not one of {', '.join(DEFECT_SCENARIOS)}")
    checks = (
        ("--cases", args.cases, args.cases >= 1),
        ("--workers", args.workers, args.workers >= 1),
        ("--speed-range", args.speed_range, 0 < args.speed_range[0] <= args.speed_range[-1]),
        ("--noise-range", args.noise_range, 0 < args.noise_range[0] <= args.noise_range[-1]),
        ("--max-wear", args.max_wear, 0 <= args.max_wear < 1),
        ("--fit-wear", args.fit_wear, args.fit_wear is None or 0 < args.fit_wear <= 1),
    )
    for name, given, ok in checks:
        if not ok:
            raise SystemExit(f"{name} = {given!r} is out of range")
    return args


def _band(text: str) -> tuple[float, float]:
    """`LO,HI` [m] with 0 < LO < HI."""
    try:
        lo, hi = (float(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LO,HI in m, got {text!r}") from None
    if not 0 < lo < hi:
        raise argparse.ArgumentTypeError(f"expected 0 < LO < HI, got {text!r}")
    return lo, hi


def main(argv=None):
    args = parse_args(argv)
    cfg = config_of(args)
    if not args.report:
        run_cases(args, cfg)
    records = load_records(args.out, cfg)
    records = {k: r for k, r in records.items() if k < args.cases}
    if not records:
        raise SystemExit(f"no records of {args.out} yet")
    summary, md = aggregate(records, cfg)
    if args.paired_with:
        commit, _, stem = args.paired_with.partition(":")
        earlier = _paired.committed_records(commit, FOLDER, stem or args.out)
        name = f"the records of `{stem or args.out}` committed at {commit}"
        summary["paired"], lines = _paired.compare(records, earlier, name)
        shared = summary["paired"]["shared"]
        if shared:

            def on_shared(recs):
                return aggregate({k: recs[k] for k in shared}, cfg)[0]

            lines += _paired.side_by_side(
                on_shared(records), on_shared(earlier), "the earlier records"
            )
        md = md + "\n" + "\n".join(lines) + "\n"
    ordered = [records[k] for k in sorted(records)]
    # only aggregated again: the environment stays that of the run that measured the records
    previous = FOLDER / f"{args.out}.json"
    env = (
        json.loads(previous.read_text()).get("environment")
        if args.report and previous.exists()
        else None
    )
    write_outputs(
        f"detection/{args.out}", ordered, md, extra={"config": cfg, "summary": summary}, env=env
    )


if __name__ == "__main__":
    main()
