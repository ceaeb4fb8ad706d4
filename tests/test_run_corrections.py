"""Per-run corrections of track position and speed fitted as nuisance parameters (issue 19,
item 4 (a) and (b)): `Objective.with_run_corrections()` over x = [theta, offsets, log speed
factors].

Two noise-free runs (0.5 s at 100 Hz, true speeds 30 and 50 m/s) are windows starting at track
position 3.1 m of runs that started at rest at 0 (lead-in 3.1 m). The fit sees a track record
shifted along the track (record irregularity at s = true one at s + d, d = 0.3 m and -0.2 m,
built as `recorded_track` of the demo: `s0` lowered by d) and speeds given 1 % off (the true
speed is 1.01 and 0.99 times the given one). Tsit5 with a constant step for data and model
alike, so that the residuals are smooth in x; the window start 3.1 m puts the step grid of the
lead-in (which starts at -lead_in / speed in window time) off the sample times at the truth:
where a sample time crosses a step boundary the interpolated output has a kink at the level of
the local error (seen with a 3.0 m start: Gauss-Newton then stalls at 6e-6 m from the truth).

Oracles: residuals of objectives built directly from measurements with the shifted start
position and scaled speed (`make_objective`, independent of the corrections code); central
finite differences of the residuals for the Jacobian columns; the known offsets and speed
factors of the synthetic data for the fit. Compiled programs (data simulation, corrected
residuals vmapped and looped, single-run residuals, corrected Jacobian) are shared through
module-level functions and fixtures.
"""

import dataclasses

import diffrax as dfx
import equinox as eqx
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

from bogie_jax.cost import (
    CorrectedObjective,
    RunCorrections,
    make_joint_objective,
    make_objective,
    residual_jacobian,
)
from bogie_jax.measure import synthetic_measurement
from bogie_jax.params import manchester_benchmark
from bogie_jax.simulation import SolveSettings
from bogie_jax.track import ERRIB176Spectrum, TrackIrregularity, synthesise_track


RATE, DURATION, START = 100.0, 0.5, 3.1  # [Hz], [s], [m]: the window's first sample
DT = 2.5e-3  # [s] constant step (as tests/test_lead_in.py)
TRUE_SPEEDS = (30.0, 50.0)  # [m/s]
SPEED_FACTORS = (1.01, 0.99)  # true speed / given speed
RECORD_OFFSETS = (0.3, -0.2)  # [m]: record irregularity at s = true one at s + d
NAMES = ("yaw_dampers.left.c",)
GN_STEPS = 6

_residuals = eqx.filter_jit(lambda objective, x: objective.residuals(x))
_jacobian = eqx.filter_jit(residual_jacobian)


def _fixed_step(**kw):
    return dict(stepsize_controller=dfx.ConstantStepSize(), dt0=DT, max_steps=2048, **kw)


SETTINGS = SolveSettings.for_objective(**_fixed_step()).forward_mode()


@pytest.fixture(scope="module")
def nominal():
    return manchester_benchmark()


@pytest.fixture(scope="module")
def true_track():
    return synthesise_track(
        ERRIB176Spectrum.low(), key=jr.PRNGKey(0), length=45.0, fade_length=2.0, start=-5.0
    )


@pytest.fixture(scope="module")
def measurements(nominal, true_track):
    """Noise-free windows at the true speeds, labelled with the given (wrong) speeds."""
    out = []
    for v, f in zip(TRUE_SPEEDS, SPEED_FACTORS):
        m = synthetic_measurement(
            nominal, true_track, speed=v, duration=DURATION, sample_rate=RATE,
            start_position=START, lead_in=START, settings=SolveSettings(**_fixed_step()),
        )  # fmt: skip
        out.append(dataclasses.replace(m, speed=v / f))
    return tuple(out)


@pytest.fixture(scope="module")
def records(true_track):
    """The track records of the two runs, shifted by `RECORD_OFFSETS`."""
    values = np.asarray(true_track.values)
    s0, ds = float(true_track.s0), float(true_track.ds)
    return tuple(TrackIrregularity(s0 - d, ds, values) for d in RECORD_OFFSETS)


@pytest.fixture(scope="module")
def corrected(measurements, nominal, records):
    objective = make_joint_objective(measurements, nominal, records, NAMES, settings=SETTINGS)
    assert objective.residual_model.vmapped
    return objective.with_run_corrections()


def _x_true():
    """Offsets -d (the record's s is the true s + d) and log(true / given speed)."""
    return np.concatenate([np.zeros(len(NAMES)), -np.array(RECORD_OFFSETS), np.log(SPEED_FACTORS)])


# ------------------------------------------------------------------------------------------
# the API without compiling
# ------------------------------------------------------------------------------------------


def test_layout_of_x_and_input_errors(corrected):
    assert isinstance(corrected, CorrectedObjective)
    assert (corrected.n_theta, corrected.n_runs, corrected.n_params) == (1, 2, 5)
    assert corrected.names == (
        *NAMES, "position_offset[0]", "position_offset[1]",
        "log_speed_factor[0]", "log_speed_factor[1]",
    )  # fmt: skip
    assert corrected.units[1:] == ("m", "m", "-", "-")
    c = RunCorrections(position_offset=[0.1, -0.2], log_speed_factor=[0.01, -0.02])
    x = np.asarray(corrected.join([0.5], c))
    np.testing.assert_array_equal(x, [0.5, 0.1, -0.2, 0.01, -0.02])
    np.testing.assert_array_equal(x[corrected.offset_slice], [0.1, -0.2])
    np.testing.assert_array_equal(x[corrected.log_speed_slice], [0.01, -0.02])
    theta, back = corrected.split(x)
    np.testing.assert_array_equal(np.asarray(theta), [0.5])
    np.testing.assert_array_equal(np.asarray(back.speed_factor), np.exp([0.01, -0.02]))
    np.testing.assert_array_equal(np.asarray(corrected.join([0.5])), [0.5, 0, 0, 0, 0])
    with pytest.raises(ValueError, match=r"`x` must have shape \(5,\)"):
        corrected.split(np.zeros(3))
    with pytest.raises(ValueError, match="one shape"):
        RunCorrections(position_offset=[0.1, 0.2], log_speed_factor=[0.0])
    with pytest.raises(ValueError, match="holds 1 runs for a residual model of 2"):
        corrected.residual_model.with_corrections(RunCorrections.zeros(1))
    with pytest.raises(TypeError, match="RunCorrections"):
        corrected.residual_model.with_corrections(np.zeros(2))
    # monitor leaves runs out through `residual_model.active`: it reaches the wrapped model
    off = eqx.tree_at(lambda o: o.residual_model.active, corrected, jnp.array([True, False]))
    assert isinstance(off, CorrectedObjective)
    np.testing.assert_array_equal(np.asarray(off.objective.residual_model.active), [True, False])
    single = corrected.residual_model.runs()[0]
    with pytest.raises(ValueError, match="holds 2 runs for a residual model of 1"):
        single.with_corrections(RunCorrections.zeros(2))


def test_profiled_jacobian_is_the_schur_complement(corrected):
    """Oracle: the theta block of (J^T J)^-1 (numpy) is the inverse of J_eff^T J_eff; a zero
    correction column (an inactive run) drops out."""
    rng = np.random.default_rng(0)
    jac = rng.standard_normal((40, corrected.n_params))
    jac[:, 2] = 0.0  # position_offset[1] of a run left out
    eff = np.asarray(corrected.profile_jacobian(jac))
    assert eff.shape == (40, 1)
    keep = [0, 1, 3, 4]
    expected = np.linalg.inv(np.linalg.inv(jac[:, keep].T @ jac[:, keep])[:1, :1])
    np.testing.assert_allclose(eff.T @ eff, expected, rtol=1e-10)
    with pytest.raises(ValueError, match=r"`jac` must have shape \(m, 5\)"):
        corrected.profile_jacobian(jac[:, :4])


# ------------------------------------------------------------------------------------------
# residuals against an independent construction
# ------------------------------------------------------------------------------------------


OFFSETS, FACTORS = np.array([0.25, 0.1]), np.array([1.004, 0.995])  # [m], [-]
THETA = np.array([0.2])


def _corrections():
    return RunCorrections(position_offset=OFFSETS, log_speed_factor=np.log(FACTORS))


@pytest.fixture(scope="module")
def direct(measurements, nominal, records):
    """Residuals at `THETA` of each run built by `make_objective` from a measurement carrying
    the start position + offset and the speed * factor (lead-in as the data's)."""
    out = []
    for m, track, off, f in zip(measurements, records, OFFSETS, FACTORS):
        shifted = dataclasses.replace(
            m, start_position=float(m.start_position) + off, speed=float(m.speed) * f
        )
        objective = make_objective(shifted, nominal, track, NAMES, settings=SETTINGS, lead_in=START)
        out.append(np.asarray(_residuals(objective, THETA)))
    return out


@pytest.mark.heavy  # a program of its own (about 40 s): the joint test below applies each
# run's corrections through the same `ResidualModel.with_corrections`
def test_single_run_corrections_equal_the_shifted_rescaled_run(
    measurements, nominal, records, direct
):
    """One run (R = 1): start + offset and speed * exp(log factor), lead-in unchanged."""
    objective = make_objective(measurements[0], nominal, records[0], NAMES, settings=SETTINGS)
    assert float(objective.residual_model.lead_in) == START
    corrected = objective.with_run_corrections()
    assert corrected.n_params == 3
    c = RunCorrections(position_offset=OFFSETS[:1], log_speed_factor=np.log(FACTORS[:1]))
    got = np.asarray(_residuals(corrected, corrected.join(THETA, c)))
    scale = np.max(np.abs(direct[0]))
    err = np.max(np.abs(got - direct[0])) / scale
    print(f"one run: max |r - r_direct| / max |r| = {err:.2e}")
    assert scale > 10.0  # far from the data: large residuals
    assert err < 1e-12
    plain = np.asarray(_residuals(corrected, corrected.join(THETA)))  # zero corrections
    assert np.max(np.abs(plain - direct[0])) > 0.1 * scale  # the corrections matter


def test_joint_corrections_equal_the_shifted_rescaled_runs(corrected, direct):
    """Both runs through the vmapped joint model, each with its own corrections. Tolerance:
    the vmapped program rounds differently from the single-run one (measured without
    corrections: 8e-11 of the largest residual); a correction given to the wrong run or not
    applied differs by O(1) of it."""
    expected = np.concatenate(direct)
    got = np.asarray(_residuals(corrected, corrected.join(THETA, _corrections())))
    scale = np.max(np.abs(expected))
    err = np.max(np.abs(got - expected)) / scale
    print(f"vmapped: max |r - r_direct| / max |r| = {err:.2e}")
    assert err < 1e-9
    swapped = RunCorrections(position_offset=OFFSETS[::-1], log_speed_factor=np.log(FACTORS[::-1]))
    wrong = np.asarray(_residuals(corrected, corrected.join(THETA, swapped)))
    assert np.max(np.abs(wrong - expected)) > 0.1 * scale


@pytest.mark.heavy
def test_joint_corrections_in_the_loop_form(measurements, nominal, records, direct):
    """The loop form (one solve per run in the program) applies the same corrections."""
    loop = make_joint_objective(
        measurements, nominal, records, NAMES, settings=SETTINGS, vmap=False
    ).with_run_corrections()
    assert not loop.residual_model.vmapped
    expected = np.concatenate(direct)
    got = np.asarray(_residuals(loop, loop.join(THETA, _corrections())))
    err = np.max(np.abs(got - expected)) / np.max(np.abs(expected))
    print(f"loop: max |r - r_direct| / max |r| = {err:.2e}")
    assert err < 1e-9


def test_non_finite_corrections_give_infinite_residuals(corrected):
    x = np.array([0.0, np.nan, 0.0, 0.0, 0.0])
    r = np.asarray(_residuals(corrected, x))
    assert np.all(np.isposinf(r))


# ------------------------------------------------------------------------------------------
# Jacobian columns against finite differences
# ------------------------------------------------------------------------------------------


def test_jacobian_columns_match_central_differences(corrected):
    x = np.array([0.05, -0.25, 0.15, np.log(1.008), np.log(0.992)])
    r, jac = (np.asarray(a) for a in _jacobian(corrected, jnp.asarray(x)))
    plain = np.asarray(_residuals(corrected, x))  # other program: rounding differs
    np.testing.assert_allclose(r, plain, rtol=0, atol=1e-8 * np.max(np.abs(plain)))
    # steps: the residuals carry rounding noise of ~1e-11 of their size (error ~ 1/h below
    # these steps) and are piecewise smooth (cubic track spline, step grid moving with the
    # speed: error ~ h above them); measured errors at these steps 5e-7 to 1.4e-6
    steps = {0: 1e-4, 1: 1e-5, 2: 1e-5, 3: 1e-6, 4: 1e-6}  # [-], [m], [m], [-], [-]
    for j, h in steps.items():
        e = np.zeros_like(x)
        e[j] = h
        plus, minus = (
            np.asarray(_residuals(corrected, x + e)),
            np.asarray(_residuals(corrected, x - e)),
        )
        fd = (plus - minus) / (2 * h)
        size = np.linalg.norm(fd)
        rel = np.linalg.norm(jac[:, j] - fd) / size
        print(f"column {corrected.names[j]}: |J - FD| / |FD| = {rel:.2e}, |FD| = {size:.3e}")
        assert rel < 1e-5
    # the offset and speed columns of one run are zero on the other run's rows
    first, second = corrected.residual_model.run_slices
    for j in (1, 3):
        assert np.all(jac[second, j] == 0) and np.any(jac[first, j] != 0)
    for j in (2, 4):
        assert np.all(jac[first, j] == 0) and np.any(jac[second, j] != 0)


def test_jacobian_along_directions_is_the_jacobian_times_them(corrected):
    """`residual_jacobian(..., directions=D)` (the monitor's blocks of columns) is J D: the
    same primal solve, k tangents instead of n."""
    x = jnp.asarray([0.05, -0.25, 0.15, np.log(1.008), np.log(0.992)])
    r, jac = (np.asarray(a) for a in _jacobian(corrected, x))
    d = np.random.default_rng(3).normal(size=(x.size, 2))
    r_d, jac_d = (np.asarray(a) for a in _jacobian(corrected, x, None, jnp.asarray(d)))
    assert jac_d.shape == (r.size, 2)
    np.testing.assert_array_equal(r_d, r)  # one primal solve, whatever the tangents
    np.testing.assert_allclose(jac_d, jac @ d, rtol=0, atol=1e-10 * np.max(np.abs(jac @ d)))


# ------------------------------------------------------------------------------------------
# fitting the corrections removes the bias
# ------------------------------------------------------------------------------------------


def _gauss_newton(corrected, x0, columns, steps=GN_STEPS):
    """Gauss-Newton on the `columns` of x (the others fixed), from `x0`."""
    x = np.array(x0, dtype=float)
    for _ in range(steps):
        r, jac = (np.asarray(a) for a in _jacobian(corrected, jnp.asarray(x)))
        x[columns] += np.linalg.lstsq(jac[:, columns], -r, rcond=None)[0]
    r = np.asarray(_residuals(corrected, x))
    return x, 0.5 * float(r @ r)


def test_fitted_corrections_recover_offset_and_speed(corrected):
    truth = _x_true()
    start = np.zeros_like(truth)
    start[0] = 0.1  # 10 % above the true (nominal) damping
    x, cost = _gauss_newton(corrected, start, list(range(truth.size)))
    err = x - truth
    print(f"fit with corrections: x = {x}, error {err}, cost {cost:.2e}")
    assert abs(err[0]) < 1e-5  # theta (log scale): relative error of the damping
    np.testing.assert_array_less(np.abs(err[corrected.offset_slice]), 1e-3)  # [m]
    np.testing.assert_array_less(np.abs(err[corrected.log_speed_slice]), 1e-5)
    assert cost < 1e-6

    # without the corrections (held at zero) the same data bias the damping estimate
    biased, cost_biased = _gauss_newton(corrected, np.zeros_like(truth), [0])
    print(f"fit without corrections: theta = {biased[0]:.4f}, cost {cost_biased:.3e}")
    assert abs(biased[0]) > 0.03
    assert cost_biased > 1e3


def test_other_records_swapped_in_give_the_rebuilt_objectives_residuals(
    measurements, nominal, records, corrected
):
    """`JointResidualModel.with_tracks`: records of the same grids swapped into the corrected
    joint objective give the residuals of the objective built on them (`make_joint_objective`);
    a record on another grid is refused, naming it."""
    other = tuple(
        TrackIrregularity(t.s0, t.ds, 0.5 * np.asarray(t.values) + 1e-4) for t in records
    )  # fmt: skip
    rebuilt = make_joint_objective(measurements, nominal, other, NAMES, settings=SETTINGS)
    rebuilt = rebuilt.with_run_corrections()
    joint = corrected.objective.residual_model
    swapped = eqx.tree_at(
        lambda o: o.objective.residual_model, corrected, joint.with_tracks(other)
    )  # fmt: skip
    x = corrected.join(THETA, _corrections())
    expected = np.asarray(_residuals(rebuilt, x))
    got = np.asarray(_residuals(swapped, x))
    assert np.max(np.abs(got - expected)) <= 1e-12 * np.max(np.abs(expected))
    assert np.max(np.abs(got - np.asarray(_residuals(corrected, x)))) > 1e-3 * np.max(
        np.abs(expected)
    )
    shifted = (TrackIrregularity(other[0].s0 + 0.1, other[0].ds, other[0].values), other[1])
    with pytest.raises(ValueError, match=r"`tracks\[0\]`.*not on the grid"):
        joint.with_tracks(shifted)
    with pytest.raises(ValueError, match="1 records for 2 runs"):
        joint.with_tracks(other[:1])
    loop = make_joint_objective(
        measurements, nominal, records, NAMES, settings=SETTINGS, vmap=False
    )
    swapped_loop = loop.residual_model.with_tracks(other)
    for run, record in zip(swapped_loop.runs(), other):
        np.testing.assert_array_equal(np.asarray(run.track.values), np.asarray(record.values))
