"""`fixed_rest_state`: an objective's start state when the parameters it fits cannot move it.

An objective starts its run at rest in the static equilibrium q0(p(theta)) of the parameters it
evaluates (`bogie_jax.model.static_equilibrium`): a Newton solve inside its compiled program,
with the implicit-function-theorem derivative. Often no fitted parameter can move q0:
- a damping coefficient acts on velocities only, which are zero at rest;
- a tied vertical stiffness (`primary.kz`: all four axleboxes) scales every spring of its group
  alike, so on a symmetric bogie each still carries its design load at q = 0
  (`spring_preloads`: P_i = design load * kz_i / mean(kz)), and q0 = 0.
The solve is then wasted, and it is a fifth to a third of the program (the default
3-parameter identification, `primary.kz`, `primary.cz`, `yaw_dampers.c`, is such a case).

The test (`bogie_jax.model.rests_at_zero`): q = 0 passes the Newton solve's own convergence
test at theta = 0 and at `N_PROBES` fixed pseudo-random theta spread over several e-folds of
every parameter. The probes see any parameter that acts on the rest state over a fair part of
its range (the accelerations at q = 0 are then of order m/s^2, not 1e-10); one that acts only
in a small part of its range could escape them. A given `y0` is never replaced, and traced
parameters (under `jit`) keep the solve. Each decision is kept for the process, keyed by the
values of the parameters and the selection: the monitor builds the same objective for every
run and every track-record draw, and the probes cost a fraction of a second each time.
"""

import hashlib

import jax
import numpy as np

from ..model import N_DOF, rests_at_zero
from ..params import BogieParams, ModelOptions
from ._selection import ParameterSelection


# pseudo-random theta probed besides theta = 0, and their spread (theta ~ N(0, 2^2): factors
# e^-4 to e^4 on a log scale, most of the range of a bounded parameter)
N_PROBES = 8
PROBE_SPREAD = 2.0
_DECISIONS: dict[str, bool] = {}  # value key -> q = 0 at every probe, this process


def rest_probes(n_params: int) -> np.ndarray:
    """theta = 0 and `N_PROBES` fixed pseudo-random theta, (N_PROBES + 1, n_params)."""
    rng = np.random.default_rng(20261126)
    probes = PROBE_SPREAD * rng.standard_normal((N_PROBES, n_params))
    return np.concatenate([np.zeros((1, n_params)), probes])


def fixed_rest_state(
    params: BogieParams, selection: ParameterSelection, options: ModelOptions
) -> np.ndarray | None:
    """The start state (20,) of zeros when q = 0 is the rest state at every probed theta (see
    the module docstring), else `None` (the objective solves q0 at each theta)."""
    leaves, treedef = jax.tree.flatten((params, selection))
    if any(isinstance(x, jax.core.Tracer) for x in leaves):
        return None
    digest = hashlib.sha256(repr((treedef, options)).encode())
    for x in leaves:
        a = np.asarray(x)
        digest.update(f"{a.dtype}{a.shape}".encode() + a.tobytes())
    key = digest.hexdigest()
    if key not in _DECISIONS:
        sets = [selection.apply(params, theta) for theta in rest_probes(selection.n_params)]
        _DECISIONS[key] = rests_at_zero(sets, options=options)
    return np.zeros(2 * N_DOF) if _DECISIONS[key] else None
