"""Which records' biases `monitor` removes from its estimates, keeps as variance or leaves
alone (`bogie_jax/monitor/_judgement.py`, `estimate_of`), on constructed terms (no simulation)."""

import types

import numpy as np
import pytest

from bogie_jax.monitor import TrackErrorEffect, estimate_of, unsettled_bias


def test_a_bias_whose_refits_have_not_settled_is_neither_removed_nor_kept():
    """`estimate_of`: a coordinate whose bias moved by more than its own size (and than
    `SIMEX_MAX_SPREAD`) in the refits' last step keeps its fitted estimate and gets no bias
    variance (the failed anti-yaw damper of `track-white` case 17: +1.30, then -5.84 in ln p); a
    settled small bias is removed, a settled large one pointing away from nominal is kept as
    variance."""
    by_step = np.array([[1.30, 0.021, 0.40], [-5.84, 0.020, 0.45]])
    n = 3
    effect = TrackErrorEffect(
        covariance=np.diag([4.0, 1e-4, 1e-4]), bias=by_step[-1], draws=16, misfit_ss=1.0,
        bias_by_step=by_step, refit_draws=4, misfits=np.zeros((16, 5)),
        bias_variance=np.full(n, 1e-6),
    )  # fmt: skip
    assert unsettled_bias(effect).tolist() == [True, False, False]
    fit = types.SimpleNamespace(phi=np.array([-4.5, 0.1, 0.6]))
    space = types.SimpleNamespace(matrix=lambda: np.eye(n))
    estimate = estimate_of(space, fit, effect, n_log=n)
    assert estimate.phi[0] == -4.5 and not estimate.corrected[0]
    assert not estimate.bias_as_variance[0]
    assert estimate.corrected[1] and estimate.phi[1] == pytest.approx(0.1 - 0.020)
    assert estimate.bias_as_variance[2] and not estimate.corrected[2]
