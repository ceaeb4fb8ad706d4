"""Shared helpers of the benchmark scripts: timing, environment record, output files."""

import contextlib
import datetime
import json
import math
import platform
import re
import subprocess
import time
from pathlib import Path

import jax
import numpy as np


RESULTS = Path(__file__).parent / "results"


@contextlib.contextmanager
def git_worktree(commit: str, where: Path):
    """The repository at `commit` checked out into `where` (a detached git worktree) while the
    context lasts: a baseline package measured beside this checkout's."""
    root = Path(__file__).resolve().parents[1]
    git = ["git", "-C", str(root), "worktree"]
    subprocess.run([*git, "add", "--detach", str(where), commit], check=True, capture_output=True)
    try:
        yield where
    finally:
        subprocess.run([*git, "remove", "--force", str(where)], check=False, capture_output=True)


def today() -> str:
    """The date in UTC, `YYYY-MM-DD`: the date a result is written with."""
    return datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d")


def environment() -> dict:
    """Device, versions, commit and date, recorded with every benchmark."""
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=False
        ).stdout.strip()
    except OSError:
        commit = ""
    return {
        "device": str(jax.devices()[0].device_kind),
        "n_devices": jax.device_count(),
        "platform": platform.platform(),
        "jax": jax.__version__,
        "commit": commit,
        "date": today(),
    }


def median_time(fn, repeats: int = 5) -> tuple[float, list[float]]:
    """Median wall time [s] of `fn()` (which must block until its result is ready)."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), times


def wilson(k: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score 95 % interval of a binomial proportion k / n (Wilson, J. Am. Stat. Assoc. 22
    (1927) 209-212); NaN for n = 0."""
    if n == 0:
        return (float("nan"), float("nan"))
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return (max(0.0, centre - half), min(1.0, centre + half))


def rate(k: int, n: int) -> str:
    """`k / n` as `p % (k/n; lo-hi)` with its Wilson interval in %; `-` for n = 0."""
    if n == 0:
        return "-"
    lo, hi = wilson(k, n)
    return f"{100 * k / n:.0f} % ({k}/{n}; {100 * lo:.0f}-{100 * hi:.0f})"


def coverage_reading(counts: dict, level: float = 0.95, band=(0.90, 0.98)) -> str:
    """How per-element coverage counts `{name: (covered, judged)}` read against a calibrated
    monitor, one whose every `level` interval holds the truth with probability `level`: the
    elements whose count lies outside its binomial two-sided 95 % range (a test at 5 % of
    `level` per element: under- or over-covering beyond chance), the same test on all the
    counts together, and the probability that a calibrated monitor puts every element's
    coverage in `band` at these counts (binomial, elements independent)."""
    from scipy.stats import binom

    beyond, all_in = [], 1.0
    for name, (k, n) in counts.items():
        if not n:
            continue
        lo, hi = math.ceil(band[0] * n - 1e-9), math.floor(band[1] * n + 1e-9)
        all_in *= float(binom.cdf(hi, n, level) - binom.cdf(lo - 1, n, level))
        if binom.cdf(k, n, level) < 0.025:
            beyond.append(f"{name} {k}/{n} under")
        elif binom.sf(k - 1, n, level) < 0.025:
            beyond.append(f"{name} {k}/{n} over")
    counted = sum(1 for k, n in counts.values() if n)
    k_all, n_all = (sum(x) for x in zip(*counts.values())) if counts else (0, 0)
    joint = "none"
    if n_all and binom.cdf(k_all, n_all, level) < 0.025:
        joint = "under"
    elif n_all and binom.sf(k_all - 1, n_all, level) < 0.025:
        joint = "over"
    return (
        f"beyond chance for a calibrated monitor (binomial, 5 %): {', '.join(beyond) or 'none'}; "
        f"all together {k_all}/{n_all}: {joint} (a case's intervals are correlated, so this "
        "overstates significance); a calibrated monitor puts all "
        f"{counted} in {100 * band[0]:.0f}-{100 * band[1]:.0f} % with probability {all_in:.2f} "
        "at these counts"
    )


def result_path(name: str, suffix: str) -> Path:
    """`results/BENCHMARK/WHAT.SUFFIX` for `name` = `"BENCHMARK/WHAT"` (its folder created):
    one folder per benchmark, each file named after what it measures."""
    benchmark, _, what = name.partition("/")
    if not benchmark or not what or "/" in what:
        raise ValueError(f"result name {name!r}: give 'benchmark/what_it_measures'")
    folder = RESULTS / benchmark
    folder.mkdir(parents=True, exist_ok=True)
    return folder / f"{what}{suffix}"


def stamp(env: dict) -> str:
    """The markdown line that says where a result comes from: commit, date, device."""
    device = env.get("device", "")
    return f"Measured at commit {env.get('commit') or '?'}, {env.get('date') or '?'}, {device}."


def write_outputs(
    name: str, records, markdown: str, extra: dict | None = None, env: dict | None = None
) -> None:
    """Write `results/BENCHMARK/WHAT.json` (records + environment, commit and date included)
    and `results/BENCHMARK/WHAT.md` (ending in `stamp`), `name` = `"BENCHMARK/WHAT"`.
    `env`: the environment the records were measured in (default: this process's)."""
    env = {"date": today(), **(env or environment())}
    payload = {"environment": env, "records": records, **(extra or {})}
    result_path(name, ".json").write_text(json.dumps(payload, indent=2))
    markdown = markdown.rstrip("\n") + "\n\n" + stamp(env) + "\n"
    result_path(name, ".md").write_text(markdown)
    print(markdown)


# --- compiled programs: size and where it comes from (used by compile.py) ---

_HLO_INSTRUCTION = re.compile(r"^\s+(?:ROOT\s+)?%[\w.\-]+ = ")
_MLIR_OP = re.compile(r"^\s*(?:%[^=\"]+=\s*)?\"?(?:[a-z_]+\.[a-z_.]+|call|return)\b")
_HLO_SECTIONS = ("FileNames", "FunctionNames", "FileLocations", "StackFrames")


def hlo_instruction_lines(hlo_text: str) -> list[str]:
    """The instruction lines of an HLO module's text (`compiled.as_text()`), fusion bodies and
    loop bodies included: one line per HLO instruction."""
    return [line for line in hlo_text.splitlines() if _HLO_INSTRUCTION.match(line)]


def mlir_op_count(mlir_text: str) -> int:
    """Operations in an MLIR module's text (`lowered.as_text()`: StableHLO, func, sdy ops),
    counted as lines that hold an operation; function headers are not counted."""
    return sum(
        1
        for line in mlir_text.splitlines()
        if _MLIR_OP.match(line) and not line.lstrip().startswith("func.func")
    )


def hlo_stack_frames(hlo_text: str) -> dict[int, list[tuple[str, str, int]]]:
    """`{stack_frame_id: [(file, function, line), ...]}`, innermost frame first, from the
    stack-frame index that XLA prints in the module's header (`FileNames`, `FunctionNames`,
    `FileLocations`, `StackFrames`; instructions name their frame by `stack_frame_id=`).
    A printed `parent_frame_id` is the parent's id plus one (0: no parent)."""
    sections: dict[str, dict[int, str]] = {}
    current = None
    for line in hlo_text.splitlines():
        if line in _HLO_SECTIONS:
            current = sections.setdefault(line, {})
        elif current is not None and not line.strip():
            current = None
        elif current is not None:
            key, rest = line.split(" ", 1)
            current[int(key)] = rest
    if "StackFrames" not in sections:
        return {}
    fields = lambda text: {k: int(v) for k, v in re.findall(r"(\w+)=(\d+)", text)}
    files = {k: v.strip('"') for k, v in sections.get("FileNames", {}).items()}
    names = {k: v.strip('"') for k, v in sections.get("FunctionNames", {}).items()}
    locations = {}
    for key, text in sections.get("FileLocations", {}).items():
        f = fields(text)
        locations[key] = (files[f["file_name_id"]], names[f["function_name_id"]], f["line"])
    parents = {k: fields(v) for k, v in sections["StackFrames"].items()}

    def chain(frame):
        out, seen = [], set()
        while frame in parents and frame not in seen:
            seen.add(frame)
            out.append(locations[parents[frame]["file_location_id"]])
            frame = parents[frame]["parent_frame_id"] - 1
        return out

    return {frame: chain(frame) for frame in parents}


def hlo_attribution(hlo_text: str, label) -> dict[str, int]:
    """HLO instructions counted by where they come from, most first.

    Each instruction is charged to the innermost frame of its call stack for which
    `label(file, function)` returns a string (`None` skips a frame, e.g. a wrapper of JAX or
    equinox); instructions without a stack count as `"(no stack)"`."""
    stacks = hlo_stack_frames(hlo_text)
    counts: dict[str, int] = {}
    for line in hlo_instruction_lines(hlo_text):
        found = re.search(r"stack_frame_id=(\d+)", line)
        frames = stacks.get(int(found.group(1)), []) if found else []
        name = next((n for n in (label(f, fn) for f, fn, _ in frames) if n), "(no stack)")
        counts[name] = counts.get(name, 0) + 1
    return dict(sorted(counts.items(), key=lambda kv: -kv[1]))
