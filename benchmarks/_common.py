"""Shared helpers of the benchmark scripts: timing, environment record, output files."""

import json
import platform
import subprocess
import time
from pathlib import Path

import jax
import numpy as np


RESULTS = Path(__file__).parent / "results"


def environment() -> dict:
    """Device, versions and commit, recorded with every benchmark."""
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
    }


def median_time(fn, repeats: int = 5) -> tuple[float, list[float]]:
    """Median wall time [s] of `fn()` (which must block until its result is ready)."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), times


def write_outputs(name: str, records, markdown: str, extra: dict | None = None) -> None:
    """Write `results/NAME.json` (records + environment) and `results/NAME.md`."""
    RESULTS.mkdir(parents=True, exist_ok=True)
    payload = {"environment": environment(), "records": records, **(extra or {})}
    (RESULTS / f"{name}.json").write_text(json.dumps(payload, indent=2))
    (RESULTS / f"{name}.md").write_text(markdown)
    print(markdown)
