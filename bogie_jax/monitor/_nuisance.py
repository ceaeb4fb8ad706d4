"""What `monitor` fits but never judges: nuisance parameters.

- **Run corrections** (`run_corrections=True`): each run's position on its track record
  [m] and its speed factor (`bogie_jax.cost.CorrectedObjective`: run k is simulated from
  start_position_k + position_offset_k at speed_k * exp(log_speed_factor_k)). A record whose
  irregularity at s is the true one at s + d (`recorded_track(..., offset=d)`) is matched by
  position_offset = -d; a speed stated as (1 + e) times the true one by a factor 1 / (1 + e).
- **Nuisance parameters** (`nuisance`), fitted on log scale like the candidates. By default
  (`nuisance=None`) the contact's model-form parameters (`default_nuisance`): the cone slope
  (the equivalent conicity of a cone-on-circle contact) and the creep factor (the scale of
  Kalker's creep coefficients), the two wheel-rail quantities that are least sure in service
  (wear moves the conicity by tens of per cent; contamination and creep saturation lower the
  effective creep coefficients) and that the elements' estimates otherwise absorb: fitted
  with the linear cone model, data from worn wheels (cone slope x 0.7-1.3) moved healthy
  anti-yaw dampers by up to 33 % and primary dampers by up to 45 %, data with creep saturation
  and blow-off dampers primary and secondary dampers by 2-5 %, both at many standard errors
  (docs/monitoring.md). A profile contact table fixes the conicity, so there the creep
  factor alone; where `params` carries a wheel wear (`BogieParams.wear`: the table blended
  from the new towards a worn wheel's), its level `wear.level` as well, from the nominal
  level given (the wear's best guess, above 0 since it is fitted on log scale).
  `nuisance=()` fits none.

The compiled program differentiates r with respect to x = [theta (candidates, then nuisance
parameters), position_offset (R), log_speed_factor (R)]. The host LM fits v = [phi (the
judged coordinates), ln p of the nuisance parameters, u (offsets / OFFSET_SCALE), w (log
speed factors / SPEED_SCALE)] of the active runs, x = B v. The scales make one LM step
(largest component at most 1) move an offset by at most 0.25 m and a speed by at most 1 %,
within the range where the residuals are close to linear in them (track irregularity of
wavelengths down to a few metres); an offset beyond +-`MAX_OFFSET` is a rejected step.

Identifiability with nuisance parameters (the Schur complement of the Fisher information,
e.g. Seber & Wild, "Nonlinear Regression", 1989, sec. 2.1.3): the candidates' columns are
projected orthogonally to every nuisance column, J_eff = (I - P_N) J_c, P_N = J_N J_N^+; then
(J_eff^T J_eff)^+ is the candidates' block of (J^T J)^+, the information on them with the
nuisance unknown (`bogie_jax.cost.CorrectedObjective.profile_jacobian` does the same for the
run corrections alone). The covariance of the estimates is the judged block of the full
covariance of v (Gauss-Newton: the same matrix; the sandwich of the profiled Jacobian would
differ through its per-component prewhitening, so the full one is used).
"""

import dataclasses

import numpy as np


OFFSET_SCALE = 0.25  # [m] per unit of the fitted offset coordinate
SPEED_SCALE = 0.01  # [-] (ln speed factor) per unit of the fitted speed coordinate
MAX_OFFSET = 1.0  # [m]: a fitted |offset| above this is a rejected LM step
MODEL_FORM_NUISANCE: dict[str, tuple[str, ...]] = {  # per `BogieParams.contact_geometry`
    "cone": ("contact.cone_slope", "contact.creep_factor"),
    "s1002-uic60": ("contact.creep_factor",),  # the profile table fixes the conicity
}
DEFAULT_NUISANCE = MODEL_FORM_NUISANCE["cone"]


WEAR_NUISANCE = "wear.level"


def default_nuisance(params) -> tuple[str, ...]:
    """The model-form nuisance parameters of `params`' contact geometry (module docstring), and
    the wheel wear `wear.level` where `params` carries one (`BogieParams.wear`)."""
    names = MODEL_FORM_NUISANCE.get(params.contact_geometry, ("contact.creep_factor",))
    return names + ((WEAR_NUISANCE,) if params.wear is not None else ())


@dataclasses.dataclass(frozen=True)
class NuisanceLayout:
    """Columns of x: `n_candidates`, `n_nuisance` parameters, then (if `corrections`) the R
    offsets and R log speed factors; `active` (R,) the runs fitted."""

    n_candidates: int
    n_nuisance: int
    n_runs: int
    corrections: bool
    active: np.ndarray

    @property
    def n_x(self) -> int:
        return self.n_candidates + self.n_nuisance + (2 * self.n_runs if self.corrections else 0)

    def _correction_columns(self):
        """(x column, scale) of the fitted corrections of the active runs."""
        if not self.corrections:
            return []
        base = self.n_candidates + self.n_nuisance
        runs = np.flatnonzero(self.active)
        return [(base + k, OFFSET_SCALE, False) for k in runs] + [
            (base + self.n_runs + k, SPEED_SCALE, True) for k in runs
        ]

    def n_extra(self) -> int:
        """Fitted nuisance coordinates: parameters and corrections of active runs."""
        return self.n_nuisance + len(self._correction_columns())

    def matrix(self, a) -> np.ndarray:
        """B (n_x, n_coords + n_extra): x = B v, with `a` (n_candidates, n_coords) the map of
        the judged coordinates."""
        a = np.asarray(a, dtype=float)
        cols = self._correction_columns()
        b = np.zeros((self.n_x, a.shape[1] + self.n_nuisance + len(cols)))
        b[: self.n_candidates, : a.shape[1]] = a
        j = a.shape[1]
        for i in range(self.n_nuisance):
            b[self.n_candidates + i, j + i] = 1.0
        j += self.n_nuisance
        for i, (col, scale, _) in enumerate(cols):
            b[col, j + i] = scale
        return b

    def offsets(self, x) -> np.ndarray:
        """(R,) position offsets [m] of x (zeros without corrections)."""
        if not self.corrections:
            return np.zeros(self.n_runs)
        base = self.n_candidates + self.n_nuisance
        return np.asarray(x)[base : base + self.n_runs]

    def log_speed_factors(self, x) -> np.ndarray:
        if not self.corrections:
            return np.zeros(self.n_runs)
        base = self.n_candidates + self.n_nuisance + self.n_runs
        return np.asarray(x)[base : base + self.n_runs]

    def in_bounds(self, x) -> bool:
        return bool(np.all(np.abs(self.offsets(x)) <= MAX_OFFSET))

    def profile(self, jac) -> np.ndarray:
        """The candidates' columns of `jac` (m, n_x) with every nuisance column (parameters,
        corrections of active runs) profiled out (module docstring)."""
        jac = np.asarray(jac, dtype=float)
        j_c = jac[:, : self.n_candidates]
        extra = list(range(self.n_candidates, self.n_candidates + self.n_nuisance))
        extra += [col for col, _, _ in self._correction_columns()]
        if not extra:
            return j_c
        j_n = jac[:, extra]
        return j_c - j_n @ np.linalg.lstsq(j_n, j_c, rcond=None)[0]

    def scale(self, values, x) -> np.ndarray:
        """(n_coords + n_extra,) dp/dv of the reported quantities: the judged values, the
        nuisance parameters' values `values` is followed by, offsets [m] and speed factors."""
        cols = self._correction_columns()
        out = [np.asarray(values, dtype=float)]
        x = np.asarray(x)
        for col, scale, speed in cols:  # d offset / du = scale; d exp(w s) / dw = s exp(w s)
            out.append(np.array([scale * (np.exp(x[col]) if speed else 1.0)]))
        return np.concatenate(out)


def check_nuisance(params, nuisance, candidates) -> tuple[str, ...]:
    """Nuisance parameter names: resolved, unique, not candidates, positive (log scale);
    `None`: `default_nuisance(params)` less any candidate. **Raises:** `ValueError` naming the
    argument."""
    from ..params import get_parameter, resolve_parameter

    if nuisance is None:
        names = tuple(n for n in default_nuisance(params) if n not in candidates)
    else:
        names = tuple((nuisance,) if isinstance(nuisance, str) else nuisance)
    dups = sorted({n for n in names if names.count(n) > 1})
    if dups:
        raise ValueError(f"`nuisance` repeats {', '.join(dups)}")
    both = [n for n in names if n in candidates]
    if both:
        raise ValueError(f"`nuisance` names candidates: {', '.join(both)} (judge or fit, not both)")
    for name in names:
        resolve_parameter(params, name, " in `nuisance`")
        value = float(np.asarray(get_parameter(params, name)))
        if not value > 0:
            hint = _WEAR_HINT if name == WEAR_NUISANCE else ""
            raise ValueError(
                f"`nuisance` parameter `{name}` = {value:g} must be positive (fitted on log "
                f"scale){hint}"
            )
    return names


_WEAR_HINT = (
    "; give the wear's best guess in (0, 1] as the nominal (e.g. "
    "`manchester_benchmark(contact='s1002-uic60', wear=0.5)`), or `wear=None` for a wheel "
    "known to be new"
)
