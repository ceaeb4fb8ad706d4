"""`run_fleet`: judge every bogie and date of an inventory that the database does not hold yet.

Resumable: the work is the inventory's bogie-dates less those stored (`FleetStore.judged`);
each outcome is written as it arrives, in its own transaction, so an interrupted run loses at
most the bogie-dates still being judged, and the next run starts from what is stored. A
failed bogie-date is stored in `failures` with its one-line error and tried again next run."""

import dataclasses
import functools
import time
from collections.abc import Callable

import sqlalchemy as sa

from ._store import FleetStore
from ._task import JudgeTask, Outcome
from ._values import Inventory
from ._worker import run_task


@dataclasses.dataclass(frozen=True)
class FleetSummary:
    """What a run did: `run_id`, bogie-dates `total` in the inventory, `before` (already
    stored), `judged` and `failed` now, and its `wall_s` [s]."""

    run_id: int
    total: int
    before: int
    judged: int
    failed: int
    wall_s: float


def pending_tasks(inventory: Inventory, judged, cache_dir=None) -> list[JudgeTask]:
    """The inventory's bogie-dates not in `judged` (a set of `(bogie_id, date)`)."""
    tasks = [JudgeTask.of(b, v, inventory.settings, cache_dir) for b, v in inventory.visits]
    return [t for t in tasks if t.key not in judged]


def _duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 90 else f"{seconds / 60:.1f} min"


class _Progress:
    """The progress line after each outcome: bogie-dates and bogies done, rate and ETA."""

    def __init__(self, say, tasks):
        self.say, self.total, self.t0 = say, len(tasks), time.perf_counter()
        self.left = {}
        for t in tasks:
            self.left[t.bogie_id] = self.left.get(t.bogie_id, 0) + 1
        self.bogies, self.done, self.failed = len(self.left), 0, 0

    def step(self, outcome: Outcome) -> None:
        self.done += 1
        self.failed += not outcome.ok
        self.left[outcome.task.bogie_id] -= 1
        elapsed = time.perf_counter() - self.t0
        rate = self.done / elapsed * 60
        eta = (
            ""
            if self.done == self.total
            else f", ETA {_duration(elapsed / self.done * (self.total - self.done))}"
        )
        complete = sum(n == 0 for n in self.left.values())
        t, what = outcome.task, "judged" if outcome.ok else f"FAILED: {outcome.error}"
        self.say(f"  {t.bogie_id} {t.date} {what} ({outcome.wall_s:.0f} s, {outcome.worker})")
        self.say(
            f"  bogie-dates {self.done}/{self.total} done, bogies {complete}/{self.bogies}, "
            f"{self.failed} failed, {rate:.2g} per min, {_duration(elapsed)}{eta}"
        )


def _store_outcome(store: FleetStore, outcome: Outcome, run_id: int, say) -> bool:
    """Write the outcome; False where another run stored this bogie-date meanwhile."""
    t = outcome.task
    if not outcome.ok:
        store.write_failure(bogie_id=t.bogie_id, date=t.date, error=outcome.error, run_id=run_id)
        return True
    try:
        store.write_judgement(outcome.record, bogie_id=t.bogie_id, date=t.date,
                              vehicle=t.vehicle, layout=t.layout, run_id=run_id,
                              wall_s=outcome.wall_s)  # fmt: skip
    except sa.exc.IntegrityError:
        say(f"  {t.bogie_id} {t.date}: stored meanwhile by another run; kept that one")
        return False
    return True


def run_fleet(inventory: Inventory, store: FleetStore, engine, *, command: str = "",
              cache_dir: str | None = None, judge: Callable | None = None,
              say: Callable[[str], None] = print) -> FleetSummary:  # fmt: skip
    """Judge the inventory's pending bogie-dates on `engine` (`SerialEngine`, `DaskEngine`,
    entered) and store each outcome in `store` (migrated) as it arrives. `judge`: the task
    function a worker calls (default `_judge.judge_visit`; tests pass a stand-in)."""
    tic = time.perf_counter()
    judged = store.judged()
    tasks = pending_tasks(inventory, judged, cache_dir)
    total = len(inventory.visits)
    say(f"{total} bogie-dates of {len(inventory.bogies)} bogies in the inventory; "
        f"{total - len(tasks)} judged before; {len(tasks)} to judge on {engine.name}")  # fmt: skip
    run_id = store.start_run(command, engine.name)
    progress, ok, failed = _Progress(say, tasks), 0, 0
    try:
        for outcome in engine.run(functools.partial(run_task, judge=judge), tasks):
            if _store_outcome(store, outcome, run_id, say):
                ok += outcome.ok
                failed += not outcome.ok
            progress.step(outcome)
    finally:
        store.finish_run(run_id, judged=ok, failed=failed)
    return FleetSummary(run_id, total, total - len(tasks), ok, failed, time.perf_counter() - tic)
