"""Measurement windows that start mid-run (issue 17, items 4 and 7).

A record cut out of a run that was already moving: the objective simulates a lead-in over the
known track before the window, from the static equilibrium, and compares only inside the
window. Noise-free data are cut from the middle of a run that started at rest at track
position 0 (Tsit5 with a constant step for data and model alike, so that the residuals are
smooth in the parameters). With the default lead-in (the whole known track before the window:
the default lead-in time, ~7 s, is longer than the 1 s before it) an LM fit from +10 % recovers
the truth to 1e-5 relative within 10 steps (it reaches ~1e-12; the LM's own stopping test at
rtol 1e-10 is not met on this zero-residual problem before its step limit, so the estimate,
not the status, is checked); started at rest at the window (`lead_in=0`) the estimate is
biased. The compiled programs are shared: both speeds and both
lead-ins have the same shapes (speed, start position and lead-in are traced).

Oracles: `default_lead_in` against numpy's eigenvalues of a central-difference Jacobian of the
vector field at the static equilibrium; the transient after the default lead-in against the
modal amplitudes (left eigenvectors of that Jacobian) of a perturbed start on a perfect track.
"""

import math

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

import bogie_jax as bj
from bogie_jax.cost import DEFAULT_DECAY, default_lead_in, make_objective, slowest_decay_rate
from bogie_jax.identify import fit
from bogie_jax.io import load_measurement, save_measurement
from bogie_jax.measure import (
    Measurement,
    MeasurementError,
    layout_description,
    synthetic_measurement,
)
from bogie_jax.model import (
    build_model,
    static_equilibrium,
    system_matrix,
    vector_field,
)
from bogie_jax.simulation import SolveSettings, simulate
from bogie_jax.track import ERRIB176Spectrum, perfect_track, synthesise_track


RUN, T_START, WINDOW = 1.5, 1.0, 0.5  # [s]: the run from rest, the window's start and length
RATE = 200.0  # [Hz]
DT = 2.5e-3  # [s] constant step (|lambda| max ~ 390 1/s: h |lambda| ~ 1, inside Tsit5's region)
NAMES = ("yaw_dampers.c", "primary.kz")
SPEEDS = (30.0, 60.0)  # [m/s]
FIT_STEPS = 10  # LM steps (one compilation for the four fits)
ASYMMETRIC = {"primary.1L.kz": 1.3, "yaw_dampers.left.c": 0.0, "secondary.left.cy": 0.5}


def _fixed_step(**kw):
    return dict(stepsize_controller=dfx.ConstantStepSize(), dt0=DT, max_steps=2048, **kw)


@pytest.fixture(scope="module")
def nominal():
    return bj.manchester_benchmark()


@pytest.fixture(scope="module")
def track():
    # one track (one array shape) for both speeds: the 60 m/s run plus margins (to 95 m)
    return synthesise_track(
        ERRIB176Spectrum.low(),
        key=jr.PRNGKey(0),
        length=max(SPEEDS) * RUN + 10.0,
        fade_length=2.0,
        start=-5.0,
    )


def _asymmetric(nominal):
    values = {n: f * float(bj.get_parameter(nominal, n)) for n, f in ASYMMETRIC.items()}
    return bj.set_parameters(nominal, values)


@pytest.fixture(scope="module", params=SPEEDS, ids=lambda v: f"{v:g}mps")
def windows(request, nominal, track):
    """Per speed: the window (noise-free data) and its objectives with and without lead-in."""
    speed = request.param
    run = synthetic_measurement(
        nominal, track, speed=speed, duration=RUN, sample_rate=RATE,
        settings=SolveSettings(**_fixed_step()),
    )  # fmt: skip
    window = run.window(T_START, WINDOW)
    settings = SolveSettings.for_objective(**_fixed_step())
    with_lead_in = make_objective(window, nominal, track, NAMES, settings=settings)
    at_rest = make_objective(window, nominal, track, NAMES, settings=settings, lead_in=0.0)
    return dict(
        speed=speed,
        window=window,
        truth=np.asarray(with_lead_in.selection.nominal),
        lead_in=float(with_lead_in.residual_model.lead_in),
        objectives=(with_lead_in, at_rest),
    )


@pytest.fixture(scope="module")
def fits(windows):
    """The fits from +10 % with and without the lead-in (one compiled fit program, about
    100 s of the suite's CPU: the two tests using them are heavy, README "Tests"; by default
    `test_monitor.py::test_monitor_on_windows_cut_from_moving_runs` fits windows cut from
    moving runs, with the default lead-in)."""
    with_lead_in, at_rest = windows["objectives"]
    start = 1.1 * windows["truth"]
    return dict(
        windows,
        fit=fit(with_lead_in, start, max_steps=FIT_STEPS, throw=False),
        fit_at_rest=fit(at_rest, start, max_steps=FIT_STEPS, throw=False),
    )


def test_window_records_its_track_position(windows):
    window, speed = windows["window"], windows["speed"]
    assert float(window.start_position) == pytest.approx(speed * T_START, rel=1e-12)
    assert window.times.shape == (round(WINDOW * RATE) + 1,)
    assert float(window.times[0]) == pytest.approx(T_START, abs=1e-12)
    np.testing.assert_allclose(
        np.asarray(window.positions), speed * np.asarray(window.times), rtol=1e-12
    )
    # the default lead-in is the whole known track before the window (default > start)
    assert windows["lead_in"] == pytest.approx(speed * T_START, rel=1e-12)


@pytest.mark.heavy
def test_fit_with_lead_in_identifies_the_truth(fits):
    result = fits["fit"]
    rel = np.abs(np.asarray(result.estimates) / fits["truth"] - 1)
    print(f"{fits['speed']:g} m/s with lead-in: {result.estimates} relative errors {rel}")
    np.testing.assert_array_less(rel, 1e-5)
    assert float(result.cost) < 1e-6  # J(truth) = 0 (noise-free)
    assert not np.any(result.on_bound)  # log-scale parameters have no box to sit on


@pytest.mark.heavy
def test_fit_without_lead_in_is_biased(fits):
    """Started at rest at the window's first sample, while the data's bogie was moving."""
    result = fits["fit_at_rest"]
    rel = np.abs(np.asarray(result.estimates) / fits["truth"] - 1)
    print(f"{fits['speed']:g} m/s at rest at the window: {result.estimates} rel. errors {rel}")
    assert np.max(rel) > 1e-3
    assert float(result.cost) > 1e3 * max(float(fits["fit"].cost), 1e-12)


# one compiled program for every finite-difference matrix (the model is a traced argument)
_batched_vector_field = jax.jit(jax.vmap(lambda y, model: vector_field(0.0, y, model), (0, None)))


def _fd_system_matrix(params, speed, q0, h=1e-7):
    """Central differences of the vector field at (q0, 0) on a perfect track (20, 20)."""
    model = build_model(params, speed=speed, track=perfect_track())
    y0 = np.concatenate([np.asarray(q0), np.zeros(10)])
    steps = h * np.eye(20)
    plus, minus = (np.asarray(_batched_vector_field(y, model)) for y in (y0 + steps, y0 - steps))
    return ((plus - minus) / (2 * h)).T


def _oracle_lead_in(a, speed):
    eig = np.linalg.eigvals(a)
    sigma = np.min(-eig.real[np.abs(eig) > 1e-8 * np.max(np.abs(eig))])
    return speed * math.log(1 / DEFAULT_DECAY) / sigma


@pytest.mark.parametrize("speed", SPEEDS)
def test_default_lead_in_matches_numpy_eigenvalues(nominal, speed):
    a = _fd_system_matrix(nominal, speed, np.zeros(10))
    expected = _oracle_lead_in(a, speed)
    got = default_lead_in(nominal, speed)
    print(f"default lead-in at {speed:g} m/s: {got:.2f} m (oracle {expected:.2f} m)")
    assert got == pytest.approx(expected, rel=1e-6)
    sigma = slowest_decay_rate(nominal, speed)
    assert got == pytest.approx(speed * math.log(1e3) / sigma, rel=1e-12)
    assert default_lead_in(nominal, speed, decay=1e-6) == pytest.approx(2 * got, rel=1e-12)


def test_system_matrix_linearises_at_the_static_equilibrium(nominal):
    """An asymmetric bogie rests at q0 != 0: the linearisation (and the lead-in) is about q0."""
    params = _asymmetric(nominal)
    q0 = np.asarray(static_equilibrium(params))
    assert np.max(np.abs(q0)) > 1e-4  # heave, roll, pitch of the frame [m, rad]
    at_q0 = _fd_system_matrix(params, 30.0, q0)
    at_zero = _fd_system_matrix(params, 30.0, np.zeros(10))
    a = np.asarray(eqx.filter_jit(system_matrix)(params, jnp.asarray(30.0)))
    scale = np.max(np.abs(at_q0))
    assert np.max(np.abs(a - at_q0)) < 1e-7 * scale
    assert np.max(np.abs(at_zero - at_q0)) > 1e-5 * scale  # the linearisation point matters
    assert default_lead_in(params, 30.0) == pytest.approx(_oracle_lead_in(at_q0, 30.0), rel=1e-6)


def test_transient_after_default_lead_in_is_below_the_ratio(nominal):
    """Start off the rest state on a perfect track; after the default lead-in every modal
    amplitude of the deviation has decayed by at least DEFAULT_DECAY (the slowest by it)."""
    speed = 30.0
    lead = default_lead_in(nominal, speed)
    a = _fd_system_matrix(nominal, speed, np.zeros(10))
    eig, vecs = np.linalg.eig(a)
    rng = np.random.default_rng(0)
    dy = 1e-4 * rng.standard_normal(20)  # [m, rad, m/s, rad/s]: small, the linear regime
    run = simulate(
        nominal, perfect_track(), speed=speed, duration=1 / RATE, sample_rate=RATE,
        start_position=lead, lead_in=lead, y0=dy,
        stepsize_controller=dfx.PIDController(rtol=1e-11, atol=1e-15),
    )  # fmt: skip
    assert bool(run.successful)
    assert float(run.ts[0]) == pytest.approx(lead / speed, rel=1e-12)
    y_end = np.concatenate([np.asarray(run.q[0]), np.asarray(run.qd[0])])
    before, after = np.linalg.solve(vecs, dy), np.linalg.solve(vecs, y_end)
    ratios = np.abs(after) / np.abs(before)
    print(f"modal decay after {lead:.1f} m: slowest {np.max(ratios):.4e}")
    assert np.max(ratios) <= DEFAULT_DECAY * (1 + 1e-3)
    assert np.max(ratios) >= DEFAULT_DECAY * (1 - 1e-3)  # the rule is not over-long


# -- item 7: bad input, before anything is compiled ------------------------------------------


def _small_window(nominal, start_position):
    sensors = bj.default_sensor_layout(nominal)
    return Measurement(
        times=1.0 + np.arange(21) / RATE,
        data=np.zeros((21, len(sensors))),
        channels=[s.name for s in sensors],
        units=[s.unit for s in sensors],
        speed=30.0,
        layout=layout_description(sensors),
        start_position=start_position,
    )


@pytest.mark.parametrize(
    ("lead_in", "match"),
    [
        (-1.0, r"`lead_in` = -1 m is outside the valid range \[0, 45\] m"),
        (45.5, r"`lead_in` = 45.5 m is outside the valid range \[0, 45\] m"),
        (math.nan, r"`lead_in` = nan m is outside the valid range \[0, 45\] m"),
        (math.inf, r"`lead_in` = inf m is outside the valid range"),
    ],
)
def test_make_objective_rejects_bad_lead_in(nominal, track, lead_in, match):
    window = _small_window(nominal, 45.0)
    with pytest.raises(ValueError, match=match):
        make_objective(window, nominal, track, NAMES, lead_in=lead_in)


def test_window_beyond_the_track_is_rejected(nominal, track):
    window = _small_window(nominal, 94.0)  # the track's samples end at 95 m
    with pytest.raises(ValueError, match=r"window beyond the track.*97 m .* 95 m"):
        make_objective(window, nominal, track, NAMES)
    with pytest.raises(ValueError, match="window beyond the track"):
        simulate(nominal, track, speed=30.0, duration=0.5, start_position=90.0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(start_position=-2.0), r"`start_position` = -2 m is outside the valid range \[0,"),
        (dict(start_position=math.nan), r"`start_position` = nan m"),
        (dict(start_position=10.0, lead_in=12.0), r"`lead_in` = 12 m .* \[0, 10\] m"),
        (dict(lead_in=1.0), r"`lead_in` = 1 m is outside the valid range \[0, 0\] m"),
    ],
)
def test_simulate_rejects_bad_window(nominal, kwargs, match):
    with pytest.raises(ValueError, match=match):
        simulate(nominal, perfect_track(), speed=30.0, duration=0.5, **kwargs)
    with pytest.raises(ValueError, match=match):
        synthetic_measurement(nominal, perfect_track(), speed=30.0, duration=0.5, **kwargs)


def test_measurement_start_position_and_window_checks(nominal):
    with pytest.raises(MeasurementError, match="`start_position` must be a finite scalar >= 0"):
        _small_window(nominal, -1.0)
    with pytest.raises(MeasurementError, match="`start_position` must be a finite scalar >= 0"):
        _small_window(nominal, math.inf)
    m = _small_window(nominal, 45.0)
    with pytest.raises(MeasurementError, match=r"`start` = 0.5 s is outside the valid range"):
        m.window(0.5, 0.05)
    with pytest.raises(MeasurementError, match=r"`duration` = 1 s is outside the valid range"):
        m.window(1.0, 1.0)
    cut = m.window(1.05, 0.025)
    assert cut.times.shape == (6,)
    assert float(cut.start_position) == pytest.approx(45.0 + 30.0 * 0.05, rel=1e-12)
    assert cut.channels == m.channels and cut.layout == m.layout


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_start_position_round_trip_and_old_files(nominal, tmp_path, suffix):
    m = _small_window(nominal, 45.25)
    back = load_measurement(save_measurement(tmp_path / f"w{suffix}", m))
    assert float(back.start_position) == 45.25
    np.testing.assert_array_equal(np.asarray(back.times), np.asarray(m.times))
    old = tmp_path / f"old{suffix}"  # a format-2 file: no start position, read as 0
    if suffix == ".npz":
        np.savez(
            old, times=np.asarray(m.times), data=np.asarray(m.data),
            channels=np.array(m.channels), units=np.array(m.units), speed=np.asarray(30.0),
            layout=np.array(m.layout), format=np.array("bogie_jax.measurement/2"),
        )  # fmt: skip
    else:
        text = (tmp_path / f"w{suffix}").read_text().splitlines()
        old.write_text("\n".join(line for line in text if "start_position" not in line))
    assert float(load_measurement(old).start_position) == 0.0
