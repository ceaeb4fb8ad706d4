"""`SolveSettings`: the diffrax options shared by `simulate`, the objective and synthetic data.

One module holds the solver, the step-size controller, the adjoint, `max_steps`, `dt0` and
`throw`, so that `simulate`, `bogie_jax.cost.make_objective` and
`bogie_jax.measure.synthetic_measurement` take one `settings=` argument instead of repeating six
keywords. Only what changes the compiled program is static (`max_steps`, `dt0`, `throw`); the
controller's `rtol`/`atol` are stored as 0-d arrays (traced), so settings differing only in
tolerance share one compilation.
"""

import diffrax as dfx
import equinox as eqx
import jax
import numpy as np

from .._validation import check_positive_int


_Controller = dfx.AbstractStepSizeController
SOLVE_OPTIONS = ("solver", "stepsize_controller", "adjoint", "max_steps", "dt0", "throw")


def traced_tolerances(controller):
    """A `PIDController` with its `rtol`/`atol` as 0-d arrays: traced rather than compile-time
    constants, so solves differing only in tolerance share one compilation. Other controllers
    are returned as they are."""
    if isinstance(controller, dfx.PIDController):
        # a JAX array (or tracer: settings rebuilt under jit) is already traced
        as_leaf = lambda x: x if isinstance(x, jax.Array) else np.asarray(x, dtype=float)
        tols = (as_leaf(controller.rtol), as_leaf(controller.atol))
        return eqx.tree_at(lambda c: (c.rtol, c.atol), controller, tols)
    return controller


def default_controller(rtol: float = 1e-6, atol: float = 1e-9) -> dfx.PIDController:
    """Default step-size controller: PID at rtol 1e-6, atol 1e-9 (states are mm and mrad)."""
    return dfx.PIDController(rtol=rtol, atol=atol)


def full_checkpoints(max_steps: int, controller=None) -> dfx.RecursiveCheckpointAdjoint:
    """`RecursiveCheckpointAdjoint` with one checkpoint per step (`checkpoints = max_steps`).

    With fewer checkpoints the backward pass recomputes runs of steps, and in diffrax 0.7.2 that
    gives wrong gradients for time-dependent vector fields with `ConstantStepSize` (31 % off on a
    forced oscillator; `tests/test_gradients.py` keeps the reproducer). One checkpoint per step
    avoids the recomputation and costs a few hundred bytes per step of memory, only when
    differentiated in reverse mode (a plain solve stores nothing).
    """
    del controller
    return dfx.RecursiveCheckpointAdjoint(checkpoints=max_steps)


class SolveSettings(eqx.Module):
    """How a run is integrated (passed to `diffrax.diffeqsolve`).

    - `solver`: a diffrax solver (default `Tsit5()`).
    - `stepsize_controller`: default PID at rtol 1e-6, atol 1e-9 (tolerances traced).
    - `adjoint`: how the solve is differentiated. `None` (default): reverse mode with one
      checkpoint per step (`full_checkpoints(max_steps)`), what `jax.grad` needs. Forward-mode
      code (residual Jacobians, `bogie_jax.cost.residual_jacobian`) switches to
      `diffrax.ForwardMode()` itself (`forward_mode()`).
    - `max_steps`: step limit per solve, an integer in [1, 1e9] (static).
    - `dt0` [s]: first step (static); `None` lets the controller choose.
    - `throw`: raise on a failed solve (static); `False` reports it in the result instead, as
      objectives and batches need (a raise under `vmap` stops every member).
    """

    solver: dfx.AbstractSolver
    stepsize_controller: dfx.AbstractStepSizeController
    adjoint: dfx.AbstractAdjoint
    max_steps: int = eqx.field(static=True)
    dt0: float | None = eqx.field(static=True)
    throw: bool = eqx.field(static=True)

    def __init__(
        self,
        solver: dfx.AbstractSolver = dfx.Tsit5(),
        stepsize_controller: dfx.AbstractStepSizeController | None = None,
        adjoint: dfx.AbstractAdjoint | None = None,
        max_steps: int = 100_000,
        dt0: float | None = 1e-3,
        throw: bool = True,
    ):
        check_positive_int("max_steps", max_steps)
        if dt0 is not None and not (np.isfinite(dt0) and dt0 > 0):
            raise ValueError(f"`dt0` = {dt0!r} s must be finite and > 0, or None")
        for name, value, kind in (
            ("solver", solver, dfx.AbstractSolver),
            ("stepsize_controller", stepsize_controller, (_Controller, type(None))),
            ("adjoint", adjoint, (dfx.AbstractAdjoint, type(None))),
        ):
            if not isinstance(value, kind):
                raise TypeError(f"`{name}` must be a diffrax {name}, got {value!r}")
        self.solver = solver
        controller = default_controller() if stepsize_controller is None else stepsize_controller
        self.stepsize_controller = traced_tolerances(controller)
        self.adjoint = full_checkpoints(max_steps) if adjoint is None else adjoint
        self.max_steps = int(max_steps)
        self.dt0 = None if dt0 is None else float(dt0)
        self.throw = bool(throw)

    @classmethod
    def for_objective(cls, **options) -> "SolveSettings":
        """The defaults of an objective: `max_steps=16_384`, `throw=False` (a failed solve gives
        infinite residuals), others as `SolveSettings()`; `options` override them."""
        return cls(**{"max_steps": 16_384, "throw": False, **options})

    def replace(self, **options) -> "SolveSettings":
        """A copy with some of `SOLVE_OPTIONS` changed. A reverse-mode adjoint with one
        checkpoint per old step follows a new `max_steps` unless `adjoint` is given.

        **Raises:** `ValueError` naming an unknown option."""
        check_options(options)
        current = {name: getattr(self, name) for name in SOLVE_OPTIONS}
        if "max_steps" in options and "adjoint" not in options:
            if current["adjoint"] == full_checkpoints(self.max_steps):
                current["adjoint"] = None
        return SolveSettings(**{**current, **options})

    def forward_mode(self) -> "SolveSettings":
        """These settings differentiated in forward mode (`diffrax.ForwardMode`), unless the
        adjoint already supports it (`ForwardMode`, `DirectAdjoint`)."""
        if isinstance(self.adjoint, (dfx.ForwardMode, dfx.DirectAdjoint)):
            return self
        return eqx.tree_at(lambda s: s.adjoint, self, dfx.ForwardMode())


def check_options(options) -> None:
    """Raise `ValueError` for keywords that are not `SOLVE_OPTIONS`."""
    unknown = sorted(set(options) - set(SOLVE_OPTIONS))
    if unknown:
        raise ValueError(
            f"unknown solve options {unknown} (cannot replace them); valid: {list(SOLVE_OPTIONS)}"
        )


def resolve_settings(settings: SolveSettings | None, default: SolveSettings, **options):
    """`settings` (or `default`) with the loose keyword `options` applied: the backward-compatible
    form `simulate(..., max_steps=...)` of `simulate(..., settings=SolveSettings(...))`."""
    if settings is not None and not isinstance(settings, SolveSettings):
        raise TypeError(f"`settings` must be a SolveSettings, got {type(settings).__name__}")
    settings = default if settings is None else settings
    return settings.replace(**options) if options else settings
