"""Standard errors scaled for the misfit in the rows that inform each estimate
(`bogie_jax.monitor._misfit_scale`): the per-estimate ratio against a Monte Carlo oracle on a
linear problem whose noise is larger in one channel group, and the scaled verdict. Nothing is
compiled."""

import types

import numpy as np
import pytest

from bogie_jax.cost import RunChannels
from bogie_jax.monitor import (
    GoodnessOfFit,
    Misfit,
    ToleranceBand,
    decision_z,
    judge,
    misfit_scales,
    scaled_for_misfit as scaled,
)


N, CHANNELS = 300, ("a_y", "b_y", "c_z")


def _space():
    """A stand-in of `FitSpace` with what `misfit_scales` reads: one run of N samples of the
    three channels."""
    runs = RunChannels.of((slice(0, N * len(CHANNELS)),), len(CHANNELS))
    measurement = types.SimpleNamespace(channels=CHANNELS)
    problem = types.SimpleNamespace(measurements=(measurement,))
    return types.SimpleNamespace(program=types.SimpleNamespace(problem=problem), runs=lambda: runs)


def test_scale_matches_the_variance_of_estimates_under_group_noise():
    """Noise 9 times the variance in channel c_z (a misfit ratio of 9 there, 1 elsewhere): the
    estimates' Monte Carlo variance ratio (20000 trials) matches rho_j within 5 %, for a
    coordinate informed mostly by c_z and one mostly by the others."""
    rng = np.random.default_rng(0)
    jac = rng.normal(size=(N * 3, 2))
    jac[2::3, 0] *= 4.0  # coordinate 0 lives in c_z
    jac[2::3, 1] *= 0.2  # coordinate 1 in a_y and b_y
    tests = (
        Misfit(0, "lateral", ("a_y", "b_y"), 2.0, 2.0, 0.0, 1.0, 0.5),
        Misfit(0, "vertical", ("c_z",), 9.0, 1.0, 0.0, 9.0, 1e-9, rejected=True),
    )
    fit = types.SimpleNamespace(jac=jac)
    rho = misfit_scales(_space(), fit, GoodnessOfFit(tests, 0.05), 2)
    sd = np.tile([1.0, 1.0, 3.0], N)
    pinv = np.linalg.pinv(jac)
    e = rng.normal(size=(len(jac), 20000))
    white, coloured = np.var(pinv @ e, axis=1), np.var(pinv @ (sd[:, None] * e), axis=1)
    np.testing.assert_allclose(rho, coloured / white, rtol=0.05)
    assert rho[0] > 5 and rho[1] < 2, rho


def test_scaled_verdict_widens_its_error_and_interval():
    """The standard error becomes max(se, sqrt(rho) se_0) (se_0 without the discrepancy term),
    the interval widens by the same factor about the estimate, and a watch flag goes where the
    wider interval reaches the band."""
    band = ToleranceBand.relative(400e3, 0.2, unit="N s/m")
    v = judge("d", 313e3, 3e3, band, z=decision_z(0.05, 13))  # 307-319 kN s/m: on watch
    v.evidence.update(std_error_residuals=1.8e3, std_error_track_record=2.4e3)  # se_0 = 3e3
    assert v.verdict == "healthy" and v.watch == "below"
    wide = scaled(v, 4.0)
    assert wide.std_error == pytest.approx(6e3)
    assert wide.ci95[0] == pytest.approx(313e3 - 2 * (313e3 - v.ci95[0]))
    assert wide.evidence["misfit_scale"] == 4.0
    assert wide.evidence["std_error_before_misfit_scale"] == 3e3
    assert wide.watch is None  # 313 +- 11.8 kN s/m reaches the band's 320
    assert scaled(v, 0.5).std_error == pytest.approx(3e3)  # never narrower
