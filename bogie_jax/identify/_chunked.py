"""Chunked, resumable multistart: the starts of `fit_multistart` run a chunk at a time through
one compiled batch, and every finished start is appended to a JSON-lines record.

The design is drawn once from `key` (as `fit_multistart` draws it), so a call interrupted after
some chunks and called again with the same arguments and `record` runs only the starts the
record lacks and returns what one uninterrupted call returns. The objective is an input of the
compiled batch (`batched_fits`): one compile serves every chunk, and later calls on data of the
same structure.
"""

import dataclasses
import json
import math
import time
from collections.abc import Callable
from pathlib import Path

import jax
import numpy as np

from ..runtime.batch import BatchResult
from ._batched import batched_fits
from ._lm_fits import default_chunk
from ._local import LocalOutput
from ._multistart import MultistartResult, collect, design_starts
from ._problem import as_problem, results_from_names, status_names


@dataclasses.dataclass(frozen=True)
class ChunkedMultistart:
    """Outcome of `fit_multistart_chunked`.

    - `result`: a `MultistartResult` over the finished starts in design order (`None` if none);
    - `indices`: design index of each of `result`'s starts;
    - `interrupted`: a `KeyboardInterrupt` stopped the run (finished chunks are kept);
    - `resumed`: starts read back from the record instead of run;
    - `compile_time`, `statistics_time`, `wall_time` [s]: the batch's compile, the final
      statistics (clusters and the best fit's covariance, compiled on a first call) and this
      call's whole time.
    """

    result: MultistartResult | None
    indices: tuple[int, ...]
    interrupted: bool
    resumed: int
    compile_time: float
    statistics_time: float
    wall_time: float


@dataclasses.dataclass(frozen=True)
class ChunkProgress:
    """Passed to `on_chunk` after every chunk: starts `done` of `total` (`resumed` of them read
    from the record), the chunk's final `costs` and `failed` flags and its per-start `records`
    (as `MultistartResult.records`), seconds since the call began (`elapsed`) and seconds spent
    running chunks (`run_time`: no compile, no resume)."""

    done: int
    total: int
    resumed: int
    costs: np.ndarray
    failed: np.ndarray
    records: list[dict]
    elapsed: float
    run_time: float

    def eta(self) -> float:
        """Seconds left at the mean rate of the chunks run so far."""
        ran = self.done - self.resumed
        return self.run_time / ran * (self.total - self.done) if ran else float("nan")


def _chunk_records(problem, thetas, batch: BatchResult) -> list[dict]:
    """`MultistartResult.records` of one chunk, without its statistics (no Jacobian)."""
    out, costs = batch.outputs
    to_physical = jax.vmap(problem.transform.to_physical)
    starts, ends = np.asarray(to_physical(thetas)), np.asarray(to_physical(out.theta))
    status = status_names(out.result)
    return [
        dict(
            start=starts[j].tolist(),
            end=ends[j].tolist(),
            cost=float(costs[j]),
            status=str(status[j]),
            failed=bool(batch.failed[j]),
            num_steps=int(out.num_steps[j]),
            num_fn_evals=int(out.num_fn_evals[j]),
        )
        for j in range(len(starts))
    ]


def _append(path: Path, indices, records: list[dict], out: LocalOutput) -> None:
    """One line per start: its record plus what rebuilds its output exactly (`theta`)."""
    lines = [
        json.dumps(
            {
                "index": int(i),
                **rec,
                "theta": np.asarray(out.theta[j]).tolist(),
                "num_jac_evals": int(out.num_jac_evals[j]),
            }
        )
        for j, (i, rec) in enumerate(zip(indices, records))
    ]
    with path.open("a") as f:
        f.write("".join(line + "\n" for line in lines))


def _read_record(path: Path, starts_physical: np.ndarray) -> dict[int, dict]:
    """Finished starts of an earlier call, checked against this call's design."""
    done = {}
    if not path.exists():
        return done
    lines = path.read_text().splitlines()
    for line_no, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            if line_no == len(lines):  # a line cut off by a hard kill: run that start again
                break
            raise ValueError(f"record {path} line {line_no} is not JSON: {line!r}") from None
        i = rec.get("index")
        if not isinstance(i, int) or not 0 <= i < len(starts_physical) or "theta" not in rec:
            raise ValueError(f"record {path} line {line_no} is not a start of this run: {line!r}")
        if not np.allclose(rec["start"], starts_physical[i], rtol=1e-9, atol=0.0):
            raise ValueError(
                f"record {path} was written by another run: start {i} differs from this "
                "design (other key, design, start count or parameters?)"
            )
        done[i] = rec
    return done


def _outputs_from_records(records: list[dict]) -> BatchResult:
    """The batch outputs `(LocalOutput, cost)` of recorded starts (on the host, as the run's)."""
    out = LocalOutput(
        theta=np.asarray([r["theta"] for r in records], float),
        result=results_from_names([r["status"] for r in records]),
        num_steps=np.asarray([r["num_steps"] for r in records]),
        num_fn_evals=np.asarray([r["num_fn_evals"] for r in records]),
        num_jac_evals=np.asarray([r["num_jac_evals"] for r in records]),
    )
    costs = np.asarray([r["cost"] for r in records], float)
    return BatchResult(outputs=(out, costs), failed=np.asarray([r["failed"] for r in records]))


def _concat(batches: list[BatchResult]) -> BatchResult:
    return jax.tree.map(lambda *xs: np.concatenate([np.asarray(x) for x in xs]), *batches)


class _BestJacobian:
    """The residual Jacobian of the lowest-cost successful start run so far (what
    `cluster_minima` makes the best: lowest cost, the lowest design index among equal ones), so
    that the chunks' Jacobians need not all be kept: one `(m, n)` array, not one per start."""

    def __init__(self):
        self.index, self.cost, self.jacobian = None, np.inf, None

    def update(self, indices, batch: BatchResult) -> BatchResult:
        """Keep the chunk's best Jacobian if it beats the best so far; the chunk without its
        Jacobians."""
        out, costs = batch.outputs
        if out.jacobian is None:
            return batch
        costs = np.where(np.asarray(batch.failed), np.inf, np.asarray(costs))
        j = int(np.argmin(costs))  # first among equal costs: the lowest design index
        if costs[j] < self.cost:
            self.index, self.cost, self.jacobian = indices[j], costs[j], out.jacobian[j]
        out = dataclasses.replace(out, jacobian=None)
        return BatchResult(outputs=(out, batch.outputs[1]), failed=batch.failed)

    def of(self, design_index: int):
        return self.jacobian if design_index == self.index else None


def fit_multistart_chunked(
    problem,
    *,
    key,
    n_starts: int = 32,
    method="lm",
    design="lhs",
    chunk: int | None = None,
    max_steps: int = 256,
    lanes: int | str | None = "auto",
    record: str | Path | None = None,
    on_compile: Callable[[int], None] | None = None,
    on_chunk: Callable[[ChunkProgress], None] | None = None,
    cluster_tol: float = 1e-4,
    bound_tol: float = 1e-6,
) -> ChunkedMultistart:
    """`fit_multistart` in chunks of `chunk` starts, resumable from a record file.

    **Arguments:**
    - `problem`, `key`, `n_starts`, `method`, `design`, `max_steps`, `lanes`, `cluster_tol`,
      `bound_tol`: as in `fit_multistart` (solves never raise; failed starts are reported).
    - `chunk`: starts per compiled batch (default `default_chunk`: 2 per CPU device, every lane
      of an accelerator); the last chunk is padded with copies of its last start, whose results
      are dropped.
    - `record`: a JSON-lines file. Starts already recorded there (by an earlier call with the
      same problem, key, design and `n_starts`) are read back, not run; every finished start is
      appended (one line per start, with its design `index`, flushed after each chunk).
    - `on_compile(chunk)`: called before the batch is compiled (ahead of time, once).
    - `on_chunk(ChunkProgress)`: called after every chunk.

    A `KeyboardInterrupt` during the chunks stops the run and keeps the finished ones.

    **Returns:** a `ChunkedMultistart`.

    **Raises:** `ValueError` for a bad `chunk` or a record written by another run.
    """
    tic = time.perf_counter()
    batched, problem = problem, as_problem(problem)  # batched_fits takes the objective itself
    thetas = np.asarray(design_starts(problem, key, n_starts, design))
    starts = np.asarray(jax.vmap(problem.transform.to_physical)(thetas))
    chunk = chunk or default_chunk(lanes, thetas.shape[1])
    if chunk < 1:
        raise ValueError(f"`chunk` must be >= 1, got {chunk}")
    path = None if record is None else Path(record)
    done = {} if path is None else _read_record(path, starts)
    resumed = len(done)
    todo = [i for i in range(n_starts) if i not in done]
    compile_time, interrupted = 0.0, False
    best_jacobian = _BestJacobian()
    pieces = []  # (design indices, BatchResult)
    if done:
        pieces.append((sorted(done), _outputs_from_records([done[i] for i in sorted(done)])))
    n_done = resumed
    try:
        if todo:
            width = min(chunk, len(todo))
            runner = batched_fits(batched, method, max_steps, lanes=lanes)
            if on_compile is not None:
                on_compile(width)
            t0 = time.perf_counter()
            runner.compile(batched, thetas[todo[:width]])
            compile_time = time.perf_counter() - t0
        t_run = time.perf_counter()
        for k in range(math.ceil(len(todo) / chunk)):
            idx = todo[k * chunk : (k + 1) * chunk]
            padded = idx + [idx[-1]] * (width - len(idx))
            batch = runner(batched, thetas[padded])
            # on the host from here: slicing device arrays would compile a program per leaf
            batch = jax.tree.map(lambda x: np.asarray(x)[: len(idx)], batch)
            records = _chunk_records(problem, thetas[idx], batch)
            if path is not None:
                _append(path, idx, records, batch.outputs[0])
            pieces.append((idx, best_jacobian.update(idx, batch)))
            n_done += len(idx)
            if on_chunk is not None:
                now = time.perf_counter()
                costs = np.array([r["cost"] for r in records])
                failed = np.array([r["failed"] for r in records])
                progress = (n_done, n_starts, resumed, costs, failed, records)
                on_chunk(ChunkProgress(*progress, now - tic, now - t_run))
    except KeyboardInterrupt:
        interrupted = True
    result, indices, t_stats = None, [], time.perf_counter()
    if pieces:
        indices = np.concatenate([np.asarray(i, int) for i, _ in pieces])
        order = np.argsort(indices)
        indices = indices[order].tolist()
        merged = jax.tree.map(lambda x: x[order], _concat([b for _, b in pieces]))
        result = collect(
            problem,
            thetas[indices],
            merged,
            time.perf_counter() - tic,
            cluster_tol=cluster_tol,
            bound_tol=bound_tol,
            throw=False,
            jacobian_of=lambda h: best_jacobian.of(indices[h]),
        )
    now = time.perf_counter()
    return ChunkedMultistart(
        result, tuple(indices), interrupted, resumed, compile_time, now - t_stats, now - tic
    )
