"""The compiled programs `monitor` evaluates, and the fitted coordinates they are evaluated in.

`JointProgram` holds the runs' joint objective (`bogie_jax.cost.make_joint_objective`, forward
mode, with each run's corrections where fitted) and evaluates its residuals r and their Jacobian
with respect to x = [ln p of the candidates and nuisance parameters, run corrections]
(`bogie_jax.cost.residual_jacobian`, its columns in blocks of one shape, one per core, each on
a thread of its own: `column_blocks`): one compiled program for the Fisher information, every
fit and horizon stage, the profile tests and the track record's refits, whatever records, runs
or horizon are used; and a program of the residuals alone (`residuals`: the tight solves of a
looser Jacobian, below, and the records' draws and refits' chord steps of `_track_error.py`,
on other records). Both go through the program store where the process keeps one (the command
line).

**Two models** (`MonitorOptions.jacobian`). The residuals set the estimate, and its cost
differences every profile test; the Jacobian sets the Gauss-Newton step and the covariance,
which an error of order delta in J moves by order delta. r comes from the equations of motion
solved at the settings' tolerance; J by default from the small-motion model
(`jacobian_objective`: `bogie_jax.small_motion`, the runs' equations linearised about the rest
state, 1-4 % from the full model's columns), evaluated beside r on threads of their own. With
`jacobian="full"`, J comes from the equations of motion: at `jacobian_rtol` where no step is
accepted on the residuals' cost (`with_loose_jacobian`: the first Jacobian, the horizon stages
and the track records' term), from r's own tight solve in the whole-record fit and the profile
tests (with J at rtol 1e-4 a final fit stalled with its steps rejected, 4.6 cost units above the
optimum: J's speed-factor columns differ by about 1 %, the others by 2e-4).

`FitSpace` maps the fitted coordinates v to x = B v (`_nuisance.NuisanceLayout.matrix`), keeps
the rows within the fitted horizon (`_horizon.py`), removes the sensor bias by the projection
of `bogie_jax.cost.RunChannels.centre` and weights the rows (`rows`): `evaluate(v)` is the (r, J) a
Levenberg-Marquardt fit of v needs. Both are values: a changed run set, horizon or weighting
is a new object.
"""

import dataclasses
from concurrent.futures import ThreadPoolExecutor

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..cost import RunChannels, make_joint_objective, residual_jacobian
from ..params import BogieParams
from ..runtime.cores import core_count
from ..runtime.program_store import stored_program
from ..runtime.solve_settings import SolveSettings
from ._nuisance import NuisanceLayout
from ._options import MonitorOptions


_JACOBIAN = eqx.filter_jit(residual_jacobian)
MAX_BLOCKS = 4  # each block repeats the primal solve: beyond a few, more costs more than it gains


def column_blocks(n: int) -> tuple[np.ndarray, ...]:
    """The blocks of directions (n, k) in which `JointProgram.evaluate` takes the n columns of
    one Jacobian: on a CPU one per core this process may run on (at most `MAX_BLOCKS`, one per
    column at most), else one (an accelerator carries every tangent at once). XLA runs one
    evaluation of a forward-mode solve on one core; blocks on threads of their own run on all
    of them (on two 8 s runs, 26 columns: 4.5 s in two blocks against 6.7 s in one). The last
    block is padded with zero directions, so that every block has one shape: one compiled
    program."""
    count = min(core_count(), MAX_BLOCKS, max(n, 1)) if jax.default_backend() == "cpu" else 1
    k = -(-n // count)
    eye = np.eye(n, count * k)
    return tuple(eye[:, i * k : (i + 1) * k] for i in range(count))


@eqx.filter_jit
def _residuals(objective, x):
    """r (m,) at x: the primal solves alone."""
    return jnp.ravel(objective.residuals(x, None))


def _program(name: str, fn, objective, *args):
    """A thunk running `fn(objective, *args)` (`fn` a `filter_jit` function): from the program
    store where the process keeps one (`bogie_jax.runtime.program_store`, as the command line
    does: traced and lowered now, or read, so that a later process on data of the same shapes
    traces nothing; compiled at the first call), else as it is (traced at the call). The
    store's key holds `name` and the objective's static part (the arrays are the program's
    arguments)."""
    dynamic, static = eqx.partition(objective, eqx.is_array)
    jitted = jax.jit(lambda d, *a: fn(eqx.combine(d, static), *a))
    stored = stored_program(jitted, (dynamic, *args), identity=(name, static))
    if stored is None:
        return lambda: fn(objective, *args)
    call, out_tree = stored
    leaves = jax.tree.leaves((dynamic, *args))
    return lambda: jax.tree.unflatten(out_tree, call(*leaves))


def _through_store(name: str, fn, objective, *args):
    """`fn(objective, *args)` through the program store (`_program`)."""
    return _program(name, fn, objective, *args)()


@dataclasses.dataclass(frozen=True)
class MonitorProblem:
    """`monitor`'s checked input: the runs and their track records, the nominal bogie, the
    `candidates` judged and the `nuisance` parameters fitted (names), their tolerance `bands`,
    the options and the solve settings (`throw=False`)."""

    measurements: tuple
    tracks: tuple
    params: BogieParams
    candidates: tuple[str, ...]
    nuisance: tuple[str, ...]
    bands: dict
    options: MonitorOptions
    settings: SolveSettings

    @property
    def n_runs(self) -> int:
        return len(self.measurements)

    @property
    def n_channels(self) -> int:
        return len(self.measurements[0].channels)

    def present(self) -> np.ndarray:
        """(m,) True where a sample is present, over all runs (sample-major)."""
        return np.concatenate(
            [np.isfinite(np.asarray(m.data)).reshape(-1) for m in self.measurements]
        )


@dataclasses.dataclass(frozen=True)
class JointProgram:
    """The joint objective of `problem`'s runs on track `records`, the runs `active` used; its
    Jacobian from solves at `jacobian_rtol` (`None`: the settings' own; module docstring)."""

    problem: MonitorProblem
    objective: object
    active: np.ndarray
    jacobian_rtol: float | None = None

    @classmethod
    def build(cls, problem: MonitorProblem, records=None, active=None) -> "JointProgram":
        """The program on `records` (default: the problem's tracks), all runs or `active`."""
        o = problem.options
        joint = make_joint_objective(
            problem.measurements, problem.params, problem.tracks if records is None else records,
            problem.candidates + problem.nuisance, options=o.model, settings=problem.settings,
            weights=o.weights,
        ).forward_mode()  # fmt: skip
        objective = joint.with_run_corrections() if o.run_corrections else joint
        active = np.ones(problem.n_runs, bool) if active is None else np.asarray(active, bool)
        program = cls(problem, objective, np.ones(problem.n_runs, bool)).with_active(active)
        return program.with_horizon(np.inf)

    def _runs(self, objective):
        """The `JointResidualModel` inside `objective`."""
        if self.problem.options.run_corrections:
            return objective.objective.residual_model
        return objective.residual_model

    def with_active(self, active) -> "JointProgram":
        """The program with the runs `active` (the others give zero residuals)."""
        active = np.array(active, dtype=bool)
        where = lambda o: self._runs(o).active
        objective = eqx.tree_at(where, self.objective, jnp.asarray(active))
        return dataclasses.replace(self, objective=objective, active=active)

    def with_horizon(self, horizon: float) -> "JointProgram":
        """The program whose solves stop `horizon` [s] after each run's first sample (`inf`:
        the whole runs; the same compiled program): a fit of the first seconds of every run
        (`_horizon.py`) pays for those seconds only."""
        where = lambda o: self._runs(o).stop_after
        value = jnp.asarray(float(horizon))
        objective = eqx.tree_at(where, self.objective, value, is_leaf=lambda x: x is None)
        return dataclasses.replace(self, objective=objective)

    def on_records(self, records) -> "JointProgram":
        """The same runs on other track records (the same compiled program, whole runs): the
        records swapped in where they lie on the problem's records' grids (the track-record
        error's draws), else the runs built again."""
        try:
            runs = self._runs(self.objective).with_tracks(records)
        except ValueError:  # records on another grid
            program = JointProgram.build(self.problem, records, self.active)
            return dataclasses.replace(program, jacobian_rtol=self.jacobian_rtol)
        objective = eqx.tree_at(self._runs, self.objective, runs)
        return dataclasses.replace(self, objective=objective).with_horizon(np.inf)

    def with_tracks(self, records) -> "JointProgram":
        """The same runs with `records` as the problem's track records from now on (the same
        compiled program, whole runs): what every later use of the problem's tracks sees."""
        problem = dataclasses.replace(self.problem, tracks=tuple(records))
        return dataclasses.replace(self, problem=problem).on_records(problem.tracks)

    def with_loose_jacobian(self) -> "JointProgram":
        """The program whose Jacobian comes from solves at `MonitorOptions.jacobian_rtol`
        (module docstring)."""
        return dataclasses.replace(self, jacobian_rtol=self.problem.options.jacobian_rtol)

    @property
    def slices(self) -> tuple:
        """Each run's rows of r."""
        return tuple(self.objective.residual_model.run_slices)

    def nuisance_layout(self) -> NuisanceLayout:
        p = self.problem
        return NuisanceLayout(
            len(p.candidates), len(p.nuisance), p.n_runs, bool(p.options.run_corrections),
            self.active.copy(),
        )  # fmt: skip

    def evaluate(self, x) -> tuple[np.ndarray, np.ndarray]:
        """r (m,) and dr/dx (m, n_x) at x, on the host (the first call compiles): r at the
        settings' tolerance, J at `jacobian_rtol` (module docstring), J's columns in blocks
        (`column_blocks`), each block and r on a thread of their own."""
        x = jnp.asarray(x)
        derivatives = self.jacobian_objective()
        separate = derivatives is not self.objective  # else one solve gives both
        # J's program traced first where the store traces apart from compiling: its tracing
        # and compile are the longest, and the residuals' tracing would share the interpreter
        blocks = [
            _program("residual_jacobian", _JACOBIAN, derivatives, x, None, jnp.asarray(d))
            for d in column_blocks(x.size)
        ]
        with ThreadPoolExecutor(len(blocks) + separate) as pool:
            residuals = pool.submit(self.residuals, x) if separate else None
            parts = [pool.submit(lambda block: jax.block_until_ready(block()), b) for b in blocks]
            parts = [part.result() for part in parts]
            jac = np.hstack([np.asarray(j) for _, j in parts])[:, : x.size]
            return (residuals.result() if separate else np.asarray(parts[0][0])), jac

    def residuals(self, x, objective=None) -> np.ndarray:
        """r (m,) at x, on the host, from solves at the settings' tolerance (or of
        `objective`, e.g. `derivative_objective()`: the same compiled program)."""
        objective = self.objective if objective is None else objective
        r = _through_store("residuals", _residuals, objective, jnp.asarray(x))
        return np.asarray(jax.block_until_ready(r))

    def jacobian_objective(self):
        """The objective whose forward-mode derivatives give J: the runs on the small-motion
        model where `MonitorOptions.jacobian` is `"small-motion"`, else
        `derivative_objective()` (module docstring)."""
        if self.problem.options.jacobian != "small-motion":
            return self.derivative_objective()
        joint = self._runs(self.objective)
        return eqx.tree_at(self._runs, self.objective, joint.with_small_motion())

    def derivative_objective(self):
        """The objective whose solves give derivatives: its step-size controller's tolerances
        relaxed to `jacobian_rtol` (absolute tolerance alike) where that is larger than the
        settings' own; else the objective itself."""
        rtol = self.jacobian_rtol
        where = lambda o: self._runs(o).settings.stepsize_controller
        controller = where(self.objective)
        if rtol is None or not isinstance(controller, dfx.PIDController):
            return self.objective
        factor = rtol / float(controller.rtol)
        if not factor > 1.0:
            return self.objective
        looser = dataclasses.replace(
            controller, rtol=np.asarray(rtol), atol=np.asarray(factor * float(controller.atol))
        )
        return eqx.tree_at(where, self.objective, looser)


class _LastEvaluation:
    """A memo of the last (r, J) of one `FitSpace`'s rows, keyed by v: a fit started where the
    last one ended evaluates nothing again."""

    def __init__(self):
        self.key, self.value = None, None

    def get(self, v, compute):
        key = np.asarray(v, dtype=float).tobytes()
        if self.key != key:
            self.key, self.value = key, compute(v)
        return self.value


@dataclasses.dataclass(frozen=True)
class FitSpace:
    """The fitted coordinates v = [phi (judged), ln p of nuisance parameters, scaled run
    corrections] of `program`, with `a` (n_candidates, n_coords) the judged coordinates' map
    (`_elements.Coordinate.members`), the rows `window` fitted, the sensor bias removed where
    `remove_bias`, and the row weights `rows` (module docstring)."""

    program: JointProgram
    a: np.ndarray
    window: np.ndarray
    remove_bias: bool
    rows: np.ndarray
    memo: _LastEvaluation = dataclasses.field(default_factory=_LastEvaluation, compare=False)

    @classmethod
    def of(cls, program: JointProgram, a, remove_bias: bool) -> "FitSpace":
        """Every row fitted, unit weights."""
        m = program.problem.present().size
        return cls(program, np.asarray(a, float), np.ones(m, bool), remove_bias, np.ones(m))

    def runs(self) -> RunChannels:
        """The rows' layout: runs, channels, the present samples within the window."""
        p = self.program
        mask = p.problem.present() & self.window
        return RunChannels.of(p.slices, p.problem.n_channels, mask, p.active.copy())

    @property
    def n_bias(self) -> int:
        """Bias parameters eliminated: one per active run-channel with a fitted sample."""
        return self.runs().n_bias if self.remove_bias else 0

    @property
    def n_coords(self) -> int:
        return self.a.shape[1]

    def matrix(self) -> np.ndarray:
        """B: x = B v."""
        return self.program.nuisance_layout().matrix(self.a)

    def project(self, x) -> np.ndarray:
        """x with every run-channel's mean removed (where `remove_bias`)."""
        return self.runs().centre(x) if self.remove_bias else x

    def with_window(self, window) -> "FitSpace":
        return dataclasses.replace(self, window=np.asarray(window, bool), memo=_LastEvaluation())

    def with_rows(self, rows) -> "FitSpace":
        """Other row weights (the memo kept: it holds the unweighted rows)."""
        return dataclasses.replace(self, rows=np.asarray(rows, float))

    def with_program(self, program: JointProgram) -> "FitSpace":
        return dataclasses.replace(self, program=program, memo=_LastEvaluation())

    def evaluate(self, v) -> tuple[np.ndarray, np.ndarray]:
        """Weighted r and dr/dv at v; a v whose run offsets lie out of bounds
        (`NuisanceLayout.in_bounds`) gives infinite residuals (a rejected step)."""
        r, jac, _ = self.memo.get(v, self._unweighted)
        return r * self.rows, jac * self.rows[:, None]

    def jacobian_x(self, v) -> np.ndarray:
        """dr/dx (m, n_x) at x = B v, unweighted and unprojected (the memo's where it has v)."""
        return self.memo.get(v, self._unweighted)[2]

    def _unweighted(self, v):
        """(P r, P J B, J) at v: in the window, bias projected, unweighted."""
        b = self.matrix()
        x = b @ v
        if not self.program.nuisance_layout().in_bounds(x):
            r = np.full(self.window.shape, np.inf)
            return r, np.zeros((r.size, b.shape[1])), np.zeros((r.size, b.shape[0]))
        r, jac = self.program.evaluate(x)
        with np.errstate(invalid="ignore"):  # rows beyond the horizon may be inf
            r, jac_v = np.where(self.window, r, 0.0), np.where(self.window[:, None], jac @ b, 0.0)
        return self.project(r), self.project(jac_v), jac

    def residuals_on(self, records, v) -> np.ndarray:
        """Weighted r at v with other track records, from the solves that give derivatives
        (`JointProgram.derivative_objective`: for differences; no bounds, no memo)."""
        program = self.program.on_records(records)
        r = program.residuals(self.matrix() @ v, program.derivative_objective())
        return self.project(r) * self.rows

    def fit_residuals_on(self, records, v) -> np.ndarray:
        """Weighted r at v with other track records, from solves at the settings' tolerance
        (the fit's; no bounds, no memo)."""
        r = self.program.on_records(records).residuals(self.matrix() @ v)
        return self.project(r) * self.rows

    def evaluate_on(self, records, v) -> tuple[np.ndarray, np.ndarray]:
        """Weighted r and dr/dv at v with other track records (no bounds, no memo)."""
        b = self.matrix()
        r, jac = self.program.on_records(records).evaluate(b @ v)
        return self.project(r) * self.rows, self.project(jac @ b) * self.rows[:, None]
