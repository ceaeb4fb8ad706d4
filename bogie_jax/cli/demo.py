"""`bogie-jax demo`: the package's main job on embedded defaults: a bogie with one anti-yaw
damper at 50 %, measured on two runs at different speeds with sensor noise, judged by
`bogie_jax.monitor.monitor` against an imperfect record of the track.

The track record: the fit uses the track as a recording car would have measured it, not the
true one: the true irregularity plus a recording error of `--track-noise` RMS per channel, and
positioned `--track-offset` metres wrong along the track. The recording error is a second,
independent realisation of the same spectrum (`TrackReference` with another seed) scaled to
that RMS (the cross level to the level difference of the two rails over the contact distance
2 b_0): an error spectrum shaped like the track's (`bogie_jax.monitor.recorded_track`). The
demo knows that error's level and passes it to `monitor` (`track_error`), which carries it
into the intervals.

`--candidates NAME...` chooses the elements judged; `--list-elements` prints the names it takes
and exits (`_candidates.py`).
"""

import datetime
import math
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from ..io import check_date, save_measurement, save_track_csv
from ..monitor import (
    MonitorOptions,
    RunSpec,
    compile_programs,
    group_value,
    monitor,
    recorded_track,
    scenario_layout,
    scenario_measurements,
)
from ..params import get_parameter, manchester_benchmark
from ._candidates import add_options, check_candidates, list_elements
from ._common import UsageError, split_names
from ._monitor_output import fitted_signals, verdict_table, write_outputs
from ._names import lookup, names


DEFAULT_SCENARIO = "yaw-damper-left-50"


def add_parser(sub):
    p = sub.add_parser(
        "demo",
        help="condition monitoring end to end: a bogie with a worn anti-yaw damper -> verdicts",
        description="Simulate two measurement runs of a bogie whose left anti-yaw damper is at "
        "50 % (sensor noise, an imperfect track record), judge every suspension element with "
        "bogie_jax.monitor.monitor, print the verdict table and write verdicts.json, "
        "verdicts.png, signals.png and report.md to --out.",
    )
    p.add_argument("--out", default="demo_out", help="output directory (default demo_out)")
    p.add_argument(
        "--scenario",
        default=DEFAULT_SCENARIO,
        help=f"defect scenario: {', '.join(names('defect'))} (default {DEFAULT_SCENARIO})",
    )
    p.add_argument(
        "--speeds", default="30,50", help="comma-separated run speeds [m/s] (default 30,50)"
    )
    p.add_argument(
        "--duration",
        type=float,
        default=1.0,
        help="duration of each run [s] (default 1.0; shorter runs, e.g. 0.5, are quicker and "
        "less precise: the tests use them)",
    )
    p.add_argument(
        "--sample-rate", type=float, default=100.0, help="sample rate [Hz] (default 100)"
    )
    p.add_argument(
        "--noise",
        type=float,
        default=1.0,
        help="sensor noise as a multiple of each sensor's noise std (default 1; 0 = noise-free)",
    )
    p.add_argument(
        "--track-noise",
        type=float,
        default=0.3,
        help="RMS error of the track record per channel [mm] (default 0.3; 0 = exact)",
    )
    p.add_argument(
        "--track-offset",
        type=float,
        default=0.1,
        help="distance offset of the track record [m] (default 0.1; 0 = exact)",
    )
    p.add_argument("--seed", type=int, default=0, help="PRNG seed of noise and tracks (default 0)")
    p.add_argument(
        "--false-alarm-rate",
        type=float,
        default=0.05,
        help="probability of any false alarm on a healthy bogie (default 0.05)",
    )
    p.add_argument("--date", default=None, help="date of the run, YYYY-MM-DD (default today)")
    add_options(p)
    return p


def _check(args, params):
    """Every check that needs no evaluation; returns (scenario, runs, date, candidates)."""
    candidates = check_candidates(params, args.candidates)
    try:
        speeds = [float(s) for s in split_names(args.speeds)]
    except ValueError:
        raise UsageError(
            f"`--speeds` must be comma-separated numbers, got {args.speeds!r}"
        ) from None
    if not speeds:
        raise UsageError("`--speeds` is empty: give at least one speed [m/s]")
    for name, value, ok, valid in (
        ("--track-noise", args.track_noise, 0 <= args.track_noise <= 10, "in [0, 10] mm"),
        ("--track-offset", args.track_offset, abs(args.track_offset) <= 10, "in [-10, 10] m"),
        ("--noise", args.noise, 0 <= args.noise < math.inf, ">= 0"),
    ):
        if not ok:
            raise UsageError(f"`{name}` = {value!r} must be {valid}")
    if args.duration > 10:
        raise UsageError(f"`--duration` = {args.duration:g} s must be at most 10 s")
    try:
        scenario = lookup("defect", args.scenario, "--scenario")
        runs = tuple(
            RunSpec(
                speed=v,
                duration=args.duration,
                sample_rate=args.sample_rate,
                seed=args.seed + 1 + k,
                noise_scale=args.noise,
            )  # fmt: skip
            for k, v in enumerate(speeds)
        )
        date = check_date(args.date)
        if not 0 < args.false_alarm_rate < 0.5:
            raise ValueError(
                f"`--false-alarm-rate` = {args.false_alarm_rate!r} must lie in (0, 0.5)"
            )
    except ValueError as e:
        raise UsageError(str(e)) from None
    return scenario, runs, date, candidates


def _truth(scenario, params) -> dict:
    truth = scenario.true_params(params)
    return {e: float(np.asarray(get_parameter(truth, e))) for e in scenario.elements}


def truth_check(result, scenario, params) -> str:
    """One line comparing the verdicts with the hidden truth of the synthetic data: correct
    alarms, false alarms, missed damage (the true value outside the healthy band), and how
    many 95 % intervals hold the true value (a group's truth: the weighted mean of its
    members relative to nominal, with the weights its verdict reports, times its nominal)."""
    truth = scenario.true_params(params)
    correct, false, missed, covered, judged = [], [], [], 0, 0
    for v in result.verdicts:
        members = v.evidence.get("members") or [v.name]
        true_values, nominals = (
            {m: float(np.asarray(get_parameter(p, m))) for m in members} for p in (truth, params)
        )
        value = group_value(members, true_values, nominals, v.evidence.get("member_weights"))
        lo, hi = v.band.healthy
        damaged = not lo <= value <= hi
        alarm = v.verdict in ("degraded", "failed")
        if alarm:
            (correct if damaged else false).append(v.name)
        elif damaged:
            missed.append(v.name)
        if np.isfinite(v.std_error) and v.evidence.get("identifiable") != "no":
            judged += 1
            covered += bool(v.ci95[0] <= value <= v.ci95[1])
    say = lambda names: ", ".join(f"`{n}`" for n in names) or "none"
    return (
        f"Against the hidden truth: correct alarms {say(correct)}; false alarms {say(false)}; "
        f"missed {say(missed)}; the true value lies inside the 95 % interval for {covered} of "
        f"{judged} judged elements."
    )


def _simulate(args, scenario, runs, params, progress, monitored):
    """The runs' measurements, simulated while `monitor`'s programs for them compile in a
    thread of their own (`compile_programs` on `monitored` = (layout, tracks, options): the
    programs do not need the data, and the two compiles share the cores)."""
    import jax.random as jr

    layout, tracks, options = monitored
    progress.compiling(
        "the simulation of the measurement runs and, beside it, the monitor's programs"
    )
    with ThreadPoolExecutor(1) as pool:
        compiled = pool.submit(compile_programs, layout, tracks, params=params, options=options)
        try:
            key = jr.PRNGKey(args.seed) if args.noise > 0 else None
            measurements = scenario_measurements(scenario, runs, params=params, key=key)
        except (ValueError, RuntimeError) as e:
            raise UsageError(str(e)) from None
        progress.done(len(runs), len(runs), "simulated runs")
        compiled.result()
    return measurements


def run(args, progress) -> int:
    params = manchester_benchmark()
    if args.list_elements:
        progress.say(list_elements(params))
        return 0
    scenario, runs, date, candidates = _check(args, params)
    speeds = ", ".join(f"{r.speed:g}" for r in runs)
    progress.say(
        f"demo: {scenario.description or scenario.name}; {len(runs)} runs at {speeds} m/s, "
        f"{args.duration:g} s each at {args.sample_rate:g} Hz, sensor noise x{args.noise:g}"
    )
    semi = float(np.asarray(params.contact.contact_semi_distance))
    noise_m = args.track_noise * 1e-3
    layout = scenario_layout(runs, params=params)
    tracks = [
        recorded_track(m.track, noise=noise_m, offset=args.track_offset, semi_distance=semi)
        for m in layout
    ]
    # the record's error is known here: carried into the intervals
    options = MonitorOptions(
        candidates=candidates, false_alarm_rate=args.false_alarm_rate, track_error=noise_m
    )
    measurements = _simulate(args, scenario, runs, params, progress, (layout, tracks, options))
    record_note = (
        f"track record: the fit uses the true track plus a recording error of "
        f"{args.track_noise:g} mm RMS per channel (spectrum-shaped), {args.track_offset:g} m "
        "off in distance"
        if args.track_noise or args.track_offset
        else "track record: the fit uses the exact track"
    )
    progress.say(record_note)
    result = monitor(
        measurements, tracks, params=params, options=options,
        progress=lambda line: progress.say(f"  {line}"),
    )  # fmt: skip
    progress.say(verdict_table(result))
    equations = options.fitted_model(result.fit.model_refit)
    fitted = fitted_signals(result, measurements, tracks, params, progress, equations=equations)
    truth = _truth(scenario, params)
    check = truth_check(result, scenario, params)
    progress.say(check.replace("`", ""))
    notes = [
        f"Synthetic data: {scenario.name} ({scenario.description}); true values "
        + (", ".join(f"`{k}` = {v:.4g}" for k, v in truth.items()) or "all nominal")
        + "; every other element nominal.",
        check,
        f"Sensor noise x{args.noise:g} of each sensor's noise std; seed {args.seed}.",
        record_note[0].upper() + record_note[1:] + ".",
        f"Process CPU time {time.process_time():.0f} s (wall {progress.elapsed():.0f} s) up to "
        "the report.",
    ]
    extra = {
        "scenario": scenario.to_dict(),
        "truth": truth,
        "track_record": {"noise_mm": args.track_noise, "offset_m": args.track_offset},
    }
    source = (
        f"bogie-jax demo: synthetic runs at {speeds} m/s of a bogie with {scenario.description}"
    )
    data = Path(args.out) / "data"
    data.mkdir(parents=True, exist_ok=True)
    files = [str(save_measurement(data / f"run{k}.csv", m)) for k, m in enumerate(measurements)]
    records = [str(data / f"track{k}.csv") for k in range(len(tracks))]
    for path, track in zip(records, tracks):
        save_track_csv(path, track)
    notes.append(
        "The runs and the track record are in `data/`; judge them again from the files with "
        f"`bogie-jax monitor --data {' '.join(files)} --track {' '.join(records)}`."
    )
    paths = write_outputs(
        args.out, result, measurements, fitted, date=date, source=source, notes=notes,
        extra=extra, progress=progress,
    )  # fmt: skip
    progress.say(f"wrote the runs and the track record to {data}/")
    progress.say("wrote " + ", ".join(str(p) for p in paths))
    progress.say(
        f"total {progress.elapsed():.0f} s wall, {time.process_time():.0f} s process CPU "
        f"({datetime.datetime.now():%H:%M:%S})"
    )
    return 0
