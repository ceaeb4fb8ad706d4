"""What a worker gets and gives back: plain frozen values, picklable to any process."""

import dataclasses

from ..params import PARAMETER_SETS
from ._values import BogieEntry, MonitorSettings, Visit


@dataclasses.dataclass(frozen=True)
class JudgeTask:
    """Judge one bogie on one date: `bogie_id`, `date` (`YYYY-MM-DD`), `vehicle` and `layout`
    names, measurement `files` and track records `tracks` (absolute paths), the fleet's
    `settings`, the compilation cache directory the worker uses (`None`: none) and the
    wheel-rail `contact` fitted (`Visit.contact`)."""

    bogie_id: str
    date: str
    vehicle: str
    layout: str
    files: tuple[str, ...]
    tracks: tuple[str, ...]
    settings: MonitorSettings
    cache_dir: str | None = None
    contact: str = "cone"

    @classmethod
    def of(cls, bogie: BogieEntry, visit: Visit, settings, cache_dir=None) -> "JudgeTask":
        return cls(bogie.id, visit.date, bogie.vehicle, bogie.layout, visit.files, visit.tracks,
                   settings, cache_dir, visit.contact)  # fmt: skip

    @property
    def key(self) -> tuple[str, str]:
        return (self.bogie_id, self.date)

    def params(self):
        """The vehicle's parameter set with the visit's wheel-rail contact."""
        make = PARAMETER_SETS[self.vehicle]
        return make() if self.contact == "cone" else make(contact=self.contact)


@dataclasses.dataclass(frozen=True)
class Outcome:
    """A task's end: `record` (the `verdicts.json` object) when judged, else `error` (one line);
    `wall_s` [s] in the worker and the worker's `worker` name (process id or Dask address)."""

    task: JudgeTask
    record: dict | None
    error: str | None
    wall_s: float
    worker: str = ""

    @property
    def ok(self) -> bool:
        return self.error is None
