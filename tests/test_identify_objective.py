"""Identification on the real objective (issue 4): multistart recovery, intervals under noise,
errors through the entry points, sharding, and the `identify` command.

One short run (`primary3` scenario: 0.25 s at 50 m/s, 100 Hz, all 13 default channels) with the
true primary.kz, primary.cz and yaw_dampers.c offset +15 %, -10 %, +10 % from nominal, searched
inside the +-50 % tolerance band. Data and fits share the solver (Tsit5, PID rtol 1e-8), so the
noise-free minimum sits exactly at the truth. The residual Jacobian is taken in forward mode.
Compiled objects are shared: the problem is a module fixture; one LM batch (the objective
an input of the compiled program, `bogie_jax.identify._batched`) serves the noise-free multistart,
the noisy trials (one data set per member, their intervals from the Jacobian each fit ended with)
and both command runs. Measured alone (2-core CPU, cold, 2026-11-26): the data 19 s, the batch's
compile 55 s, its 4 fits 12 s; the default tests of this file about 110 s. In the suite's
processes the persistent compilation cache does not keep these programs (their solves contain
equinox's error callbacks). The check against unsharded fits compiles `fit` as well (about
60 s more) and is `heavy` (README, "Tests").
"""

import json

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

import bogie_jax.cli.identify as identify_command
from bogie_jax.cli import Parser, Progress, UsageError
from bogie_jax.cost import make_objective
from bogie_jax.identify import (
    SCENARIOS,
    as_problem,
    batched_fits,
    fit,
    fit_multistart,
    fit_multistart_chunked,
    fit_statistics,
    relative_errors,
    scenario_problem,
    stack_objectives,
    tolerance_bounds,
)
from bogie_jax.measure import default_sensor_layout
from bogie_jax.params import manchester_benchmark
from bogie_jax.track import perfect_track


try:
    from blank_data import blank_measurement
except ImportError:  # tests/ imported as a package
    from tests.blank_data import blank_measurement


DURATION, RATE, MAX_STEPS, N_STARTS = 0.25, 100.0, 100, 4
NEAR_BOUND = 1e-4  # ends this close to a bound (fraction of the box width) count as on it
_FIT_STATISTICS = eqx.filter_jit(fit_statistics)


@pytest.fixture(scope="module")
def clean():
    return scenario_problem("primary3", duration=DURATION, sample_rate=RATE)


@pytest.fixture(scope="module")
def multistart4(clean):
    """Noise-free multistart LM, 4 starts sharded over the 4 host devices (the command's path:
    `fit_multistart_chunked`, the objective an input of the compiled batch)."""
    run = fit_multistart_chunked(
        clean.objective,
        key=jr.PRNGKey(0),
        n_starts=N_STARTS,
        chunk=N_STARTS,
        max_steps=MAX_STEPS,
    )
    assert not run.interrupted
    return run.result


@pytest.mark.slow
def test_noise_free_multistart_recovers_truth(clean, multistart4):
    assert jax.device_count() == 4
    res = multistart4
    best = res.best
    assert best is not None and best.success
    np.testing.assert_array_less(relative_errors(best.estimates, clean.truth), 1e-5)
    assert float(best.cost) < 1e-6  # J(truth) = 0; the LM stops within rtol 1e-10 of it
    assert not np.any(np.asarray(best.on_bound))
    assert res.clusters[0].count >= 1
    assert len(res.records()) == N_STARTS
    # estimates never leave the tolerance band
    lo, hi = (
        np.asarray(clean.objective.selection.lower),
        np.asarray(clean.objective.selection.upper),
    )
    assert np.all((res.ends >= lo) & (res.ends <= hi))


# With unit-variance weights and the Gauss-Newton statistics, each parameter's 95 % interval
# should cover the truth in ~95 % of trials (all three together in ~86 %); the seeds below were
# run once and are kept fixed (documented share: at least 3 of these 4 trials cover every truth;
# see benchmarks/results/identification.md for the share over more trials).
NOISE_SEEDS = (11, 12, 13, 14)


@pytest.mark.slow
def test_noisy_truth_inside_intervals(clean):
    objectives, truths = [], []
    for seed in NOISE_SEEDS:
        noisy = scenario_problem(
            "primary3", duration=DURATION, sample_rate=RATE, key=jr.PRNGKey(seed)
        )
        objectives.append(noisy.objective)
        truths.append(noisy.truth)
    # one batch, one noisy data set per member (the compiled batch of the multistart test),
    # every fit from the nominal values (theta = 0)
    fits = batched_fits(clean.objective, "lm", MAX_STEPS)
    batch = fits(stack_objectives(objectives), jnp.zeros((len(objectives), 3)), stacked=True)
    assert not np.any(np.asarray(batch.failed))
    # each fit's statistics from the residual Jacobian and cost its LM state ended with (the
    # multistart's own path: no second Jacobian program)
    out, costs = batch.outputs
    transform = as_problem(clean.objective).transform
    tol = jnp.asarray(1e-6)
    covered = []
    for k, truth in enumerate(truths):
        stats = _FIT_STATISTICS(transform, out.theta[k], costs[k], out.jacobian[k], tol)
        ci = np.asarray(stats["ci95"])
        assert np.all(ci[:, 0] < ci[:, 1])
        covered.append(bool(np.all((ci[:, 0] <= truth) & (truth <= ci[:, 1]))))
        # noise at the sensors' noise level: estimates close to (not at) the truth
        assert np.all(relative_errors(stats["estimates"], truth) < 0.2)
        assert 0.5 < float(stats["noise_variance"]) < 2.0
    assert sum(covered) >= len(NOISE_SEEDS) - 1, covered


@pytest.fixture(scope="module")
def unsimulated():
    """The objective of `clean` (the primary3 selection in its tolerance band) on zero data and
    a perfect track: built without a simulation (nothing compiled), which is all the checks of
    `fit` and `fit_multistart` on their starting points read."""
    scenario = SCENARIOS["primary3"]
    nominal = manchester_benchmark()
    names = tuple(scenario.offsets)
    sensors = default_sensor_layout(nominal)
    n = round(DURATION * RATE) + 1
    zero = blank_measurement(sensors, n=n, rate=RATE, speed=scenario.speed)
    bounds = tolerance_bounds(nominal, names, scenario.band)
    return make_objective(zero, nominal, perfect_track(), names, sensors=sensors, bounds=bounds)


def test_errors_through_entry_points(unsimulated):
    objective = unsimulated
    assert objective.selection.names == ("primary.kz", "primary.cz", "yaw_dampers.c")
    with pytest.raises(ValueError, match="unknown parameter 'primary.kzz'"):
        scenario_problem("primary3", ["primary.kzz"], duration=DURATION, sample_rate=RATE)
    with pytest.raises(ValueError, match="empty"):
        scenario_problem("primary3", [], duration=DURATION, sample_rate=RATE)
    with pytest.raises(ValueError, match="unknown scenario"):
        scenario_problem("nope")
    # primary.kz at 3x nominal: outside its +-50 % band, the others at nominal (inside)
    outside = np.asarray(objective.selection.nominal) * np.array([3.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="strictly inside the bounds: primary.kz"):
        fit(objective, start=outside)
    with pytest.raises(ValueError, match="strictly inside the bounds"):
        fit_multistart(objective, key=jr.PRNGKey(0), starts=outside[None])


def _parse(argv):
    parser = Parser(prog="bogie-jax")
    identify_command.add_parser(parser.add_subparsers(dest="command", parser_class=Parser))
    return parser.parse_args(["identify", *argv])


def _run(args):
    return identify_command.run(args, Progress())


def _args(tmp_path, *extra):
    return _parse(
        [
            "--scenario",
            "primary3",
            "--duration",
            str(DURATION),
            "--noise",
            "0",
            "--starts",
            str(N_STARTS),
            "--chunk",
            str(N_STARTS),
            "--max-steps",
            str(MAX_STEPS),
            "--out",
            str(tmp_path / "out"),
            *extra,
        ]
    )


@pytest.mark.slow
def test_cli_identify(tmp_path, capsys, clean):
    args = _args(tmp_path)
    assert _run(args) == 0
    out = capsys.readouterr().out
    assert "starts 4/4 done" in out and "primary.kz" in out and "95% interval" in out
    res = json.loads((tmp_path / "out" / "results.json").read_text())
    assert [p["name"] for p in res["parameters"]] == ["primary.kz", "primary.cz", "yaw_dampers.c"]
    for p, true in zip(res["parameters"], clean.truth):
        assert p["true"] == pytest.approx(true, rel=1e-12)
        assert p["estimate"] == pytest.approx(true, rel=1e-5)
        assert set(p) >= {"name", "unit", "true", "nominal", "estimate", "ci95"}
    assert len(res["starts"]) == N_STARTS and not res["interrupted"]
    lines = (tmp_path / "out" / "starts.jsonl").read_text().splitlines()
    assert [json.loads(x)["index"] for x in lines] == list(range(N_STARTS))
    for name in ("waterfall.png", "estimates.png"):
        assert (tmp_path / "out" / name).stat().st_size > 1000


@pytest.mark.slow
def test_cli_interrupt_keeps_finished_starts(tmp_path, monkeypatch, capsys):
    calls = []

    def interrupt(chunk):
        calls.append(chunk.done)
        raise KeyboardInterrupt

    monkeypatch.setattr(identify_command, "_on_chunk", lambda progress: interrupt)
    # interrupted after the first of two chunks
    args = _args(tmp_path, "--no-plots")
    args.starts = 2 * N_STARTS  # two chunks of N_STARTS (the compiled batch of the test above)
    assert _run(args) == 130
    res = json.loads((tmp_path / "out" / "results.json").read_text())
    assert res["interrupted"] and res["n_finished"] == N_STARTS and len(res["starts"]) == N_STARTS
    assert len((tmp_path / "out" / "starts.jsonl").read_text().splitlines()) == N_STARTS
    assert calls == [N_STARTS]


def test_cli_list_params(capsys):
    assert _run(_parse(["--list-params"])) == 0
    out = capsys.readouterr().out
    assert "yaw_dampers.c" in out and "N s/m" in out and "nominal" in out
    # both kinds of name: tied groups and single elements (issue 17)
    assert "yaw_dampers.left.c" in out and "primary.1L.kz" in out and "secondary.right.cy" in out


@pytest.mark.parametrize(
    "argv, match",
    [
        (["--starts", "0"], "--starts"),
        (["--method", "newton"], "unknown `--method`"),
        (["--scenario", "nope"], "unknown `--scenario`"),
        (["--design", "grid"], "unknown `--design`"),
        (["--noise", "-1"], "--noise"),
        (["--band", "1.5"], "--band"),
        (["--chunk", "0"], "--chunk"),
        (["--data", "/nonexistent.npz"], "does not exist"),
        (["--params", ","], "empty"),
        (["--params", "primary.kzz", "--duration", "0.1"], "unknown parameter 'primary.kzz'"),
    ],
)
def test_cli_bad_values(tmp_path, argv, match):
    args = _parse([*argv, "--out", str(tmp_path / "o")])
    with pytest.raises(UsageError, match=match):
        _run(args)


def test_cli_bad_data_file(tmp_path):
    bad = tmp_path / "run.txt"
    bad.write_text("t,a\n0,1\n")
    with pytest.raises(UsageError, match="expected a .npz or .csv file"):
        _run(_parse(["--data", str(bad), "--out", str(tmp_path / "o")]))
    with pytest.raises(SystemExit):  # --data and --scenario are exclusive (argparse, exit 2)
        _parse(["--data", str(bad), "--scenario", "default"])


# heavy (README, "Tests"): `fit`'s own program, about 60 s more; by default the per-device
# runner's sharding is checked against one device on an analytic member
# (`test_per_device_runner.py`, and `test_identify.py`'s multistart on 4 devices against one)
@pytest.mark.slow
@pytest.mark.heavy
def test_sharded_multistart_equals_one_device(clean, multistart4):
    """The batch sharded over 4 devices gives the fits run one by one on one device (`fit`,
    which compiles one unbatched program: a second vmapped compilation on one device would
    cost minutes on a small CPU): the same status, cost and on-bound flags for every start, and
    the same estimates where the fit is well determined (not on a bound).

    Why the two differ at all: the same LM and starts, but two compiled evaluation programs
    (the batch's runs one fit per device inside `shard_map`, `fit`'s is a plain `jit`). XLA
    fuses them differently, and the adaptive ODE steps turn those last-bit differences into
    different step sequences, so the objective itself differs at the solver's error level: at
    one theta the residuals of an unbatched and a vmapped program differ by up to 1.6e-4
    (noise-weighted; max |r| 1.7e-4 near the truth), the costs by 4e-4 at J = 2055. Each path
    stops where its own cost stops falling by more than that: near the truth (J ~ 1e-8) the
    estimates agree to ~3e-7. A start that ends on a bound has no stationary point there (in
    logistic coordinates the corner lies at infinity, and the cost keeps falling towards it),
    so each path stops at its own point of the valley: the estimates of such a start are not
    compared; its status, cost and the bounds it ends at are, within `NEAR_BOUND` (1e-4) of the
    box width (`statistics`' own flag, 1e-6, falls inside that spread)."""
    lower = np.asarray(clean.objective.selection.lower)
    upper = np.asarray(clean.objective.selection.upper)
    near = lambda x: np.minimum(x - lower, upper - x) / (upper - lower) < NEAR_BOUND
    compared = 0
    for k, (start, end, cost) in enumerate(
        zip(multistart4.starts, multistart4.ends, multistart4.costs)
    ):
        single = fit(clean.objective, start=start, max_steps=MAX_STEPS, throw=False)
        assert single.status_name == multistart4.status[k]
        # (J ~ 1e-8 where the noise-free fits stop: the stopping point depends on rounding; at a
        # minimum on a bound the cost is not stationary, so it moves with the estimate: 1e-5)
        np.testing.assert_allclose(float(single.cost), cost, rtol=1e-5, atol=1e-6)
        # both ends at the same bounds, within `NEAR_BOUND` of the box width (see above)
        single_end = np.asarray(single.estimates)
        np.testing.assert_array_equal(near(end), near(single_end))
        if not near(end).any():
            np.testing.assert_allclose(single_end, end, rtol=1e-5)
            compared += 1
    # the check cannot pass on bounds alone (with this key at least 3 of the 4 ends interior)
    assert compared >= N_STARTS - 1
