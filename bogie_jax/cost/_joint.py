"""Joint objective of several runs of one bogie: shared suspension parameters, residuals of all
runs concatenated (run by run, each sample-major as in `ResidualModel`).

    r(theta) = [r_1(theta); r_2(theta); ...; r_R(theta)],   J(theta) = 1/2 |r(theta)|^2,

the sum of the single-run costs (paper eq. 12 summed over runs: independent noise per run).

Runs of one structure (same sample count and rate, channels, sensors, solver settings, track
array length) are evaluated by one `vmap` over the runs: the compiled program holds one solve
whatever the number of runs, so compile time does not grow with it. Tracks that differ only in
their number of samples are padded with zero samples and zero spline curvatures beyond their
end first: the spline is unchanged on the track, and beyond its end, where the track model is
perfect (zero), the padded track is zero too when the track ends at zero (synthesised tracks
fade to exactly zero); a track ending at a non-zero value ramps to zero over one sample spacing
instead of stepping. Runs of different structure are traced one after the other (one solve per
run in the program).
"""

import dataclasses
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from .._validation import nonempty_tuple
from ..params import BogieParams, ModelOptions
from ..runtime.solve_settings import resolve_settings
from ..simulation import SolveSettings
from ..small_motion import SmallMotionSteps
from ._make import make_objective
from ._objective import Objective, ResidualModel
from ._run_corrections import RunCorrections, check_corrections


class JointResidualModel(eqx.Module):
    """Weighted residuals of several runs with shared parameters (see module docstring).

    Build it with `joint_residual_model` or `make_joint_objective`. An `Objective` holds it in
    place of a `ResidualModel`: it has the attributes the package reads (`params`, `settings`,
    `n_residuals`, `mask`, `__call__`, `predict`, `simulate`).

    - `params`: base parameters; `settings`: the `SolveSettings` of every run's solve;
    - `active` (n_runs,): a run with `False` contributes zero residuals (and zero Jacobian
      rows): a run can be left out without changing the compiled program;
    - `run_sizes`: the number of residuals of each run (static); `vmapped`: whether the runs
      are evaluated by one `vmap` (static);
    - `corrections`: `RunCorrections` (n_runs,) applied to every run (`with_corrections`),
      mapped with the stacked run leaves; `None`: none;
    - `stop_after` [s]: every run's solve stops that long after its first sample (`simulate`;
      the later residuals are not used), traced; `None`: the whole runs;
    - `small_motion`: `None`, or every run on the small-motion model with these
      `SmallMotionSteps` (`with_small_motion`).
    """

    params: BogieParams
    settings: SolveSettings
    active: Bool[Array, " r"]
    batched: object  # ResidualModel tree: stacked run-dependent leaves (None elsewhere)
    shared: object  # ResidualModel tree (vmapped) or tuple of ResidualModels (loop)
    run_sizes: tuple[int, ...] = eqx.field(static=True)
    vmapped: bool = eqx.field(static=True)
    corrections: RunCorrections | None = None
    stop_after: Float[Array, ""] | None = None
    small_motion: SmallMotionSteps | None = eqx.field(static=True, default=None)

    @property
    def n_runs(self) -> int:
        return len(self.run_sizes)

    @property
    def n_residuals(self) -> int:
        return int(sum(self.run_sizes))

    @property
    def run_slices(self) -> tuple[slice, ...]:
        """The slice of each run's residuals in the concatenated vector."""
        ends = np.cumsum((0, *self.run_sizes))
        return tuple(slice(int(a), int(b)) for a, b in zip(ends[:-1], ends[1:]))

    def with_corrections(self, corrections: RunCorrections) -> "JointResidualModel":
        """The runs at `start_position + position_offset` [m] and `speed *
        exp(log_speed_factor)` [m/s] (`RunCorrections` of shape (n_runs,), added to any held
        already); traceable: the values are traced, one program for all of them."""
        check_corrections(corrections, self.n_runs)
        if self.corrections is not None:
            corrections = self.corrections + corrections
        return dataclasses.replace(self, corrections=corrections)

    def with_small_motion(self, substeps: int = 8) -> "JointResidualModel":
        """Every run on the small-motion model (`ResidualModel.with_small_motion`), the
        lead-in's steps those of the run with the longest lead-in."""
        steps = [m.with_small_motion(substeps).small_motion for m in self.runs()]
        lead_in_steps = max(s.lead_in_steps for s in steps)
        return dataclasses.replace(self, small_motion=SmallMotionSteps(substeps, lead_in_steps))

    def with_tracks(self, tracks) -> "JointResidualModel":
        """The runs on other track records of the same grids: `tracks`, one
        `TrackIrregularity` per run with the `s0`, `ds` and sample count of the record held
        for it (runs whose records differ in length hold the shorter ones padded to the
        longest: build the objective again for those); the same compiled program, without
        building the runs again. **Raises:** `ValueError` for another count of records or
        another grid."""
        tracks = tuple(tracks)
        if len(tracks) != self.n_runs:
            raise ValueError(f"`tracks` has {len(tracks)} records for {self.n_runs} runs")
        held = self._tracks()
        for k, (old, new) in enumerate(zip(held, tracks)):
            if not _same_grid(old, new):
                raise ValueError(
                    f"`tracks[{k}]` ({new.num_samples} samples from s0 = {float(new.s0):g} m "
                    f"at ds = {float(new.ds):g} m) is not on the grid held for run {k} "
                    f"({old.num_samples} from {float(old.s0):g} m at {float(old.ds):g} m)"
                )
        if not self.vmapped:
            shared = tuple(dataclasses.replace(m, track=t) for m, t in zip(self.shared, tracks))
            return dataclasses.replace(self, shared=shared)
        stacked = jax.tree.map(lambda *leaves: jnp.stack(leaves), *tracks)
        return dataclasses.replace(self, batched=dataclasses.replace(self.batched, track=stacked))

    def _tracks(self) -> tuple:
        """Each run's track record as held (padded to the longest where vmapped)."""
        if not self.vmapped:
            return tuple(m.track for m in self.shared)
        return tuple(jax.tree.map(lambda x: x[k], self.batched.track) for k in range(self.n_runs))

    def _run(self, model: ResidualModel, corrections) -> ResidualModel:
        """One run with this model's `settings`, `stop_after`, `small_motion` and its
        corrections (if any)."""
        model = dataclasses.replace(
            model, settings=self.settings, stop_after=self.stop_after,
            small_motion=self.small_motion,
        )  # fmt: skip
        return model if corrections is None else model.with_corrections(corrections)

    def _run_corrections(self, k: int):
        return None if self.corrections is None else jax.tree.map(lambda x: x[k], self.corrections)

    def runs(self) -> tuple[ResidualModel, ...]:
        """The single-run models (with this model's `settings` and corrections)."""
        if not self.vmapped:
            return tuple(self._run(m, self._run_corrections(k)) for k, m in enumerate(self.shared))
        return tuple(
            self._run(
                eqx.combine(jax.tree.map(lambda x: x[k], self.batched), self.shared),
                self._run_corrections(k),
            )
            for k in range(self.n_runs)
        )

    @property
    def mask(self):
        """(n_residuals,) True where a sample is present (and its run active)."""
        return jnp.concatenate(
            [jnp.where(on, m.mask, False).reshape(-1) for on, m in zip(self.active, self.runs())]
        )

    def _map(self, fn):
        """`fn(run_model)` for every run: stacked (vmapped) or a tuple (loop)."""
        if self.vmapped:

            def one(batched, corrections):
                return fn(self._run(eqx.combine(batched, self.shared), corrections))

            return jax.vmap(one)(self.batched, self.corrections)
        return tuple(fn(m) for m in self.runs())

    def __call__(self, params: BogieParams):
        """Residuals of all runs, concatenated (`n_residuals`,); zeros for inactive runs."""
        out = self._map(lambda m: m(params))
        if self.vmapped:
            return jnp.where(self.active[:, None], out, 0.0).reshape(-1)
        return jnp.concatenate([jnp.where(on, r, 0.0) for on, r in zip(self.active, out)])

    def predict(self, params: BogieParams) -> tuple:
        """Model channels of each run, a tuple of (n_times, n_channels) arrays."""
        out = self._map(lambda m: m.predict(params))
        return tuple(out[k] for k in range(self.n_runs)) if self.vmapped else out

    def simulate(self, params: BogieParams) -> tuple:
        """The simulated runs, a tuple of `Trajectory`s."""
        out = self._map(lambda m: m.simulate(params))
        if not self.vmapped:
            return out
        return tuple(jax.tree.map(lambda x: x[k], out) for k in range(self.n_runs))


def _same(a, b) -> bool:
    if a is b:
        return True
    if isinstance(a, (np.ndarray, jax.Array)) or isinstance(b, (np.ndarray, jax.Array)):
        a, b = np.asarray(a), np.asarray(b)
        return a.shape == b.shape and a.dtype == b.dtype and bool(np.array_equal(a, b))
    try:
        return bool(a == b)
    except Exception:  # noqa: BLE001 - objects without a boolean equality are not the same
        return False


def _same_grid(a, b) -> bool:
    """Whether track records `a` and `b` have one sampling grid (s0, ds, sample count)."""
    return (
        a.num_samples == b.num_samples and float(a.s0) == float(b.s0) and float(a.ds) == float(b.ds)
    )


def _same_sampling(model: ResidualModel, first: ResidualModel) -> ResidualModel:
    """`model` with `first`'s (static) `duration` and `sample_rate` where they agree to
    rounding (1e-9 relative) and the sample counts are equal: windows at other start positions
    and speeds carry other rounding in their times (e.g. 0.49999999999999994 s against 0.5 s),
    which would otherwise split runs of one structure into a loop of solves."""
    close = lambda a, b: math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)
    if (
        model.data.shape == first.data.shape
        and close(model.sample_rate, first.sample_rate)
        and close(model.duration, first.duration)
    ):
        return dataclasses.replace(model, duration=first.duration, sample_rate=first.sample_rate)
    return model


def _pad_track(model: ResidualModel, n: int) -> ResidualModel:
    track = model.track
    extra = n - track.num_samples
    if extra == 0:
        return model
    pad = lambda x: jnp.concatenate([jnp.asarray(x), jnp.zeros((extra, 3), x.dtype)])
    track = eqx.tree_at(
        lambda t: (t.values, t.curvatures), track, (pad(track.values), pad(track.curvatures))
    )
    return eqx.tree_at(lambda m: m.track, model, track)


# Fields of a run whose array leaves are always stacked, even where the runs happen to agree
# (two runs from the start of the track, no missing sample in either): the split into stacked
# and shared leaves is the program's structure, so it must not depend on these values (windows
# at other start positions, a run with missing samples would otherwise compile another program).
RUN_FIELDS = ("track", "speed", "data", "mask", "sqrt_weights", "start_position", "lead_in")


def _stack_runs(models):
    """`(batched, shared)` trees if the runs can share one vmapped program, else `None`."""
    n_track = max(m.track.num_samples for m in models)
    models = [_pad_track(m, n_track) for m in models]
    flat = [jax.tree.flatten(m) for m in models]
    treedef = flat[0][1]
    if any(t != treedef for _, t in flat):
        return None
    paths = [path for path, _ in jax.tree_util.tree_flatten_with_path(models[0])[0]]
    per_run = [getattr(path[0], "name", None) in RUN_FIELDS for path in paths]
    batched, shared = [], []
    for run_leaf, values in zip(per_run, zip(*(leaves for leaves, _ in flat))):
        stack = run_leaf and all(isinstance(v, (np.ndarray, jax.Array)) for v in values)
        if not stack and all(_same(values[0], v) for v in values[1:]):
            batched.append(None)
            shared.append(values[0])
            continue
        arrays = [np.shape(v) for v in values]
        if not all(isinstance(v, (np.ndarray, jax.Array)) for v in values) or len(set(arrays)) > 1:
            return None
        batched.append(jnp.stack([jnp.asarray(v) for v in values]))
        shared.append(None)
    return jax.tree.unflatten(treedef, batched), jax.tree.unflatten(treedef, shared)


def joint_residual_model(models, *, vmap: bool | None = None) -> JointResidualModel:
    """A `JointResidualModel` of single-run `ResidualModel`s of one bogie.

    **Arguments:**
    - `models`: one `ResidualModel` per run (e.g. `make_objective(...).residual_model`), with
      the same base `params` and `settings` (the first run's are used).
    - `vmap`: `None` (default): one vmapped evaluation if the runs share a structure (see the
      module docstring), else a loop; `True`: require the vmapped form (`ValueError` if the
      runs differ in structure); `False`: the loop.

    **Raises:** `ValueError` for no runs, runs of different base parameters, or `vmap=True`
    with runs of different structure.
    """
    models = nonempty_tuple(
        "models", models, ResidualModel, "a joint objective needs at least one run"
    )
    params, settings = models[0].params, models[0].settings
    base = jax.tree.flatten(params)
    for k, m in enumerate(models[1:], start=1):
        other = jax.tree.flatten(m.params)
        if other[1] != base[1] or not all(_same(a, b) for a, b in zip(base[0], other[0])):
            raise ValueError(
                f"`models[{k}]` has other base parameters than `models[0]`: the runs of a "
                "joint objective share one bogie"
            )
    # one settings and params object everywhere, so that these leaves are shared, not stacked
    models = tuple(dataclasses.replace(m, params=params, settings=settings) for m in models)
    models = tuple(_same_sampling(m, models[0]) for m in models)
    sizes = tuple(int(m.n_residuals) for m in models)
    active = np.ones(len(models), dtype=bool)
    stacked = None if vmap is False or len(models) == 1 else _stack_runs(models)
    if vmap and len(models) > 1 and stacked is None:
        raise ValueError(
            "`vmap=True` needs runs of one structure (sample count and rate, channels, "
            "sensors, solver settings, track arrays of one length)"
        )
    if stacked is None:
        return JointResidualModel(params, settings, active, None, models, sizes, False)
    return JointResidualModel(params, settings, active, *stacked, sizes, True)


def make_joint_objective(
    measurements,
    params: BogieParams,
    tracks,
    names,
    *,
    sensors=None,
    weights=None,
    bounds=None,
    options: ModelOptions = ModelOptions(),
    settings: SolveSettings | None = None,
    y0=None,
    vmap: bool | None = None,
    **solve_options,
) -> Objective:
    """The joint objective (module docstring) of several `measurements` of one bogie, over the
    shared parameters `names`: an `Objective` holding a `JointResidualModel`, for `fit`,
    `residual_jacobian`, `covariance_from_jacobian` and `fisher_information` as one run's.

    **Arguments:** `measurements` and `tracks`: one track (`TrackIrregularity`) per
    measurement, in the same order. Other arguments as `make_objective`, the same for every
    run (`sensors`, `weights`, one `settings`); `vmap` as `joint_residual_model`.

    **Raises:** `ValueError` for no measurements, a different number of tracks, and
    everything `make_objective` raises for a run (the message names the run).
    """
    measurements, tracks = tuple(measurements), tuple(tracks)
    if not measurements:
        raise ValueError("`measurements` is empty: give at least one measurement run")
    if len(tracks) != len(measurements):
        raise ValueError(
            f"`tracks` has {len(tracks)} entries for {len(measurements)} measurements: give "
            "one track per run"
        )
    settings = resolve_settings(settings, SolveSettings.for_objective(), **solve_options)
    objectives = []
    for k, (m, track) in enumerate(zip(measurements, tracks)):
        try:
            objectives.append(
                make_objective(
                    m,
                    params,
                    track,
                    names,
                    sensors=sensors,
                    weights=weights,
                    bounds=bounds,
                    options=options,
                    settings=settings,
                    y0=y0,
                )  # fmt: skip
            )
        except ValueError as e:
            raise type(e)(f"run {k}: {e}") from None
    model = joint_residual_model([o.residual_model for o in objectives], vmap=vmap)
    return Objective(objectives[0].selection, model)
