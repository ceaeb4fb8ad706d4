"""What a worker gets and gives back: plain frozen values, picklable to any process."""

import dataclasses

from ._values import BogieEntry, MonitorSettings, Visit


@dataclasses.dataclass(frozen=True)
class JudgeTask:
    """Judge one bogie on one date: `bogie_id`, `date` (`YYYY-MM-DD`), `vehicle` and `layout`
    names, measurement `files` and track records `tracks` (absolute paths), the fleet's
    `settings`, and the compilation cache directory the worker uses (`None`: none)."""

    bogie_id: str
    date: str
    vehicle: str
    layout: str
    files: tuple[str, ...]
    tracks: tuple[str, ...]
    settings: MonitorSettings
    cache_dir: str | None = None

    @classmethod
    def of(cls, bogie: BogieEntry, visit: Visit, settings, cache_dir=None) -> "JudgeTask":
        return cls(bogie.id, visit.date, bogie.vehicle, bogie.layout, visit.files, visit.tracks,
                   settings, cache_dir)  # fmt: skip

    @property
    def key(self) -> tuple[str, str]:
        return (self.bogie_id, self.date)


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
