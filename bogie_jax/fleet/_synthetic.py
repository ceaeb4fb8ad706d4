"""A synthetic fleet on disk: per bogie a defect scenario (`bogie_jax.monitor.DEFECT_SCENARIOS`),
measurement files of its dated runs (`bogie_jax.io` NPZ, each with its synthetic track
reference) and the inventory naming them. For tests, the benchmark and demonstrations."""

import dataclasses
import datetime
from pathlib import Path

import jax.random as jr

from ..io import save_measurement
from ..monitor import RunSpec, scenario_measurements
from ._inventory import INVENTORY_FORMAT


# a synthetic bogie's one visit by default: a fixed day, so that a fleet written twice is the same
DEFAULT_VISIT = datetime.date(2026, 11, 1).isoformat()


@dataclasses.dataclass(frozen=True)
class SyntheticBogie:
    """One bogie of a synthetic fleet: `id`, its defect `scenario` (a name), its `dates`
    (ISO days; default one visit, `DEFAULT_VISIT`)."""

    id: str
    scenario: str = "healthy"
    dates: tuple[str, ...] = (DEFAULT_VISIT,)


SHORT_RUNS = (
    RunSpec(speed=30.0, duration=0.5, seed=1),
    RunSpec(speed=50.0, duration=0.5, seed=2),
)
"""Two half-second runs: the smallest case `monitor` judges well (a fleet test's runs)."""


def _toml_list(items) -> str:
    return "[" + ", ".join(f'"{x}"' for x in items) + "]"


def write_synthetic_fleet(
    folder, bogies, *, runs=SHORT_RUNS, candidates=(), seed: int = 0,
    false_alarm_rate: float = 0.05, track_error_mm: float = 0.0,
) -> Path:  # fmt: skip
    """Simulate every bogie's runs on every date into `folder/data/ID/DATE/runK.npz` (the noise
    key differs per bogie and date) and write `folder/inventory.toml` (its `[monitor]` settings:
    `candidates`, `false_alarm_rate`, `track_error_mm`); returns its path."""
    folder = Path(folder)
    lines = [f'format = "{INVENTORY_FORMAT}"', "", "[monitor]",
             f"false_alarm_rate = {false_alarm_rate!r}",
             f"track_error_mm = {float(track_error_mm)!r}"]  # fmt: skip
    if candidates:
        lines.append(f"candidates = {_toml_list(candidates)}")
    key = jr.PRNGKey(seed)
    for b, bogie in enumerate(bogies):
        lines += ["", "[[bogie]]", f'id = "{bogie.id}"', 'vehicle = "manchester"',
                  'layout = "default"']  # fmt: skip
        for d, date in enumerate(bogie.dates):
            data = scenario_measurements(bogie.scenario, runs, key=jr.fold_in(key, 1000 * b + d))
            names = []
            for k, m in enumerate(data):
                name = f"data/{bogie.id}/{date}/run{k}.npz"
                save_measurement(folder / name, m)
                names.append(name)
            lines += ["", "[[bogie.measurement]]", f"date = {date}", f"files = {_toml_list(names)}"]
    path = folder / "inventory.toml"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path
