"""`fit_multistart_chunked` on an analytic least-squares problem: chunks agree with one call,
and a run interrupted after a chunk resumes from its record to the same result."""

import json

import jax.numpy as jnp
import jax.random as jr
import numpy as np
import optimistix as optx
import pytest

from bogie_jax.identify import (
    RESULT_NAMES,
    BoxTransform,
    LeastSquaresProblem,
    fit_multistart_chunked,
    local_methods,
    results_from_names,
    status_name,
    status_names,
)


# Two minima in x: global at (1, 0.5), a local one near (-0.98, 0.5); residuals are NaN for
# x < -1.5 (a "failed simulation" region), so some starts fail and are recorded as such. The
# last residual no parameter explains (a model error): the cost at the minimum is 0.005, not 0,
# so the noise variance and the covariance are not degenerate.
TR = BoxTransform([-2.0, -1.0], [2.0, 2.0], names=("x", "y"))


def _residuals(theta, args):
    x, y = TR.to_physical(theta)
    r = jnp.stack([x**2 - 1.0, 0.2 * (x - 1.0), y - 0.5, jnp.ones_like(x) * 0.1])
    return jnp.where(x < -1.5, jnp.nan, r)


PROBLEM = LeastSquaresProblem(_residuals, TR)
N, CHUNK = 7, 3  # three chunks, the last one padded
# the optimum to rounding (no relative-offset stop, see test_levenberg_marquardt.py): the
# chunked ends are compared with the exact minima
EXACT_LM = local_methods(offset_tol=0.0, stall_offset=0.0)["lm"]
KW = dict(key=jr.PRNGKey(3), n_starts=N, chunk=CHUNK, max_steps=200, method=EXACT_LM)


@pytest.fixture(scope="module")
def whole(tmp_path_factory):
    path = tmp_path_factory.mktemp("whole") / "starts.jsonl"
    chunks = []
    run = fit_multistart_chunked(PROBLEM, record=path, on_chunk=chunks.append, **KW)
    return run, path, chunks


def test_one_run_records_every_start(whole):
    run, path, chunks = whole
    assert not run.interrupted and run.resumed == 0 and run.indices == tuple(range(N))
    assert [c.done for c in chunks] == [3, 6, 7] and all(c.total == N for c in chunks)
    assert [len(c.costs) for c in chunks] == [3, 3, 1]
    assert [r["start"] for c in chunks for r in c.records] == run.result.starts.tolist()
    assert all(c.resumed == 0 and c.run_time <= c.elapsed for c in chunks)
    assert np.isfinite(chunks[0].eta()) and chunks[-1].eta() == 0.0
    lines = [json.loads(x) for x in path.read_text().splitlines()]
    assert [x["index"] for x in lines] == list(range(N))
    res = run.result
    assert len(res.costs) == N and res.best is not None
    np.testing.assert_allclose(res.best.estimates, [1.0, 0.5], atol=1e-6)
    assert run.compile_time > 0 and run.statistics_time > 0
    assert run.wall_time >= run.compile_time + run.statistics_time


def test_resume_after_interrupt_gives_the_same_result(whole, tmp_path):
    run, _, _ = whole
    path = tmp_path / "starts.jsonl"

    def interrupt(progress):
        raise KeyboardInterrupt

    first = fit_multistart_chunked(PROBLEM, record=path, on_chunk=interrupt, **KW)
    assert first.interrupted and first.indices == (0, 1, 2)
    assert len(path.read_text().splitlines()) == CHUNK
    second = fit_multistart_chunked(PROBLEM, record=path, **KW)
    assert not second.interrupted and second.resumed == CHUNK
    assert second.indices == tuple(range(N))
    assert len(path.read_text().splitlines()) == N
    a, b = run.result, second.result
    np.testing.assert_allclose(b.starts, a.starts, rtol=1e-12)
    np.testing.assert_allclose(b.ends, a.ends, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(b.costs, a.costs, rtol=1e-9, atol=1e-15)
    np.testing.assert_array_equal(b.failed, a.failed)
    np.testing.assert_array_equal(b.status, a.status)
    np.testing.assert_array_equal(b.num_steps, a.num_steps)
    assert [c.members for c in b.clusters] == [c.members for c in a.clusters]
    np.testing.assert_allclose(b.best.estimates, a.best.estimates, rtol=1e-9)
    np.testing.assert_allclose(b.best.std_errors, a.best.std_errors, rtol=1e-6)
    # a finished record is read back, nothing is run again
    third = fit_multistart_chunked(PROBLEM, record=path, **KW)
    assert third.resumed == N and third.compile_time == 0.0
    np.testing.assert_allclose(third.result.costs, a.costs, rtol=1e-9, atol=1e-15)
    # the best fit's statistics: `run` forms them from the residual Jacobian its fit ended with
    # (no evaluation after the fits), `third` (every start read back: no fit state) evaluates
    # the residual Jacobian at the same theta (`statistics`, one more evaluation in the counts)
    c = third.result.best
    np.testing.assert_array_equal(c.theta, a.best.theta)
    assert int(a.best.num_fn_evals) == int(np.sum(a.num_fn_evals))
    assert int(c.num_fn_evals) == int(np.sum(a.num_fn_evals)) + 1
    assert c.dof == a.best.dof == 2 and float(a.best.cost) == pytest.approx(0.005, rel=1e-6)
    for field in ("estimates", "cost", "noise_variance", "std_errors", "ci95", "covariance"):
        np.testing.assert_allclose(getattr(a.best, field), getattr(c, field), rtol=1e-10)
    np.testing.assert_allclose(a.best.correlation, c.correlation, rtol=1e-10, atol=1e-12)
    np.testing.assert_array_equal(a.best.on_bound, c.on_bound)
    assert a.best.rank == c.rank == 2


def test_record_of_another_run_is_refused(whole):
    _, path, _ = whole
    with pytest.raises(ValueError, match="written by another run"):
        fit_multistart_chunked(PROBLEM, record=path, **{**KW, "key": jr.PRNGKey(4)})


def test_status_is_results_and_travels_by_name(whole, tmp_path):
    """Statuses are `optimistix.RESULTS`, recorded by member name and read back by name; a
    record with a name that is no `RESULTS` member is refused before anything compiles."""
    run, path, _ = whole
    res = run.result
    assert set(res.status) <= set(RESULT_NAMES)
    # failed starts (oracle: the residuals are NaN wherever the run ended at x < -1.5, or the
    # solver status is not successful) are exactly the flagged ones
    expected = (res.status != "successful") | ~np.isfinite(res.costs)
    np.testing.assert_array_equal(res.failed, expected)
    assert isinstance(res.best.status, optx.RESULTS) and res.best.success
    assert status_name(res.best.status) == "successful"
    names = ["successful", "nonlinear_max_steps_reached", "nonfinite"]
    batched = results_from_names(names)
    assert isinstance(batched, optx.RESULTS)
    np.testing.assert_array_equal(status_names(batched), names)
    np.testing.assert_array_equal(
        np.asarray(batched == optx.RESULTS.nonlinear_max_steps_reached), [False, True, False]
    )
    line = json.loads(path.read_text().splitlines()[0])
    bad = tmp_path / "bad.jsonl"
    bad.write_text(json.dumps({**line, "status": "no_such_status"}) + "\n")
    with pytest.raises(ValueError, match="unknown solver status"):
        fit_multistart_chunked(PROBLEM, record=bad, **KW)
