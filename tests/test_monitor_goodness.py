"""Does the fit explain the data (issue 51, item 3): the goodness-of-fit test per run and channel
group (`bogie_jax/monitor/_goodness.py`) on constructed residuals, the score test of the elements
not judged and the withheld alarms (`_suspects.py`), the result's fields and the command's exit
code. Pure numpy: nothing is simulated or compiled."""

import dataclasses
import json
import math

import numpy as np
import pytest

from bogie_jax.cost import RunChannels
from bogie_jax.measure import default_sensor_layout
from bogie_jax.monitor import (
    FitSummary,
    GoodnessOfFit,
    Misfit,
    MonitorResult,
    Suspect,
    ToleranceBand,
    channel_groups,
    decision_z,
    freed_interval,
    freed_step,
    goodness_of_fit,
    judge,
    omitted_elements,
    recheck_alarm,
    relative_change,
    score_tests,
)
from bogie_jax.params import manchester_benchmark


try:
    from blank_data import blank_measurement
except ImportError:  # tests/ imported as a package
    from tests.blank_data import blank_measurement


N, RATE = 100, 100.0  # one 1 s run at 100 Hz


@pytest.fixture(scope="module")
def setting():
    sensors = default_sensor_layout(manchester_benchmark())
    c = len(sensors)
    m = blank_measurement(sensors, n=N, rate=RATE, speed=30.0, track_length=200.0)
    runs = RunChannels.of([slice(0, N * c), slice(N * c, 2 * N * c)], c)
    rows = runs.expand(np.random.default_rng(1).uniform(0.5, 2.0, (2, c)))
    return m, runs, rows


def _noise(runs, rows, rng):
    return runs.centre(rng.normal(size=rows.size) * rows)


def test_channel_groups_follow_the_sensor_layout(setting):
    m, _, _ = setting
    groups = dict(channel_groups(m))
    assert list(groups) == ["frame lateral", "frame vertical", "yaw rate", "axlebox lateral"]
    assert [m.channels[j] for j in groups["yaw rate"]] == ["frame_yaw_rate"]
    assert all(m.channels[j].endswith("_z") for j in groups["frame vertical"])
    assert len(groups["axlebox lateral"]) == 4
    # without a layout: the same groups from the channels' names and units
    bare = blank_measurement(default_sensor_layout(manchester_benchmark()), n=N, rate=RATE,
                             speed=30.0)  # fmt: skip
    assert dict(channel_groups(bare)) == groups


def test_white_residuals_are_explained_at_the_nominal_rate(setting):
    """White noise (each channel its own level): the family-wise rejection rate over 2 runs x 4
    groups is at most the false-alarm rate (Holm), in either tail, and each test's p-value is
    near uniform in both tails (600 draws: rate 5 % +- 1.8 % at two standard errors; measured
    5.3 % in 1000)."""
    m, runs, rows = setting
    rng = np.random.default_rng(2)
    rejected, overstated, p, p_lower = 0, 0, [], []
    for _ in range(600):
        g = goodness_of_fit(_noise(runs, rows, rng), runs, rows, [m, m], None, 0.05)
        rejected += not g.explained
        overstated += bool(g.overstated)
        p += [t.p_value for t in g.tests]
        p_lower += [t.p_lower for t in g.tests]
    assert len(g.tests) == 8
    assert rejected / 600 < 0.08 and overstated / 600 < 0.08
    p, p_lower = np.array(p), np.array(p_lower)
    assert 0.035 < np.mean(p < 0.05) < 0.065
    assert np.mean(p < 0.01) < 0.02
    assert 0.035 < np.mean(p_lower < 0.05) < 0.065
    assert np.mean(p_lower < 0.01) < 0.02


def test_a_low_frequency_sinusoid_in_one_group_is_named(setting):
    m, runs, rows = setting
    rng = np.random.default_rng(3)
    r = _noise(runs, rows, rng)
    vertical = dict(channel_groups(m))["frame vertical"]
    t = np.arange(N) / RATE
    block = r[runs.slices[1]].reshape(N, -1)
    for j in vertical:  # 6 Hz, the variance of the channel's noise
        block[:, j] += np.sqrt(2) * rows[runs.slices[1]][j] * np.sin(2 * np.pi * 6 * t)
    r[runs.slices[1]] = runs.centre(r)[runs.slices[1]]
    g = goodness_of_fit(r, runs, rows, [m, m], None, 0.05)
    assert not g.explained
    assert [(x.run, x.group) for x in g.misfits] == [(1, "frame vertical")]
    assert g.misfits[0].ratio > 2
    # the same sinusoid in the track records' error draws is explained (the null holds it)
    shape = np.zeros((16, r.size))
    for d in range(16):
        s = np.zeros((N, runs.n_channels))
        s[:, list(vertical)] = np.sqrt(2) * np.sin(2 * np.pi * 6 * t + d)[:, None]
        shape[d, runs.slices[1]] = (s * rows[runs.slices[1]].reshape(N, -1)).ravel()
    assert goodness_of_fit(r, runs, rows, [m, m], shape, 0.05).explained


def test_a_record_error_told_far_larger_than_the_misfit_is_overstated(setting):
    """Draws of the records' error that leave a 6 Hz misfit of 3 times the noise's amplitude in
    run 0's frame vertical group, on residuals of white noise alone: that group, and only it,
    holds less than the error as told should leave (`overstated`); the data stay explained."""
    m, runs, rows = setting
    r = _noise(runs, rows, np.random.default_rng(5))
    vertical = list(dict(channel_groups(m))["frame vertical"])
    t = np.arange(N) / RATE
    shape = np.zeros((16, r.size))
    for d in range(16):
        s = np.zeros((N, runs.n_channels))
        s[:, vertical] = 3 * np.sqrt(2) * np.sin(2 * np.pi * 6 * t + d)[:, None]
        shape[d, runs.slices[0]] = (s * rows[runs.slices[0]].reshape(N, -1)).ravel()
    g = goodness_of_fit(r, runs, rows, [m, m], shape, 0.05)
    assert g.explained
    assert [(x.run, x.group) for x in g.overstated] == [(0, "frame vertical")]
    assert g.overstated[0].ratio < 0.3 and g.overstated[0].p_lower < 1e-3
    assert not goodness_of_fit(r, runs, rows, [m, m], None, 0.05).overstated


def test_a_residual_far_below_the_stated_noise_is_not_called(setting):
    """A fit of noise-free data converges to a tiny, smooth residual: no misfit the sensors could
    see at their stated noise."""
    m, runs, rows = setting
    t = np.tile(np.repeat(np.arange(N) / RATE, runs.n_channels), 2)
    r = runs.centre(1e-4 * rows * np.sin(2 * np.pi * 3 * t))
    assert goodness_of_fit(r, runs, rows, [m, m], None, 0.05).explained


def test_the_score_test_finds_the_omitted_column_and_the_alarm_is_withheld():
    """A linear model: the data hold an omitted column; the fitted column absorbs part of it
    (an alarm), the score test ranks the omitted column first, and with it free the alarm no
    longer holds."""
    rng = np.random.default_rng(4)
    m = 400
    jac = rng.normal(size=(m, 2))
    omitted = 0.6 * jac[:, :1] + 0.8 * rng.normal(size=(m, 1))
    others = rng.normal(size=(m, 5))
    data = -0.5 * omitted[:, 0] + 0.05 * rng.normal(size=m)  # r = model - data
    step = np.linalg.lstsq(jac, data, rcond=None)[0]
    r = jac @ step - data
    s2 = float(r @ r) / (m - 2)
    lm, change, _ = score_tests(jac, r, np.column_stack([omitted, others]), s2)
    assert np.argmax(lm) == 0 and lm[0] > 100 and np.all(lm[1:] < 15)
    assert change[0] == pytest.approx(-0.5, abs=0.05)
    band = ToleranceBand.relative(1.0, 0.2)
    z = decision_z(0.05, 2)
    estimate = float(np.exp(step[0]))  # about exp(-0.3): degraded without the omitted column
    v = judge("a", estimate, 0.01, band, z=z)
    assert v.verdict == "degraded"
    held = recheck_alarm(v, 0, jac, r, omitted)
    assert held.verdict == "not identifiable" and held.evidence["withheld"] == "degraded"
    assert held.evidence["with_suspects_free"]["estimate"] == pytest.approx(1.0, abs=0.02)
    assert "does not explain" in held.evidence["reason"]
    # an alarm that holds with the column free is kept
    collinear = recheck_alarm(v, 0, jac, r, 2.0 * jac[:, :1])  # determines the coordinate
    assert collinear.verdict == "not identifiable"
    assert collinear.evidence["with_suspects_free"]["std_error"] == float("inf")
    kept = recheck_alarm(v, 0, jac, r, others[:, :1])
    assert kept.verdict == "degraded" and "with_suspects_free" in kept.evidence


def test_a_profile_decided_alarm_is_rechecked_in_ln_p_when_the_freed_step_is_huge():
    """A `failed` verdict decided by its profile test, and a suspect column that all but
    determines the coordinate: the freed step is hundreds in ln p (exp underflows to 0). The
    recheck scales the statistic by the distances to the limit in ln p, before and after the
    step, and by the standard errors' ratio: a finite statistic, no error."""
    rng = np.random.default_rng(9)
    m = 300
    jac = rng.normal(size=(m, 1))
    delta = 1e-4 * rng.normal(size=(m, 1))
    r = -1e6 * delta[:, 0]
    step, ratio = freed_step(jac, r, jac + delta, 0)
    assert step < -745  # exp(step) == 0.0 in double precision
    band = ToleranceBand.relative(1.0, 0.2)
    v = judge("a", 1e-3, 1e-4, band, z=decision_z(0.05, 1))
    assert v.verdict == "failed"
    decided = [{"limit": band.failed_below, "wald": 1e3,
                "profile": {"status": "converged", "statistic": 40.0}}]  # fmt: skip
    v = dataclasses.replace(v, evidence=dict(v.evidence, tests=decided))
    held = recheck_alarm(v, 0, jac, r, jac + delta)
    check = held.evidence["with_suspects_free"]
    assert check["estimate"] == 0.0 and math.isfinite(check["statistic"])
    distance = math.log(1e-3 / band.failed_below)  # the estimate's, below the limit
    expected = 40.0 * (distance + step) / distance / math.sqrt(ratio)
    assert check["statistic"] == pytest.approx(expected, rel=1e-12)
    assert check["holds"] == (expected > v.evidence["z"])


def test_an_interval_with_the_suspect_free_is_that_of_the_fit_with_its_column():
    """A linear model in ln p: y = J phi + j_x d + noise fitted without j_x. Oracle: numpy's
    least squares with j_x as a column: its estimate of phi_0 and the ratio of its Gauss-Newton
    variance, (J_w^T J_w)^-1_00 over (J^T J)^-1_00. Over 400 noise draws the freed intervals
    hold the truth in 90-98 % (the fit's own: under half)."""
    rng = np.random.default_rng(8)
    m, sigma = 300, 0.05
    jac = rng.normal(size=(m, 2))
    omitted = 0.7 * jac[:, :1] + 0.7 * rng.normal(size=(m, 1))
    wide = np.column_stack([jac, omitted])
    var_ratio = np.linalg.inv(wide.T @ wide)[0, 0] / np.linalg.inv(jac.T @ jac)[0, 0]
    band = ToleranceBand.relative(1.0, 0.2)
    z = decision_z(0.05, 2)
    held = [0, 0]
    for _ in range(400):
        data = -0.1 * omitted[:, 0] + sigma * rng.normal(size=m)  # truth: phi = 0
        phi = np.linalg.lstsq(jac, data, rcond=None)[0]
        r = jac @ phi - data
        se = sigma * np.sqrt(np.linalg.inv(jac.T @ jac)[0, 0])
        v = judge("a", float(np.exp(phi[0])), float(np.exp(phi[0]) * se), band, z=z)
        free = freed_interval(v, 0, jac, r, omitted)
        oracle = np.linalg.lstsq(wide, data, rcond=None)[0][0]
        assert free.estimate == pytest.approx(np.exp(oracle), rel=1e-9)
        assert free.std_error == pytest.approx(free.estimate * se * np.sqrt(var_ratio), rel=1e-9)
        assert free.evidence["estimate_before_suspects_free"] == v.estimate
        held[0] += v.ci95[0] <= 1.0 <= v.ci95[1]
        held[1] += free.ci95[0] <= 1.0 <= free.ci95[1]
    print(f"intervals holding the truth: fit {held[0]}/400, with the column free {held[1]}/400")
    assert held[0] < 200 and 360 <= held[1] <= 392
    # a column that all but determines the coordinate: a step beyond exp's range either way, or
    # an infinite variance ratio, leaves the verdict as it is
    delta = 1e-4 * rng.normal(size=(m, 1))
    for sign in (1.0, -1.0):
        assert abs(freed_step(jac, sign * 1e6 * delta[:, 0], jac[:, :1] + delta, 0)[0]) > 1e3
        assert freed_interval(v, 0, jac, sign * 1e6 * delta[:, 0], jac[:, :1] + delta) == v
    assert freed_interval(v, 0, jac, r, 2.0 * jac[:, :1]) == v


def test_elements_not_judged_exclude_candidates_and_their_tied_groups():
    params = manchester_benchmark()
    names = omitted_elements(params, ("yaw_dampers.c", "primary.1L.kz"), ("contact.cone_slope",))
    assert "secondary.left.cz" in names and "primary.1R.kz" in names
    assert not any(n.startswith("yaw_dampers.") and n.endswith(".c") for n in names)
    assert "primary.1L.kz" not in names


def _result(goodness):
    fit = FitSummary(("d",), "converged", 1, 1, 0.0, 1.0, 1.0, 1, 1.0, 1)
    v = judge("d", 400e3, 10e3, ToleranceBand.relative(400e3, 0.2), z=2.5)
    return MonitorResult((v,), (), fit, (), 0.05, {}, goodness)


def test_result_says_where_the_data_are_not_explained():
    bad = Misfit(1, "frame vertical", ("frame_1L_z",), 40.0, 4.0, 0.0, 10.0, 1e-9, True)
    good = Misfit(0, "yaw rate", ("frame_yaw_rate",), 1.0, 1.0, 0.0, 1.0, 0.5, False)
    suspect = Suspect("secondary.left.cz", 120.0, 1e-20, -0.6, ("run 1 frame vertical",))
    result = _result(GoodnessOfFit((good, bad), 0.05, suspects=(suspect,)))
    assert not result.explained and result.misfits == (bad,)
    record = json.loads(json.dumps(result.to_dict()))
    assert record["explained"] is False
    gof = record["goodness_of_fit"]
    assert gof["misfits"][0]["group"] == "frame vertical" and gof["misfits"][0]["run"] == 1
    assert len(gof["tests"]) == 2 and gof["suspects"][0]["name"] == "secondary.left.cz"
    assert gof["low_band_hz"] == [0.5, 15.0]
    text = result.table()
    assert "DATA NOT EXPLAINED" in text and "run 1 frame vertical" in text
    assert "secondary.left.cz" in text
    fine = _result(GoodnessOfFit((good,), 0.05))
    assert fine.explained and "NOT EXPLAINED" not in fine.table()
    assert fine.to_dict()["explained"] is True


def test_monitor_data_exits_with_3_where_the_data_are_not_explained(tmp_path, monkeypatch):
    """`bogie-jax monitor --data`: the verdicts, table and report written; exit code 3 (not
    0) where the data are not explained; `monitor` and the fitted signals stubbed."""
    from bogie_jax.cli import main, monitor as cli_monitor
    from bogie_jax.io import save_measurement

    sensors = default_sensor_layout(manchester_benchmark())
    files = []
    for k in range(2):
        m = blank_measurement(sensors, n=N, rate=RATE, speed=30.0, track_length=200.0)
        files.append(str(save_measurement(tmp_path / f"run{k}.csv", m)))
    bad = Misfit(0, "frame vertical", ("frame_1L_z",), 40.0, 4.0, 0.0, 10.0, 1e-9, True)
    for goodness, code in ((GoodnessOfFit((bad,), 0.05), 3), (GoodnessOfFit((), 0.05), 0)):
        monkeypatch.setattr(cli_monitor, "monitor", lambda *a, g=goodness, **k: _result(g))
        monkeypatch.setattr(cli_monitor, "fitted_signals", lambda *a, **k: None)
        out = tmp_path / f"out{code}"
        assert main(["monitor", "--data", *files, "--out", str(out)]) == code
        record = json.loads((out / "verdicts.json").read_text())
        assert record["explained"] is (code == 0)
        report = (out / "report.md").read_text()
        assert ("DATA NOT EXPLAINED" in report) is (code == 3)


def test_a_suspects_change_beyond_exps_range_is_infinite_not_an_error():
    """A column that barely touches the data asks for a step of hundreds in ln p: its change
    is reported as inf (or -1), never an OverflowError that would stop the monitor."""
    assert relative_change(800.0) == math.inf
    assert relative_change(-800.0) == -1.0
    assert relative_change(0.1) == pytest.approx(math.expm1(0.1), rel=1e-15)
