"""The one compiled program `monitor` evaluates, and the fitted coordinates it is evaluated in.

`JointProgram` holds the runs' joint objective (`bogie_jax.cost.make_joint_objective`, forward
mode, with each run's corrections where fitted) and evaluates its residuals r and their Jacobian
with respect to x = [ln p of the candidates and nuisance parameters, run corrections]
(`bogie_jax.cost.residual_jacobian`): one compiled program for the Fisher information, every
fit, the profile tests and the track record's realisations, whatever records or runs are used.

`FitSpace` maps the fitted coordinates v to x = B v (`_nuisance.NuisanceLayout.matrix`), keeps
the rows within the fitted horizon (`_horizon.py`), removes the sensor bias by the projection
of `bogie_jax.cost.RunChannels.centre` and weights the rows (`rows`): `evaluate(v)` is the (r, J) a
Levenberg-Marquardt fit of v needs. Both are values: a changed run set, horizon or weighting
is a new object.
"""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..cost import RunChannels, make_joint_objective, residual_jacobian
from ..params import BogieParams
from ..runtime.solve_settings import SolveSettings
from ._nuisance import NuisanceLayout
from ._options import MonitorOptions


_JACOBIAN = eqx.filter_jit(residual_jacobian)


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
    """The joint objective of `problem`'s runs on track `records`, the runs `active` used."""

    problem: MonitorProblem
    objective: object
    active: np.ndarray

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
        return cls(problem, objective, np.ones(problem.n_runs, bool)).with_active(active)

    def with_active(self, active) -> "JointProgram":
        """The program with the runs `active` (the others give zero residuals)."""
        active = np.array(active, dtype=bool)
        if self.problem.options.run_corrections:
            where = lambda o: o.objective.residual_model.active
        else:
            where = lambda o: o.residual_model.active
        objective = eqx.tree_at(where, self.objective, jnp.asarray(active))
        return dataclasses.replace(self, objective=objective, active=active)

    def on_records(self, records) -> "JointProgram":
        """The same runs on other track records (the same compiled program)."""
        return JointProgram.build(self.problem, records, self.active)

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
        """r (m,) and dr/dx (m, n_x) at x, on the host (the first call compiles)."""
        r, jac = jax.block_until_ready(_JACOBIAN(self.objective, jnp.asarray(x)))
        return np.asarray(r), np.asarray(jac)


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
        r, jac = self.memo.get(v, self._unweighted)
        return r * self.rows, jac * self.rows[:, None]

    def _unweighted(self, v):
        b = self.matrix()
        x = b @ v
        if not self.program.nuisance_layout().in_bounds(x):
            r = np.full(self.window.shape, np.inf)
            return r, np.zeros((r.size, b.shape[1]))
        r, jac = self.program.evaluate(x)
        with np.errstate(invalid="ignore"):  # rows beyond the horizon may be inf
            r, jac = np.where(self.window, r, 0.0), np.where(self.window[:, None], jac @ b, 0.0)
        return self.project(r), self.project(jac)

    def evaluate_on(self, records, v) -> tuple[np.ndarray, np.ndarray]:
        """Weighted r and dr/dv at v with other track records (no bounds, no memo)."""
        b = self.matrix()
        r, jac = self.program.on_records(records).evaluate(b @ v)
        return self.project(r) * self.rows, self.project(jac @ b) * self.rows[:, None]
