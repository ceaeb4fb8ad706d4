"""Wall time of `bogie-jax identify` as a user runs it, cold and warm (issue 15, item 5).

Each round makes an empty compilation cache directory (`BOGIE_JAX_CACHE_DIR`) and an output
folder, then runs the command twice, each in a fresh process: cold (nothing compiled yet) and
warm (reading the cache the cold run filled). The wall time is taken around the process, so it
includes Python's start, the imports and the exit. The command's own total and its phases come
from the last line it prints. The 1-minute load average is recorded before each process. Rounds
run one after another on the same machine: compare figures within one run of this script.

The default command is the `bogie-jax` script installed beside this interpreter (as after
`pip install .`), else `python -m bogie_jax.cli`. A source checkout on `PYTHONPATH` compiles the
package's bytecode in every process where `PYTHONDONTWRITEBYTECODE` is set; an installed package
has it compiled at install time.

Run (from the repository root):
    python benchmarks/identify_wall.py --rounds 5
    python benchmarks/identify_wall.py --command /path/to/venv/bin/bogie-jax --name user
    python benchmarks/identify_wall.py -- --starts 4      # arguments after -- go to identify

Writes `results/identify_wall/NAME.json` and `.md` (NAME: `--name`, default `cold_and_warm`).
"""

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks._common import environment, write_outputs  # noqa: E402


TARGETS = {"cold": 60.0, "warm": 30.0}  # [s] wall time on 2 cores (issue 15, item 5)
TOTAL_LINE = re.compile(
    r"^total (?P<total>[\d.]+) s: compiling the batch (?P<batch>[\d.]+) s \(\d+ %\), "
    r"data and objective (?P<data>[\d.]+) s, fits (?P<fits>[\d.]+) s, "
    r"statistics (?P<statistics>[\d.]+) s",
    re.M,
)


def default_command() -> list[str]:
    """The `bogie-jax` script beside this interpreter, else `python -m bogie_jax.cli`."""
    script = Path(sys.executable).with_name("bogie-jax")
    return [str(script)] if script.exists() else [sys.executable, "-m", "bogie_jax.cli"]


def package_location(command: list[str]) -> str:
    """Where the command's interpreter imports `bogie_jax` from (run outside the checkout, as
    the command itself is)."""
    python = command[0] if command[0].endswith(("python", "python3")) else None
    python = python or str(Path(command[0]).with_name("python"))
    out = subprocess.run(
        [python, "-c", "import bogie_jax; print(bogie_jax.__file__)"],
        capture_output=True,
        text=True,
        cwd=tempfile.gettempdir(),  # not the checkout: `-c` puts the working directory first
        check=False,
    )
    return out.stdout.strip() or out.stderr.strip()[-200:]


def run_once(command: list[str], cache: Path, out: Path, args: list[str]) -> dict:
    """One `identify` process: wall time, exit status and the phases it printed."""
    env = {**os.environ, "BOGIE_JAX_CACHE_DIR": str(cache)}
    load = os.getloadavg()[0]
    tic = time.perf_counter()
    proc = subprocess.run(
        [*command, "identify", "--out", str(out), *args],
        capture_output=True,
        text=True,
        env=env,
        cwd=out.parent,
        check=False,
    )
    wall = time.perf_counter() - tic
    text = proc.stdout + proc.stderr
    match = TOTAL_LINE.search(text)
    phases = {k: float(v) for k, v in match.groupdict().items()} if match else {}
    return {
        "wall_s": wall,
        "returncode": proc.returncode,
        "load_1min": load,
        "first_line": text.splitlines()[0] if text else "",
        **{f"{k}_s": v for k, v in phases.items()},
        **({} if proc.returncode == 0 and match else {"tail": text[-2000:]}),
    }


def summary(records: list[dict]) -> dict:
    """Per mode: count, median, min, max of the wall time and how many runs met the target."""
    out = {}
    for mode, target in TARGETS.items():
        walls = [r["wall_s"] for r in records if r["mode"] == mode and r["returncode"] == 0]
        if walls:
            out[mode] = {
                "runs": len(walls),
                "median_s": statistics.median(walls),
                "min_s": min(walls),
                "max_s": max(walls),
                "target_s": target,
                "within_target": sum(w <= target for w in walls),
            }
    return out


def markdown(
    records: list[dict], stats: dict, command: list[str], location: str, first: str
) -> str:
    lines = [
        "# `bogie-jax identify` wall time, cold and warm (issue 15, item 5)",
        "",
        f"Command: `{' '.join(Path(c).name if i == 0 else c for i, c in enumerate(command))}"
        f" identify`; package imported from `{location}`. First line: `{first}`.",
        "",
        "| round | mode | wall s | printed total s | batch s | data s | fits s | statistics s "
        "| load (1 min) | exit |",
        "| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in records:
        phases = [r.get(f"{k}_s", float("nan")) for k in ("total", "batch", "data", "fits")]
        cells = [r["round"], r["mode"], f"{r['wall_s']:.1f}"]
        cells += [f"{v:.1f}" for v in (*phases, r.get("statistics_s", float("nan")))]
        cells += [f"{r['load_1min']:.2f}", r["returncode"]]
        lines.append("| " + " | ".join(str(c) for c in cells) + " |")
    lines += ["", "| mode | runs | median wall s | min | max | target s | runs within |"]
    lines += ["| --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for mode, s in stats.items():
        lines.append(
            f"| {mode} | {s['runs']} | {s['median_s']:.1f} | {s['min_s']:.1f} | {s['max_s']:.1f}"
            f" | {s['target_s']:.0f} | {s['within_target']} of {s['runs']} |"
        )
    return "\n".join(lines) + "\n"


def main() -> None:
    argv = sys.argv[1:]
    passthrough = argv[argv.index("--") + 1 :] if "--" in argv else []
    argv = argv[: argv.index("--")] if "--" in argv else argv
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=5, help="cold + warm pairs (default 5)")
    p.add_argument("--command", default=None, help="the bogie-jax script (default: see module)")
    p.add_argument(
        "--name", default="cold_and_warm", help="results stem under results/identify_wall/"
    )
    opts = p.parse_args(argv)
    if opts.rounds < 1:
        p.error(f"--rounds = {opts.rounds}: give at least 1")
    command = [opts.command] if opts.command else default_command()
    location = package_location(command)
    records = []
    for k in range(opts.rounds):
        with tempfile.TemporaryDirectory(prefix="identify_wall_") as tmp:
            for mode in ("cold", "warm"):
                rec = run_once(command, Path(tmp) / "cache", Path(tmp) / f"out_{mode}", passthrough)
                records.append({"round": k, "mode": mode, **rec})
                print(f"round {k} {mode}: {rec['wall_s']:.1f} s wall, exit {rec['returncode']}")
    stats = summary(records)
    name = f"identify_wall/{opts.name}"
    first = next((r["first_line"] for r in records if r["first_line"]), "")  # its devices
    # this process's devices are not the command's: the command's first line says what it ran on
    env = {k: v for k, v in environment().items() if k not in ("device", "n_devices")}
    env |= {"command": command, "package": location, "args": passthrough, "first_line": first}
    md = markdown(records, stats, command, location, first)
    write_outputs(name, records, md, {"summary": stats}, env)


if __name__ == "__main__":
    main()
