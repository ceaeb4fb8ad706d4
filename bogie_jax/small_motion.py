"""`simulate_small_motion`: the small-motion model's response to a track, exactly discretised.

The small-motion model (`bogie_jax.model.small_motion_system`) is linear and time-invariant at
constant speed: d(dy)/dt = a dy + b u(t). Between two time points h apart where the input is
taken linear in time (a first-order hold), its solution is exact (e.g. Franklin, Powell &
Workman, *Digital Control of Dynamic Systems*, 3rd ed. 1998, sec. 6.3.2):

    dy_{j+1} = Phi dy_j + G0 u_j + G1 (u_{j+1} - u_j),

    expm(h [[a, b, 0], [0, 0, I / h], [0, 0, 0]]) = [[Phi, G0, G1], [0, I, I], [0, 0, I]],

the matrix exponential by scaling and squaring of a Taylor polynomial (Moler & Van Loan,
"Nineteen dubious ways to compute the exponential of a matrix, twenty-five years later", SIAM
Review 45 (2003) 3-49, method 3). The track's inputs are a cubic spline in distance, so the hold
errs by O(h^2) in them: `substeps` steps of h per output sample. The response is one linear
recurrence with no adaptive steps (a `lax.scan` over the samples, the substeps summed in one
product), so it costs far less than the diffrax solve of the full equations of motion
(`bogie_jax.simulate`), whose second-order terms it leaves out.
"""

import dataclasses
import math

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp

from ._precision import warn_if_float32
from ._validation import check_positive_int
from .model import N_DOF, build_model, inputs_vector, small_motion_system, track_inputs
from .params import BogieParams, ModelOptions
from .simulation import Trajectory, check_simulation_inputs, check_window, sample_times
from .track import TrackIrregularity


TAYLOR_DEGREE = 12
"""Degree of the Taylor polynomial of `expm` at a scaled norm <= 1/2 (truncation < 1e-13)."""
MAX_SQUARINGS = 40
"""Most squarings of `expm`: norms up to 2^39 (a step's a h far beyond any bogie's)."""


@dataclasses.dataclass(frozen=True)
class SmallMotionSteps:
    """The hold discretisation of `small_motion_response` (static: part of the program):
    `substeps` hold steps per output sample (>= 1) and `lead_in_steps` over the lead-in (>= 0;
    0: the motion starts at rest at the first sample)."""

    substeps: int = 8
    lead_in_steps: int = 0

    def __post_init__(self):
        check_positive_int("substeps", self.substeps, 1000)
        check_positive_int("lead_in_steps", self.lead_in_steps, 10**7, lo=0)


def expm(m):
    """exp(m) of a square matrix by scaling and squaring (module docstring): m / 2^s with its
    1-norm at most 1/2, a Taylor polynomial of degree `TAYLOR_DEGREE`, then s squarings (s
    traced, at most `MAX_SQUARINGS`: one program for every norm). Differentiable in forward and
    reverse mode (s is piecewise constant in m)."""
    norm = jnp.max(jnp.sum(jnp.abs(m), axis=0))
    s = jnp.clip(jnp.ceil(jnp.log2(jnp.maximum(norm, 1e-300) / 0.5)), 0.0, MAX_SQUARINGS)
    x = m * 2.0**-s
    eye = jnp.eye(m.shape[0], dtype=m.dtype)
    e = eye
    for k in range(TAYLOR_DEGREE, 0, -1):  # Horner: I + x/1 (I + x/2 (I + ...))
        e = eye + x @ e / k
    square = lambda i, e: jnp.where(i < s, e @ e, e)
    return jax.lax.fori_loop(0, MAX_SQUARINGS, square, e)


def hold_matrices(a, b, h):
    """(Phi, G0, G1) of the first-order-hold step of length `h` [s] (module docstring)."""
    n, m = b.shape
    big = jnp.zeros((n + 2 * m, n + 2 * m), dtype=a.dtype)
    big = big.at[:n, :n].set(a * h).at[:n, n : n + m].set(b * h)
    big = big.at[n : n + m, n + m :].set(jnp.eye(m, dtype=a.dtype))
    e = expm(big)
    return e[:n, :n], e[:n, n : n + m], e[:n, n + m :]


def _march(dy0, a, b, h, u, per_block: int):
    """The states after each block of `per_block` steps of length `h` from dy0 (20,), the
    inputs `u` (n_blocks * per_block + 1, 18) at the step ends: (n_blocks, 20)."""
    phi, g0, g1 = hold_matrices(a, b, h)
    forcing = u[:-1] @ (g0 - g1).T + u[1:] @ g1.T  # (steps, 20)
    blocks = forcing.reshape(-1, per_block, forcing.shape[-1])
    powers = [jnp.eye(phi.shape[0], dtype=phi.dtype)]
    for _ in range(per_block - 1):
        powers.append(phi @ powers[-1])
    powers = jnp.stack(powers[::-1])  # Phi^(per_block - 1 - j) for step j of a block
    per_block_forcing = jnp.einsum("jab,kjb->ka", powers, blocks)
    phi_block = phi @ powers[0]

    def step(dy, c):
        nxt = phi_block @ dy + c
        return nxt, nxt

    return jax.lax.scan(step, dy0, per_block_forcing)[1]


def simulate_small_motion(
    params: BogieParams,
    track: TrackIrregularity,
    *,
    speed,
    duration: float,
    sample_rate: float = 200.0,
    start_position=0.0,
    lead_in=0.0,
    lead_in_steps: int | None = None,
    options: ModelOptions = ModelOptions(),
    substeps: int = 8,
    y0=None,
) -> Trajectory:
    """The small-motion model's response to `track` at constant `speed` (module docstring), from
    rest `lead_in` [m] before the first sample, as a `Trajectory` (q, q_dot, q_ddot at the
    samples; `num_steps` the hold steps). Arguments as `bogie_jax.simulate`, and:

    - `substeps`: hold steps per output sample (static, >= 1; default 8: at 100 Hz, 60 m/s a
      step of 7.5 cm, 40 per 3 m wavelength);
    - `lead_in_steps`: hold steps over the lead-in (static); default: the lead-in's time at
      the window's step length, rounded up, which needs `lead_in` and `speed` concrete;
    - `y0`: the state (20,) [m, rad, m/s, rad/s] at the start of the lead-in; default `None`:
      at rest in the static equilibrium.

    **Raises:** `ValueError` naming the argument, its value and the valid range (as
    `bogie_jax.simulate`), before anything is compiled.
    """
    check_simulation_inputs(speed, duration, sample_rate)
    check_window(start_position, lead_in, speed=speed, duration=duration, track=track)
    check_positive_int("substeps", substeps, 1000)
    if lead_in_steps is None:
        try:
            lead_time = float(lead_in) / float(speed)
        except (TypeError, jax.errors.ConcretizationTypeError):
            raise ValueError(
                "`lead_in_steps` must be given where `lead_in` or `speed` is traced; valid: an "
                "int >= 0"
            ) from None
        lead_in_steps = math.ceil(lead_time * sample_rate * substeps - 1e-9)
    check_positive_int("lead_in_steps", lead_in_steps, 10**7, lo=0)
    if lead_in_steps == 0 and isinstance(lead_in, (int, float)) and lead_in > 0:
        raise ValueError(f"`lead_in_steps` = 0 with `lead_in` = {lead_in:g} m; valid: >= 1")
    if y0 is not None and jnp.shape(y0) != (2 * N_DOF,):
        raise ValueError(f"`y0` has shape {jnp.shape(y0)}; valid: ({2 * N_DOF},)")
    warn_if_float32()
    as_array = lambda x: jnp.asarray(x, dtype=float)
    return small_motion_response(
        params, track, as_array(speed), as_array(start_position), as_array(lead_in),
        duration=duration, sample_rate=sample_rate, options=options,
        steps=SmallMotionSteps(substeps, lead_in_steps), y0=None if y0 is None else as_array(y0),
    )  # fmt: skip


@eqx.filter_jit
def small_motion_response(
    params, track, speed, start_position, lead_in, *, duration, sample_rate, options, steps, y0=None
) -> Trajectory:
    """`simulate_small_motion` without its checks, as one compiled program (traceable: the
    residuals of `bogie_jax.cost` call it inside theirs); `steps` a `SmallMotionSteps`; `y0`
    (20,) the state at the start of the lead-in (`None`: at rest in the static equilibrium).
    The rest state is taken at q = 0 where its Newton solve fails
    (`bogie_jax.model.small_motion_system`)."""
    substeps, lead_in_steps = steps.substeps, steps.lead_in_steps
    system = small_motion_system(params, speed, options)
    model = build_model(params, speed=speed, track=track, options=options)
    inputs = jax.vmap(lambda t: inputs_vector(*track_inputs(model, t)))
    first = start_position / speed
    window = sample_times(duration, sample_rate)
    h = 1.0 / (sample_rate * substeps)
    dy = jnp.zeros_like(system.rest) if y0 is None else jnp.asarray(y0) - system.rest
    if lead_in_steps > 0:
        lead = lead_in / speed
        t_lead = first - lead + lead * jnp.arange(lead_in_steps + 1) / lead_in_steps
        dy = _march(dy, system.a, system.b, lead / lead_in_steps, inputs(t_lead), 1)[-1]
    t_fine = first + jnp.arange((len(window) - 1) * substeps + 1) * h
    u_fine = inputs(t_fine)
    later = _march(dy, system.a, system.b, h, u_fine, substeps)
    states = jnp.concatenate([dy[None], later])
    u_samples = u_fine[::substeps]
    qdd = states @ system.a[N_DOF:].T + u_samples @ system.b[N_DOF:].T
    y = states + system.rest
    steps = jnp.asarray(lead_in_steps + (len(window) - 1) * substeps)
    return Trajectory(
        ts=first + window, q=y[:, :N_DOF], qd=y[:, N_DOF:], qdd=qdd, speed=speed,
        result=dfx.RESULTS.successful, num_steps=steps, num_accepted_steps=steps,
        num_rejected_steps=jnp.asarray(0),
    )  # fmt: skip
