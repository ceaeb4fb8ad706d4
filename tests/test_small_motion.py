"""The small-motion model's exactly discretised response (`bogie_jax.small_motion`) against
independent oracles: scipy's matrix exponential, scipy's integration of the same linear system,
the closed-form response of a damped oscillator to a ramp, and the full equations of motion
(diffrax) at small amplitude, where the two differ by the second-order terms only."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.integrate
import scipy.linalg

import bogie_jax as bj
from bogie_jax.model import build_model, inputs_vector, small_motion_system, track_inputs
from bogie_jax.small_motion import expm, hold_matrices, simulate_small_motion


SPEED, DURATION, RATE = 50.0, 0.5, 100.0
WINDOW = dict(speed=SPEED, duration=DURATION, sample_rate=RATE, start_position=40.0, lead_in=20.0)


@pytest.mark.parametrize("norm", [1e-3, 0.7, 30.0, 2e3])
def test_expm_matches_scipy_at_every_norm(norm):
    rng = np.random.default_rng(int(norm * 1e3))
    m = rng.normal(size=(9, 9))
    m *= norm / np.max(np.sum(np.abs(m), axis=0))
    m -= np.eye(9) * norm / 2  # a decaying system's matrix at large norms (finite exponential)
    got = np.asarray(expm(jnp.asarray(m)))
    assert np.allclose(got, scipy.linalg.expm(m), rtol=1e-9, atol=1e-12)


def _oscillator_ramp_response(t, zeta, omega):
    """x(t) of x'' + 2 zeta omega x' + omega^2 x = t, x(0) = x'(0) = 0 (closed form)."""
    wd = omega * np.sqrt(1 - zeta**2)
    c1 = 2 * zeta / omega**3
    transient = np.exp(-zeta * omega * t) * (
        c1 * np.cos(wd * t) + (2 * zeta**2 - 1) / (omega**2 * wd) * np.sin(wd * t)
    )
    return t / omega**2 - c1 + transient


def test_a_hold_step_is_exact_for_an_input_linear_in_time():
    """A first-order hold is exact where the input is linear: a damped oscillator driven by a
    ramp, stepped at h = 0.05 s, matches the closed form to rounding."""
    zeta, omega, h = 0.2, 7.0, 0.05
    a = jnp.array([[0.0, 1.0], [-(omega**2), -2 * zeta * omega]])
    b = jnp.array([[0.0], [1.0]])
    phi, g0, g1 = hold_matrices(a, b, h)
    x, t = jnp.zeros(2), 0.0
    for _ in range(40):
        x = phi @ x + g0 @ jnp.array([t]) + g1 @ jnp.array([h])
        t += h
    assert float(x[0]) == pytest.approx(_oscillator_ramp_response(t, zeta, omega), rel=1e-10)


@pytest.fixture(scope="module")
def setting():
    params = bj.manchester_benchmark()
    track = bj.synthesise_track(
        bj.track.spectrum_from_name("erri-low"), key=jax.random.PRNGKey(5), length=120.0
    )
    return params, track


def _scaled(track, factor):
    return bj.track.TrackIrregularity(track.s0, track.ds, factor * np.asarray(track.values))


def _rms_error(x, ref):
    """RMS of x - ref over the samples relative to ref's RMS about its mean, per column."""
    ref = np.asarray(ref)
    spread = np.sqrt(np.mean((ref - ref.mean(axis=0)) ** 2, axis=0))
    return np.sqrt(np.mean((np.asarray(x) - ref) ** 2, axis=0)) / spread


def test_the_response_is_scipys_integration_of_the_same_linear_system(setting):
    """Oracle: scipy's `solve_ivp` (Radau, rtol 1e-9) of d(dy)/dt = a dy + b u(t), u the
    track's inputs under the wheelsets (tabulated 28 times finer than the hold's steps). The
    hold's error is second order in the step: at 8 steps per sample (6.25 cm at 50 m/s) within
    0.3 % of each coordinate's RMS."""
    params, track = setting
    lin = simulate_small_motion(params, track, **WINDOW)
    system = small_motion_system(params, SPEED)
    model = build_model(params, speed=SPEED, track=track)
    first = WINDOW["start_position"] / SPEED
    t0, ts = first - WINDOW["lead_in"] / SPEED, np.asarray(lin.ts)
    fine = np.linspace(t0, ts[-1], 20001)  # 45 us apart: 28 times finer than the hold's steps
    u = np.asarray(jax.vmap(lambda t: inputs_vector(*track_inputs(model, t)))(fine))
    a, b = np.asarray(system.a), np.asarray(system.b)
    bu = u @ b.T

    def rhs(t, y):  # u linear between the tabulated points
        i = min(max(int(np.searchsorted(fine, t)) - 1, 0), len(fine) - 2)
        w = (t - fine[i]) / (fine[i + 1] - fine[i])
        return a @ y + (1 - w) * bu[i] + w * bu[i + 1]

    sol = scipy.integrate.solve_ivp(
        rhs, (t0, ts[-1]), np.zeros(20), method="Radau", t_eval=ts, rtol=1e-9, atol=1e-13, jac=a
    )
    y = sol.y.T + np.asarray(system.rest)
    assert np.max(_rms_error(lin.q, y[:, :10])) < 3e-3
    assert np.max(_rms_error(lin.qd, y[:, 10:])) < 3e-3


def test_the_small_motion_model_is_the_full_model_to_first_order(setting):
    """Oracle: the full equations of motion (diffrax). On the track scaled down to a tenth, the
    accelerations agree within 1.5 % of each one's RMS; on the track itself the relative
    difference is about ten times that: it grows with the motion's size, as the second-order
    terms the small-motion model leaves out do (the hold's own error, 0.1-0.3 %, does not)."""
    params, track = setting
    errors = []
    for factor in (0.1, 1.0):
        small = _scaled(track, factor)
        full = bj.simulate(params, small, **WINDOW)
        lin = simulate_small_motion(params, small, **WINDOW)
        errors.append(np.max(_rms_error(lin.qdd, full.qdd)))
    assert errors[0] < 1.5e-2
    assert 5.0 < errors[1] / errors[0] < 20.0


def test_a_start_off_rest_decays_as_the_matrix_exponential(setting):
    """Oracle: on a track without irregularity the deviation from rest from `y0` is
    expm(a t) (y0 - rest) (scipy's matrix exponential), t from the start of the lead-in."""
    params, track = setting
    system = small_motion_system(params, SPEED)
    kick = np.zeros(20)
    kick[[0, 1, 10, 11]] = [2e-3, 1e-3, 0.05, -0.02]  # wheelset 1: y [m], yaw [rad], rates
    y0 = np.asarray(system.rest) + kick
    lin = simulate_small_motion(params, _scaled(track, 0.0), y0=y0, **WINDOW)
    t = np.asarray(lin.ts) - (WINDOW["start_position"] - WINDOW["lead_in"]) / SPEED
    a = np.asarray(system.a)
    expected = np.stack([scipy.linalg.expm(a * tk) @ kick for tk in t])
    got = np.concatenate([lin.q, lin.qd], axis=1) - np.asarray(system.rest)
    assert np.max(np.abs(got - expected)) < 1e-9 * np.max(np.abs(kick)) + 1e-12


def test_bad_arguments_are_named_before_anything_runs(setting):
    params, track = setting
    with pytest.raises(ValueError, match="substeps"):
        simulate_small_motion(params, track, substeps=0, **WINDOW)
    with pytest.raises(ValueError, match="speed"):
        simulate_small_motion(params, track, **{**WINDOW, "speed": -1.0})
    with pytest.raises(ValueError, match="lead_in_steps"):
        simulate_small_motion(params, track, lead_in_steps=0, **WINDOW)
    with pytest.raises(ValueError, match="y0"):
        simulate_small_motion(params, track, y0=np.zeros(3), **WINDOW)
    with pytest.raises(ValueError, match="lead_in_steps"):
        jax.jit(lambda v: simulate_small_motion(params, track, **{**WINDOW, "speed": v}).q)(SPEED)
