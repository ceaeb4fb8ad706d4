"""Critical speeds of the Manchester vehicle 1: linear and nonlinear, cone and real profiles.

For each contact (the default 1:20 cone, S1002 on UIC60 1:40, the measured worn wheel on UIC60
1:40) with and without anti-yaw dampers:
- the linear critical speed and hunting frequency (`bogie_jax.model.critical_speed`: the
  eigenvalues of the equations linearised at the centred position, linear creep);
- the nonlinear critical speed by a speed ramp-down from a hunting limit cycle
  (`bogie_jax.hunting.ramp_from_linear`: saturated creep, blow-off dampers, flange springs on
  the cone (a table holds the flange in its geometry), an ideal track; a 5 mm kick grown for
  30 s into a cycle 6 m/s above the linear critical speed, or at 150 m/s where the bogie is
  linearly stable there, then 81 speeds in 0.5 m/s steps, each run 8 s from the last state of
  the one before).
The bifurcation is called subcritical where the cycle lives on more than 1 m/s below the linear
critical speed, supercritical where it dies within 1 m/s of it.

Run: `python benchmarks/critical_speeds.py` (about 10 minutes on 2 cores); writes
results/critical_speeds/linear_and_ramp_down.{json,md}.
"""

import sys
import time
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)

import numpy as np

import bogie_jax as bj
from bogie_jax.hunting import ramp_from_linear
from bogie_jax.model import critical_speed
from bogie_jax.params import set_parameters


sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks._common import write_outputs  # noqa: E402


CONTACTS = ("cone", "s1002-uic60", "worn-uic60")
SPEEDS, STEP, ABOVE, TOP = 81, 0.5, 6.0, 150.0
DWELL = 8.0


def vehicle(contact: str, yaw_dampers: bool):
    params = bj.manchester_benchmark(contact=contact)
    return params if yaw_dampers else set_parameters(params, {"yaw_dampers.c": 0.0})


def one_case(contact: str, yaw_dampers: bool) -> dict:
    params = vehicle(contact, yaw_dampers)
    linear = critical_speed(params, v_min=5.0, v_max=TOP)
    found = bool(linear.found)
    v_lin = float(linear.speed) if found else None
    t0 = time.perf_counter()
    ramp = ramp_from_linear(params, v_lin, above=ABOVE, count=SPEEDS, step=STEP, dwell=DWELL)
    lower, upper = ramp.dies_between()
    seconds = time.perf_counter() - t0
    return {
        "contact": contact,
        "yaw_dampers": yaw_dampers,
        "linear_critical_speed_m_s": v_lin,
        "hunting_frequency_hz": float(linear.frequency) if found else None,
        "ramp_speeds_m_s": [float(v) for v in ramp.speeds],
        "amplitude_m": [float(a) for a in ramp.amplitude],
        "growth_per_s": [float(g) for g in ramp.growth],
        "alive": [bool(a) for a in ramp.alive],
        "successful": [bool(s) for s in ramp.successful],
        "cycle_dies_between_m_s": None if np.isnan(lower) else [lower, upper],
        "ramp_wall_s": seconds,
    }


def kind(record: dict) -> str:
    bracket, v_lin = record["cycle_dies_between_m_s"], record["linear_critical_speed_m_s"]
    if bracket is None or v_lin is None:
        return "-"
    return "subcritical" if bracket[1] < v_lin - 1.0 else "supercritical"


def markdown(records: list[dict]) -> str:
    lines = [
        "## Critical speeds of the Manchester vehicle 1 (ideal track)",
        "",
        "| contact | anti-yaw dampers | linear critical speed | the cycle dies between | "
        "bifurcation | largest cycle on the ramp |",
        "| --- | --- | --- | --- | --- | ---: |",
    ]
    for r in records:
        v_lin = r["linear_critical_speed_m_s"]
        linear = (
            f"{v_lin:.1f} m/s ({r['hunting_frequency_hz']:.2f} Hz)"
            if v_lin is not None
            else f"stable to {TOP:.0f} m/s"
        )
        bracket = r["cycle_dies_between_m_s"]
        dies = f"{bracket[0]:.1f}-{bracket[1]:.1f} m/s" if bracket else _no_cycle(r)
        largest = max((a for a, ok in zip(r["amplitude_m"], r["successful"]) if ok), default=0.0)
        lines.append(
            f"| {r['contact']} | {'on' if r['yaw_dampers'] else 'off'} | {linear} | {dies} | "
            f"{kind(r)} | {1e3 * largest:.2f} mm |"
        )
    lines += [
        "",
        f"Ramp: {SPEEDS} speeds in {STEP} m/s steps from {ABOVE:g} m/s above the linear critical "
        f"speed (or from {TOP:g} m/s), {DWELL:g} s per speed, saturated creep, blow-off "
        "dampers and (cone) flange springs; alive where the leading wheelset's amplitude over "
        "the last second is at least 0.1 mm and decays by less than 2 % per second.",
    ]
    return "\n".join(lines)


def _no_cycle(record: dict) -> str:
    if not all(record["successful"]):
        return "a run failed"
    return "no cycle" if not record["alive"][0] else "alive to the ramp's end"


def main() -> None:
    records = []
    for contact in CONTACTS:
        for yaw_dampers in (True, False):
            records.append(one_case(contact, yaw_dampers))
            r = records[-1]
            print(contact, yaw_dampers, r["linear_critical_speed_m_s"], r["cycle_dies_between_m_s"])
    write_outputs("critical_speeds/linear_and_ramp_down", records, markdown(records))


if __name__ == "__main__":
    main()
