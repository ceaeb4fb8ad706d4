"""The JAX bogie model against its independent numpy twin (`tests/reference/bogie_twin.py`).

The JAX model (`bogie_jax.model`) derives its equations of motion from the Lagrangian by
automatic differentiation; the twin writes the kinematics by hand and assembles the equations by
Newton-Euler plus virtual power (Kane's method). Both follow `docs/model.md`. Agreement of the
mass matrix, of the right-hand side (with every model option) and of integrated trajectories
(scipy's integrators on the twin vs diffrax on the JAX model) tests the physics code.

The JAX functions are jitted once per module (the model is a traced argument, so only a change
of `ModelOptions` or of the track's sample count recompiles).
"""

import diffrax
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest
import scipy.integrate

import bogie_jax
from bogie_jax.model import build_model, mass_matrix, track_inputs, vector_field
from bogie_jax.params import PARAMETER_SETS, ModelOptions, set_parameters
from bogie_jax.track import ERRIB176Spectrum, TrackIrregularity, synthesise_track


try:
    from reference.bogie_twin import BogieTwin, perfect_track_inputs
except ImportError:  # tests/ imported as a package
    from tests.reference.bogie_twin import BogieTwin, perfect_track_inputs


SPEED = 50.0  # [m/s]
DURATION = 1.0  # [s] trajectory length (the ERRI-track Radau run is shorter, see below)
ERRI_DURATION = 0.5  # [s] Radau on the irregular track (1 s takes ~40 s of CPU)
OPTION_SETS = {
    "linear": ModelOptions(),
    "all": ModelOptions(creep_saturation=True, flange_contact=True, nonlinear_dampers=True),
}
OPTION_NAMES = ("creep_saturation", "flange_contact", "nonlinear_dampers")
# coordinate groups of the trajectory comparison: (q indices) and the same for q_dot
GROUPS = {
    "frame translation": [0, 1, 2],
    "frame rotation": [3, 4, 5],
    "wheelset lateral": [6, 7],
    "wheelset yaw": [8, 9],
}

_vector_field = jax.jit(vector_field)
_mass_matrix = jax.jit(mass_matrix)


@jax.jit
def _diffrax_solve(model, y0, ts):
    solution = diffrax.diffeqsolve(
        diffrax.ODETerm(vector_field),
        diffrax.Dopri8(),
        t0=ts[0],
        t1=ts[-1],
        dt0=1e-4,
        y0=y0,
        args=model,
        stepsize_controller=diffrax.PIDController(rtol=1e-11, atol=1e-13),
        saveat=diffrax.SaveAt(ts=ts),
        max_steps=100_000,
    )
    return solution.ys


# ---------------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def params():
    return bogie_jax.manchester_benchmark()


def asymmetric(params):
    """One failed or changed element per group: left anti-yaw damper at 0, primary 1L vertical
    spring +30 %, secondary left lateral damper at 50 %."""
    return set_parameters(
        params,
        {
            "yaw_dampers.left.c": 0.0,
            "primary.1L.kz": 1.3 * float(params.primary.kz[0]),
            "secondary.left.cy": 0.5 * float(params.secondary.cy[0]),
        },
    )


@pytest.fixture(scope="module")
def asymmetric_params(params):
    return asymmetric(params)


@pytest.fixture(scope="module")
def erri_track(params):
    """ERRI B176 low-level track under both wheelsets from t = 0.

    Spacing 2a/8 (0.32 m): both wheelsets cross spline knots at the same instants, where the
    (C2 spline) track's third derivative jumps; the scipy integration restarts there. The track
    starts 2 spacings behind wheelset 2 (at s = -a at t = 0) with a 1 m fade, so the
    irregularity is non-trivial under both wheelsets almost at once.
    """
    a = float(params.geometry.semi_wheelbase)
    spacing = 2 * a / 8
    start = -a - 2 * spacing
    n = int(np.ceil((SPEED * DURATION + 2 * a + 4 * spacing) / spacing))
    return synthesise_track(
        ERRIB176Spectrum.low(),
        key=jr.PRNGKey(2024),
        length=n * spacing,
        spacing=spacing,
        fade_length=1.0,
        start=start,
    )


@pytest.fixture(scope="module")
def zero_track(erri_track):
    """A perfect track with the ERRI track's sample count (reuses the compiled functions)."""
    return TrackIrregularity(
        s0=erri_track.s0, ds=erri_track.ds, values=jnp.zeros_like(erri_track.values)
    )


_stacked_track_inputs = jax.jit(lambda model, t: jnp.stack(track_inputs(model, t)))


def _numpy_track_inputs(model):
    """The JAX track inputs of `model` as a numpy callable `t -> (w, w_dot, w_ddot)`."""

    def call(t):
        w = np.asarray(_stacked_track_inputs(model, t))
        return w[0], w[1], w[2]

    return call


def _pair(params, track, options=ModelOptions(), speed=SPEED):
    model = build_model(params, speed=speed, track=track, options=options)
    twin = BogieTwin(params, speed, _numpy_track_inputs(model), options=options)
    return model, twin


def _random_state(rng, *, q_scale=1e-3, qd_scale=1e-2):
    q = q_scale * rng.standard_normal(10)
    qd = qd_scale * rng.standard_normal(10)
    return np.concatenate([q, qd])


# ------------------------------------------------------------------------------ mass matrix
def test_mass_matrix_matches_twin(params, erri_track):
    """M(q, w(t)) of JAX equals the twin's to 1e-10 relative (max abs difference / max abs
    entry), is symmetric to 1e-12 and positive definite, at random states and times."""
    model, twin = _pair(params, erri_track)
    rng = np.random.default_rng(0)
    worst = 0.0
    for _ in range(6):
        q = _random_state(rng)[:10]
        t = rng.uniform(0.0, DURATION)
        m_jax = np.asarray(_mass_matrix(model, jnp.asarray(q), t))
        m_twin = twin.mass_matrix(q, t)
        scale = np.abs(m_twin).max()
        worst = max(worst, np.abs(m_jax - m_twin).max() / scale)
        for m in (m_jax, m_twin):
            assert np.abs(m - m.T).max() <= 1e-12 * scale
            assert np.linalg.eigvalsh(0.5 * (m + m.T)).min() > 0.0
    assert worst <= 1e-10, worst


def test_mass_matrix_crh380a(zero_track):
    """Same check for the second parameter set, on a perfect track, at larger angles."""
    model, twin = _pair(bogie_jax.crh380a(), zero_track)
    rng = np.random.default_rng(1)
    for _ in range(3):
        q = _random_state(rng, q_scale=2e-2)[:10]
        m_jax = np.asarray(_mass_matrix(model, jnp.asarray(q), 0.0))
        m_twin = twin.mass_matrix(q, 0.0)
        assert np.abs(m_jax - m_twin).max() <= 1e-10 * np.abs(m_twin).max()


# ---------------------------------------------------------------------- right-hand side
def _option_states(rng):
    """Random states, and for each option states where its nonlinearity is active.

    Returns {"linear" | option name: [y, ...]}.
    """
    states = {"linear": [_random_state(rng) for _ in range(3)]}
    # wheelset lateral and yaw rates up to ~0.4 m/s: u = |F_lin| / (mu N) from ~0.1 to > 3
    states["creep_saturation"] = []
    for scale in (0.02, 0.1, 0.4):
        y = _random_state(rng, q_scale=2e-3)
        y[16:20] = scale * rng.standard_normal(4)
        states["creep_saturation"].append(y)
    states["flange_contact"] = []
    for sign in (1.0, -1.0):
        y = _random_state(rng)
        y[6:8] = sign * np.array([0.0105, -0.009])  # beyond the 8 mm clearance
        states["flange_contact"].append(y)
    states["nonlinear_dampers"] = []
    for yaw_rate in (0.005, 0.03, -0.08):  # damper rates b_yd * yaw_rate: below and above
        y = _random_state(rng)
        y[15] = yaw_rate
        states["nonlinear_dampers"].append(y)
    return states


@pytest.mark.parametrize("name", list(OPTION_SETS))
def test_rhs_matches_twin(params, erri_track, name):
    """dy/dt of JAX equals the twin's on an ERRI-low track: |a_jax - a_twin| / |a_twin| <= 1e-9
    (2-norms of the acceleration half of dy/dt; the velocity half is y's own), at random
    states and times. "all" switches every option on; its states include, for each option,
    states where that option's nonlinearity is active (checked on the twin: switching just
    that option off changes dy/dt by more than 1 % for at least one of them)."""
    options = OPTION_SETS[name]
    model, twin = _pair(params, erri_track, options)
    rng = np.random.default_rng(10)
    states = _option_states(rng)
    groups = ["linear"] if name == "linear" else list(states)
    worst = 0.0
    effects = {}
    for group in groups:
        for y in states[group]:
            t = rng.uniform(0.02, DURATION)
            f_jax = np.asarray(_vector_field(t, jnp.asarray(y), model))
            f_twin = twin.rhs(t, y)
            np.testing.assert_array_equal(f_jax[:10], y[10:])
            error = np.linalg.norm(f_jax[10:] - f_twin[10:]) / np.linalg.norm(f_twin[10:])
            worst = max(worst, error)
            if group in OPTION_NAMES:
                without = BogieTwin(
                    params, SPEED, twin.track_inputs, options=_without(options, group)
                )
                effect = np.linalg.norm(f_twin - without.rhs(t, y)) / np.linalg.norm(f_twin)
                effects[group] = max(effects.get(group, 0.0), effect)
    assert worst <= 1e-9, worst
    assert all(effects[n] > 1e-2 for n in OPTION_NAMES if name != "linear"), effects


@pytest.mark.parametrize("name", list(OPTION_SETS))
def test_rhs_matches_twin_asymmetric(asymmetric_params, erri_track, name):
    """Per-element parameters: dy/dt of JAX equals the twin's for the asymmetric bogie (left
    yaw damper 0, primary 1L kz +30 %, secondary left cy 50 %), 1e-9 relative as above, at the
    states of `test_rhs_matches_twin` (every option's nonlinearity active in "all"); and the
    asymmetry matters: the symmetric twin differs by more than 1e-3 relative."""
    options = OPTION_SETS[name]
    model, twin = _pair(asymmetric_params, erri_track, options)
    symmetric = BogieTwin(
        bogie_jax.manchester_benchmark(), SPEED, twin.track_inputs, options=options
    )
    rng = np.random.default_rng(11)
    states = _option_states(rng)
    worst, effect = 0.0, 0.0
    for group in ["linear"] if name == "linear" else list(states):
        for y in states[group]:
            t = rng.uniform(0.02, DURATION)
            f_jax = np.asarray(_vector_field(t, jnp.asarray(y), model))
            f_twin = twin.rhs(t, y)
            scale = np.linalg.norm(f_twin[10:])
            worst = max(worst, np.linalg.norm(f_jax[10:] - f_twin[10:]) / scale)
            effect = max(effect, np.linalg.norm(symmetric.rhs(t, y)[10:] - f_twin[10:]) / scale)
    assert worst <= 1e-9, worst
    assert effect > 1e-3, effect


def _without(options, name):
    flags = {n: getattr(options, n) for n in OPTION_NAMES}
    flags[name] = False
    return ModelOptions(**flags)


def test_saturation_states_cover_both_regimes(params, erri_track):
    """The creep-saturation states of `test_rhs_matches_twin` reach u < 1, 1 < u < 3 and
    u > 3 (u = |F_lin| / (mu N), linear forces from the twin)."""
    _, twin = _pair(params, erri_track)
    rng = np.random.default_rng(10)
    mu = float(params.contact.friction)
    u = []
    for y in _option_states(rng)["creep_saturation"]:
        for c in twin.creep_details(rng.uniform(0.02, DURATION), y):
            u.append(np.hypot(c["f_x"], c["f_y"]) / (mu * c["normal_load"]))
    u = np.asarray(u)
    assert (u < 1.0).any() and ((u > 1.0) & (u < 3.0)).any() and (u > 3.0).any(), u


# ------------------------------------------------------------------------ static equilibrium
@pytest.mark.parametrize("param_set", ["manchester", "crh380a"])
@pytest.mark.parametrize("name", list(OPTION_SETS))
def test_static_equilibrium(zero_track, param_set, name):
    """On a perfect track y = 0 is an equilibrium: the twin's dy/dt is zero to 1e-10 (absolute,
    m/s^2 and rad/s^2), an independent check of the preloads; so is the JAX model's."""
    p = PARAMETER_SETS[param_set]()
    options = OPTION_SETS[name]
    twin = BogieTwin(p, SPEED, perfect_track_inputs, options=options)
    assert np.abs(twin.rhs(0.0, np.zeros(20))).max() <= 1e-10
    model = build_model(p, speed=SPEED, track=zero_track, options=options)
    assert np.abs(np.asarray(_vector_field(0.0, jnp.zeros(20), model))).max() <= 1e-10


# ------------------------------------------------------------------------------ trajectories
def _group_errors(y_jax, y_twin):
    """max over samples and group coordinates of |y_jax - y_twin|, divided by the max of
    |y_twin| over the same, per coordinate group (positions and velocities separately)."""
    out = {}
    for label, idx in GROUPS.items():
        for kind, offset in (("", 0), (" rate", 10)):
            cols = [i + offset for i in idx]
            diff = np.abs(y_jax[:, cols] - y_twin[:, cols]).max()
            out[label + kind] = diff / np.abs(y_twin[:, cols]).max()
    return out


def _radau(twin, y0, ts, breakpoints=()):
    """scipy Radau on the twin, restarted at `breakpoints` (where the input is not smooth)."""
    edges = np.concatenate([[ts[0]], [b for b in breakpoints if ts[0] < b < ts[-1]], [ts[-1]]])
    out, y = [], np.asarray(y0, dtype=float)
    for k, (lo, hi) in enumerate(zip(edges[:-1], edges[1:])):
        last = k == len(edges) - 2
        sel = ts[(ts >= lo) & ((ts <= hi) if last else (ts < hi))]
        sol = scipy.integrate.solve_ivp(
            twin.rhs, (lo, hi), y, method="Radau", rtol=1e-10, atol=1e-12, dense_output=True
        )
        assert sol.success, sol.message
        if sel.size:
            out.append(sol.sol(sel).T)
        y = sol.y[:, -1]
    return np.vstack(out)


@pytest.mark.slow
def test_trajectory_free_decay(params, zero_track):
    """Free decay from a 2 mm lateral offset of both wheelsets on a perfect track, 1 s at
    50 m/s: scipy Radau (rtol 1e-10, atol 1e-12) on the twin vs diffrax Dopri8 (rtol 1e-11,
    atol 1e-13) on the JAX model. Measure, per coordinate group (frame translations, frame
    rotations, wheelset laterals, wheelset yaws; positions and rates separately): max abs
    difference over all 201 samples / max abs value of the twin's; must be <= 1e-6."""
    model = build_model(params, speed=SPEED, track=zero_track)
    twin = BogieTwin(params, SPEED, perfect_track_inputs)
    y0 = np.zeros(20)
    y0[6:8] = 2e-3
    ts = np.linspace(0.0, DURATION, 201)
    y_twin = _radau(twin, y0, ts)
    y_jax = np.asarray(_diffrax_solve(model, jnp.asarray(y0), jnp.asarray(ts)))
    errors = _group_errors(y_jax, y_twin)
    assert max(errors.values()) <= 1e-6, errors
    # the decay is a real motion: the lateral mode is excited and decays
    assert np.abs(y_twin[:, 6:8]).max() >= 2e-3 and np.abs(y_twin[-1, 6:8]).max() < 2e-3


@pytest.mark.slow
def test_trajectory_erri_track(params, erri_track):
    """0.5 s at 50 m/s from rest on the ERRI-low track (1 s with Radau at this tolerance takes
    ~40 s): scipy Radau (rtol 1e-10, atol 1e-12, restarted at the spline knot crossings) on
    the twin vs diffrax Dopri8 (rtol 1e-11, atol 1e-13) on the JAX model. Measure, per
    coordinate group (positions and rates separately): max abs difference over all 201
    samples / max abs value of the twin's; must be <= 1e-6."""
    model, twin = _pair(params, erri_track)
    ts = np.linspace(0.0, ERRI_DURATION, 201)
    a = float(params.geometry.semi_wheelbase)
    knots = np.asarray(erri_track.distance())
    breakpoints = (knots + a) / SPEED  # wheelset 2 at a knot; wheelset 1 at the same times
    y_twin = _radau(twin, np.zeros(20), ts, breakpoints)
    y_jax = np.asarray(_diffrax_solve(model, jnp.zeros(20), jnp.asarray(ts)))
    errors = _group_errors(y_jax, y_twin)
    assert max(errors.values()) <= 1e-6, errors
    # the track does excite the bogie under both wheelsets
    assert np.abs(y_twin[:, 6]).max() > 1e-3 and np.abs(y_twin[:, 7]).max() > 1e-3


@pytest.mark.slow
def test_trajectory_asymmetric(asymmetric_params, zero_track):
    """Per-element parameters in motion: the asymmetric bogie (left anti-yaw damper at 0,
    primary 1L vertical spring +30 %, secondary left lateral damper at 50 %) released at q = 0
    (not its rest state: it settles, with heave, roll and pitch) with both wheelsets 2 mm
    aside, 0.5 s at 50 m/s on a perfect track (1 s takes ~70 s of CPU): scipy Radau
    (rtol 1e-10, atol 1e-12) on the twin
    vs diffrax Dopri8 (rtol 1e-11, atol 1e-13) on the JAX model; per coordinate group
    (positions and rates separately) max abs difference / max abs value of the twin's <= 1e-6."""
    model = build_model(asymmetric_params, speed=SPEED, track=zero_track)
    twin = BogieTwin(asymmetric_params, SPEED, perfect_track_inputs)
    y0 = np.zeros(20)
    y0[6:8] = 2e-3
    ts = np.linspace(0.0, ERRI_DURATION, 201)
    y_twin = _radau(twin, y0, ts)
    y_jax = np.asarray(_diffrax_solve(model, jnp.asarray(y0), jnp.asarray(ts)))
    errors = _group_errors(y_jax, y_twin)
    print("asymmetric trajectory, relative errors per group:", errors)
    assert max(errors.values()) <= 1e-6, errors
    # the asymmetry moves the frame vertically: heave, roll and pitch away from 0
    assert np.all(np.abs(y_twin[:, 2:5]).max(axis=0) > 1e-5)
