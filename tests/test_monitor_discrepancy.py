"""The model discrepancy's covariance (`bogie_jax.monitor._discrepancy`) against Monte Carlo
oracles on a linear least-squares problem: its residuals hold white noise and, in some trials, a
smooth stationary discrepancy correlated across channels. Nothing is compiled."""

import numpy as np
import pytest
import scipy.signal

from bogie_jax.cost import RunChannels
from bogie_jax.monitor import model_discrepancy


RATE, N, C, P = 100.0, 400, 3, 4  # [Hz], samples per run, channels, parameters
TRIALS = 400


def _design(rng):
    """(2 runs x N samples x C channels, P) Jacobian: smooth responses (sums of sinusoids in
    0.5-10 Hz), sample-major per run, with each run-channel's mean removed (the bias)."""
    t = np.arange(N) / RATE
    cols = []
    for _ in range(P):
        f = rng.uniform(0.5, 10.0, (2, C, 3))
        phase = rng.uniform(0, 2 * np.pi, (2, C, 3))
        x = np.sin(2 * np.pi * f[..., None] * t + phase[..., None]).sum(axis=2)  # (2, C, N)
        x -= x.mean(axis=-1, keepdims=True)
        cols.append(np.transpose(x, (0, 2, 1)).reshape(-1))
    return np.stack(cols, axis=1)


def _smooth_process(rng, size):
    """(2, N, C) a stationary AR(2) process with a resonance near 3 Hz, shared by the channels
    with gains (1, 0.7, -0.4) plus an independent AR(1) part: coherent across channels."""
    a1, a2 = 2 * 0.97 * np.cos(2 * np.pi * 3.0 / RATE), -(0.97**2)
    x = scipy.signal.lfilter([1.0], [1.0, -a1, -a2], rng.normal(size=(2, N + 200)), axis=1)
    own = scipy.signal.lfilter([1.0], [1.0, -0.9], rng.normal(size=(2, N + 200, C)), axis=1)
    d = x[:, 200:, None] * np.array([1.0, 0.7, -0.4]) + 0.5 * own[:, 200:]
    return size * d / d.std()


@pytest.fixture(scope="module")
def problem():
    rng = np.random.default_rng(7)
    jac = _design(rng)
    runs = RunChannels.of((slice(0, N * C), slice(N * C, 2 * N * C)), C)
    return jac, runs


def _trials(jac, runs, discrepancy: float, seed: int):
    """(estimates' errors from the discrepancy alone (TRIALS, P), mean estimated covariance)."""
    rng = np.random.default_rng(seed)
    h_inv_jt = np.linalg.pinv(jac)
    projector = np.eye(jac.shape[0]) - jac @ h_inv_jt
    errors, estimated = [], []
    for _ in range(TRIALS):
        d = _smooth_process(rng, discrepancy).reshape(-1) if discrepancy else np.zeros(len(jac))
        e = rng.normal(size=len(jac))
        r = projector @ (d + e)
        errors.append(h_inv_jt @ d)
        estimated.append(model_discrepancy(r, jac, runs, (RATE, RATE)).covariance)
    return np.array(errors), np.mean(estimated, axis=0)


def test_discrepancy_covariance_matches_the_monte_carlo_spread(problem):
    """A smooth discrepancy 3 times the noise's RMS: the estimated variances agree with the
    Monte Carlo variances of the estimates' errors it causes (400 trials) within 25 %."""
    jac, runs = problem
    errors, estimated = _trials(jac, runs, 3.0, seed=1)
    mc = np.var(errors, axis=0)
    np.testing.assert_allclose(np.diag(estimated), mc, rtol=0.25)


def test_discrepancy_is_small_on_white_noise(problem):
    """White noise alone (400 trials): the term's mean variance stays under a tenth of the
    Gauss-Newton variance (its positive part's bias at the end, no systematic excess)."""
    jac, runs = problem
    _, estimated = _trials(jac, runs, 0.0, seed=2)
    gn = np.diag(np.linalg.pinv(jac.T @ jac))
    assert np.all(np.diag(estimated) < 0.1 * gn), np.diag(estimated) / gn


def test_track_draws_are_not_counted_twice(problem):
    """Residuals that are exactly one of the track records' error draws' shapes: with the draws
    given, their mean cross-spectrum is subtracted and the term shrinks to a small fraction of
    what it is without them."""
    jac, runs = problem
    rng = np.random.default_rng(3)
    projector = np.eye(len(jac)) - jac @ np.linalg.pinv(jac)
    draws = np.stack([projector @ _smooth_process(rng, 3.0).reshape(-1) for _ in range(32)])
    r = projector @ (_smooth_process(rng, 3.0).reshape(-1) + rng.normal(size=len(jac)))
    without = np.trace(model_discrepancy(r, jac, runs, (RATE, RATE)).covariance)
    with_draws = np.trace(model_discrepancy(r, jac, runs, (RATE, RATE), misfits=draws).covariance)
    assert with_draws < 0.3 * without, (with_draws, without)
