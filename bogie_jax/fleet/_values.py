"""The inventory's values: the fleet's monitor settings, its bogies and their dated
measurements (standard library only: a worker unpickles them before it imports JAX)."""

import dataclasses


@dataclasses.dataclass(frozen=True)
class MonitorSettings:
    """What every bogie of the fleet is judged with (the inventory's `[monitor]` table):
    `false_alarm_rate` in (0, 0.5), `track_error_mm` [mm] in [0, 10] (the track records' error
    RMS), `band` (relative half-width of the healthy bands, `None`: monitor's default) and
    `candidates` (element names, `()`: monitor's default list)."""

    false_alarm_rate: float = 0.05
    track_error_mm: float = 0.0
    band: float | None = None
    candidates: tuple[str, ...] = ()


@dataclasses.dataclass(frozen=True)
class Visit:
    """One dated measurement of one bogie: its `files` (`bogie_jax.io` CSV or NPZ, one per
    run, judged jointly) and `tracks` (track record CSVs: none, one for all runs, or one per
    file), as absolute paths; `date` as `YYYY-MM-DD`; `contact` the wheel-rail contact fitted:
    `"cone"` (the vehicle's default) or the wheels' profile measured at the visit
    (`bogie_jax.contact.measured_wheel`'s contact name)."""

    date: str
    files: tuple[str, ...]
    tracks: tuple[str, ...] = ()
    contact: str = "cone"


@dataclasses.dataclass(frozen=True)
class BogieEntry:
    """One bogie: `id`, `vehicle` (a parameter set, `bogie_jax.params.PARAMETER_SETS`),
    `layout` (a sensor layout name, `bogie_jax.sensitivity.LAYOUTS`), its `visits` by date."""

    id: str
    vehicle: str
    layout: str
    visits: tuple[Visit, ...]


@dataclasses.dataclass(frozen=True)
class Inventory:
    """A checked inventory: its `path`, the fleet's `settings` and its `bogies`."""

    path: str
    settings: MonitorSettings
    bogies: tuple[BogieEntry, ...]

    @property
    def visits(self) -> tuple[tuple[BogieEntry, Visit], ...]:
        """Every `(bogie, visit)` pair, bogies in file order, visits by date."""
        return tuple((b, v) for b in self.bogies for v in b.visits)
