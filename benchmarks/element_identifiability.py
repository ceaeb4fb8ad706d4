"""Which single suspension elements the sensors can tell apart (issue 17, item 5).

Per-element parameters of the Manchester benchmark bogie (each anti-yaw damper, each axlebox's
primary vertical damper and vertical and lateral rubber spring, each side's secondary lateral
damper; `bogie_jax.params.element_names`), on an ERRI-low track, seen through two layouts:

- `default`: the 13-channel default layout of `bogie_jax.measure`;
- `frame-acc`: frame accelerometers above the four axleboxes only (8 channels);

at 30 and 60 m/s, and with both runs together (the Fisher information of independent runs
adds). For each (layout, speed) the Fisher information at the nominal point (noise-free data,
1/sigma^2 weights, relative scaling dr/d ln p) gives every element's Cramer-Rao relative standard
error with all elements free; the tied group (all members moving together, e.g. `yaw_dampers.c`)
gets its own from the Fisher information with the group's columns summed (the others stay free).
The correlation of two members of a group is read from the covariance.

Classification of an element (threshold `--max-rel-std`, default 10 %):
- `separable`: its own relative standard error is below the threshold;
- `group`: not separable, but its tied group's is below the threshold (the sensors see "one of
  these elements changed", not which);
- `needs sensor`: neither.

Run: `python benchmarks/element_identifiability.py [--duration 2] [--speeds 30,60]`.
"""

import os


os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=2")

import argparse  # noqa: E402
import itertools  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import jax  # noqa: E402


jax.config.update("jax_enable_x64", True)

import diffrax as dfx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import jax.random as jr  # noqa: E402
import numpy as np  # noqa: E402


sys.path.insert(0, str(Path(__file__).parent))
from _common import write_outputs  # noqa: E402

import bogie_jax as bj  # noqa: E402
from bogie_jax.cost import synthetic_objective  # noqa: E402
from bogie_jax.identify import as_problem  # noqa: E402
from bogie_jax.sensitivity import physical_jacobian, sensor_layouts  # noqa: E402
from bogie_jax.track import ERRIB176Spectrum, synthesise_track  # noqa: E402


AXLEBOXES = ("1L", "1R", "2L", "2R")
SIDES = ("left", "right")
# group (tied name) -> its members (element names)
GROUPS = {
    "yaw_dampers.c": tuple(f"yaw_dampers.{s}.c" for s in SIDES),
    "primary.cz": tuple(f"primary.{a}.cz" for a in AXLEBOXES),
    "primary.kz": tuple(f"primary.{a}.kz" for a in AXLEBOXES),
    "primary.ky": tuple(f"primary.{a}.ky" for a in AXLEBOXES),
    "secondary.cy": tuple(f"secondary.{s}.cy" for s in SIDES),
}
ELEMENTS = tuple(itertools.chain.from_iterable(GROUPS.values()))
STUDY_LAYOUTS = ("default", "frame-acc")


def relative_std(rel_jac, rcond=1e-12):
    """Cramer-Rao relative standard errors (n,) from the relative-scaled Jacobian (m, n):
    sqrt(diag(F^+)) with F = J^T J, inf for a column in the (numerical) null space of F."""
    cov = bj.cost.covariance_from_jacobian(rel_jac, rcond=rcond)
    return np.asarray(cov.std_errors), np.asarray(cov.correlation)


def classify(rel_jac, max_rel_std):
    """Per element: own relative std, its group's relative std, class, and correlations."""
    own, corr = relative_std(rel_jac)
    index = {n: i for i, n in enumerate(ELEMENTS)}
    out = {}
    for group, members in GROUPS.items():
        cols = [index[m] for m in members]
        others = [i for i in range(len(ELEMENTS)) if i not in cols]
        tied = np.concatenate([rel_jac[:, cols].sum(axis=1, keepdims=True), rel_jac[:, others]], 1)
        group_std = float(relative_std(tied)[0][0])
        pairs = {
            f"{a}~{b}": float(corr[index[a], index[b]])
            for a, b in itertools.combinations(members, 2)
        }
        for m in members:
            s = float(own[index[m]])
            cls = (
                "separable"
                if s < max_rel_std
                else "group"
                if group_std < max_rel_std
                else "needs sensor"
            )
            out[m] = {"relative_std": s, "group_relative_std": group_std, "class": cls}
        out[group] = {"relative_std": group_std, "member_correlations": pairs}
    return out


def speed_jacobian(speed, args, params, sensors):
    """Relative-scaled residual Jacobian (n_samples, n_channels, n_elements) at `speed`."""
    margin = 2 * float(params.geometry.semi_wheelbase) + 20.0
    track = synthesise_track(
        ERRIB176Spectrum.low(),
        key=jr.PRNGKey(args.seed),
        length=70.0 * args.duration + margin,  # one track length for every speed (one program)
        fade_length=2.0,
        start=-5.0,
    )
    objective, _ = synthetic_objective(
        params,
        track,
        ELEMENTS,
        speed=speed,
        duration=args.duration,
        sample_rate=args.sample_rate,
        sensors=sensors,
        key=None,
        bounds="spec",
        stepsize_controller=dfx.PIDController(rtol=1e-7, atol=1e-10),
        max_steps=16_384,
    )
    t0 = time.perf_counter()
    jac, values = physical_jacobian(as_problem(objective), jnp.zeros(len(ELEMENTS)))
    jac = np.asarray(jax.block_until_ready(jac)) * np.asarray(values)[None, :]
    seconds = time.perf_counter() - t0
    print(f"  {speed:g} m/s: Jacobian {jac.shape} in {seconds:.1f} s", flush=True)
    return jac.reshape(-1, len(sensors), len(ELEMENTS)), seconds


def short(name):
    return (
        name.replace("primary.", "p.").replace("secondary.", "s.").replace("yaw_dampers.", "yaw.")
    )


def markdown(records, args, timing):
    cases = [(r["layout"], r["speed"]) for r in records]
    by = {(r["layout"], r["speed"]): r["elements"] for r in records}
    lines = [
        "## Which single elements the sensors can tell apart (issue 17)",
        "",
        f"Manchester bogie, ERRI-low track (seed {args.seed}), {args.duration:g} s at "
        f"{args.sample_rate:g} Hz per run, noise-free data at the nominal parameters, the "
        f"sensors' nominal noise (1/sigma^2 weights). Cramer-Rao relative standard error of each "
        f"element with all {len(ELEMENTS)} elements free; in brackets the tied group's. "
        f"`sep`: separable (< {100 * args.max_rel_std:g} %), `grp`: only as its group, "
        "`--`: needs another sensor. `30+60`: both runs together.",
        "",
        "| element | " + " | ".join(f"{lay} {v}" for lay, v in cases) + " |",
        "| --- |" + " --- |" * len(cases),
    ]
    tag = {"separable": "sep", "group": "grp", "needs sensor": "--"}
    for name in ELEMENTS:
        cells = []
        for case in cases:
            e = by[case][name]
            cells.append(
                f"{tag[e['class']]} {100 * e['relative_std']:.2g} % "
                f"({100 * e['group_relative_std']:.2g} %)"
            )
        lines.append(f"| {short(name)} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "Largest |correlation| between two members of a group (1 = the sensors cannot tell "
        "them apart):",
        "",
        "| group | " + " | ".join(f"{lay} {v}" for lay, v in cases) + " |",
        "| --- |" + " --- |" * len(cases),
    ]
    for group in GROUPS:
        cells = []
        for case in cases:
            pairs = by[case][group]["member_correlations"]
            worst = max(pairs, key=lambda k: abs(pairs[k]))
            a, b = (short(x) for x in worst.split("~"))
            cells.append(f"{pairs[worst]:+.3f} ({a} / {b})")
        lines.append(f"| {short(group)} | " + " | ".join(cells) + " |")
    lines += ["", f"Wall time: {timing['total_s']:.0f} s on {timing['device']}."]
    return "\n".join(lines) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=2.0, help="simulated time per run [s]")
    p.add_argument("--sample-rate", type=float, default=100.0, help="sample rate [Hz]")
    p.add_argument("--speeds", default="30,60", help="comma-separated speeds [m/s]")
    p.add_argument("--seed", type=int, default=0, help="track seed")
    p.add_argument("--max-rel-std", type=float, default=0.1, help="identifiability threshold")
    p.add_argument(
        "--label",
        default="elements_by_sensor_layout",
        help="output file stem under results/element_identifiability/",
    )
    args = p.parse_args(argv)
    params = bj.manchester_benchmark()
    layouts = sensor_layouts(params)
    by_name = {s.name: s for k in STUDY_LAYOUTS for s in layouts[k]}
    sensors = tuple(by_name.values())
    channels = tuple(by_name)
    cols = {k: np.array([channels.index(s.name) for s in layouts[k]]) for k in STUDY_LAYOUTS}
    t_start = time.perf_counter()
    speeds = [float(s) for s in args.speeds.split(",")]
    jacobians, timing = {}, {"jacobian_s": {}}
    for v in speeds:
        jacobians[v], timing["jacobian_s"][f"{v:g}"] = speed_jacobian(v, args, params, sensors)
    records = []
    for layout, c in cols.items():
        rows = {f"{v:g}": jacobians[v][:, c, :].reshape(-1, len(ELEMENTS)) for v in speeds}
        if len(speeds) > 1:
            rows["+".join(f"{v:g}" for v in speeds)] = np.concatenate(list(rows.values()))
        for label, rel_jac in rows.items():
            records.append(
                {
                    "layout": layout,
                    "speed": label,
                    "channels": [channels[i] for i in c],
                    "elements": classify(rel_jac, args.max_rel_std),
                }
            )
    timing["total_s"] = time.perf_counter() - t_start
    timing["device"] = f"{jax.device_count()} x {jax.devices()[0].device_kind}"
    md = markdown(records, args, timing)
    write_outputs(
        f"element_identifiability/{args.label}",
        records,
        md,
        extra={"settings": vars(args), "timing": timing, "elements": list(ELEMENTS)},
    )


if __name__ == "__main__":
    main()
