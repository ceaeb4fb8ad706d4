"""Model discrepancy: the part of the residuals that neither the sensors' noise nor the track
records' error explains, carried into the covariance of the estimates.

The residual of run k is modelled as r = e + t + d: white sensor noise e (per channel, the level
of the noise band, as `_goodness.py` estimates it), the records' error's effect t (its draws,
`TrackErrorEffect.misfits`) and a model discrepancy d, a zero-mean stationary Gaussian process
independent of both, with cross-spectral matrix S_d(f) over the run's channels (a discrepancy
function in the sense of Kennedy & O'Hagan, "Bayesian calibration of computer models", J. R.
Statist. Soc. B 63 (2001) 425-464). The least-squares estimates then carry

    C_d = H^+ (sum_k J_k^T Sigma_k J_k) H^+,   H = J^T J,

J the fit's Jacobian in its weighted, bias-projected rows and Sigma_k the covariance of d over
run k's samples (the sandwich form, Huber 1967). For a stationary d, J^T Sigma J is the sum over
the discrete Fourier transform's bins of Re(J^(f)^H S_d(f) J^(f)) / n (the Whittle approximation
of a Toeplitz covariance; Brillinger, "Time Series: Data Analysis and Theory", 1981, ch. 7).
S_d is estimated at every bin between 0 and `HIGH_BAND_START` as the residuals'
cross-periodogram less the draws' mean cross-periodogram and the noise level s^2 I, averaged
over `DANIELL_BINS` neighbouring bins (Daniell's window). The bins' sum is taken as it is
(where the model explains the data its expectation is zero, so the term is unbiased there) and
C_d is projected onto the positive semidefinite matrices at the end.

The term is added to the Gauss-Newton covariance only (`GaussNewtonCovariance`, the rule with a
track record's error); the sandwich rule already estimates the long-run variance of the whole
residual, discrepancy included. Its degrees of freedom are the number of bins summed.
"""

import dataclasses

import numpy as np

from ..cost import RunChannels
from ._goodness import HIGH_BAND_START, _run_blocks


DANIELL_BINS = 5  # bins averaged in a cross-spectral estimate


@dataclasses.dataclass(frozen=True)
class Discrepancy:
    """The model discrepancy's covariance `covariance` (n, n) in the fit's coordinates and the
    degrees of freedom `dof` of its estimate (the bins summed)."""

    covariance: np.ndarray
    dof: float


def _cross_periodogram(x, n: int) -> np.ndarray:
    """(..., F, c, c) X(f) X(f)^H / n of the DFT `x` (..., F, c)."""
    return np.einsum("...fa,...fb->...fab", x, x.conj()) / n


def _daniell(s: np.ndarray, width: int) -> np.ndarray:
    """`s` (F, ...) averaged over `width` neighbouring bins (fewer at the ends)."""
    kernel = np.ones(width)
    flat = s.reshape(s.shape[0], -1)
    total = np.apply_along_axis(lambda x: np.convolve(x, kernel, mode="same"), 0, flat)
    count = np.convolve(np.ones(s.shape[0]), kernel, mode="same")[:, None]
    return (total / count).reshape(s.shape)


def _run_meat(r, jac, draws, rate: float) -> tuple[np.ndarray, int]:
    """(sum over bins of Re(J^H S_d J) / n, bins summed) of one run: `r` (n, c), `jac` (n, c,
    p), `draws` (D, n, c) or `None` (module docstring)."""
    n = r.shape[0]
    f = np.fft.rfftfreq(n, 1.0 / rate)
    spectrum = _cross_periodogram(np.fft.rfft(r, axis=0), n)
    if draws is not None:
        spectrum = spectrum - _cross_periodogram(np.fft.rfft(draws, axis=1), n).mean(axis=0)
    high = (f >= HIGH_BAND_START) & (f < rate / 2)
    low = (f > 0) & (f < min(HIGH_BAND_START, rate / 2))
    if not high.any() or not low.any():
        return np.zeros((jac.shape[-1],) * 2), 0
    noise = np.real(np.einsum("faa->fa", spectrum[high])).mean(axis=0)
    excess = _daniell(spectrum - np.diag(np.maximum(noise, 0.0)), DANIELL_BINS)[low]
    jf = np.fft.rfft(jac, axis=0)[low]
    meat = 2.0 * np.real(np.einsum("fap,fab,fbq->pq", jf.conj(), excess, jf)) / n
    return meat, int(low.sum())


def model_discrepancy(r, jac, runs: RunChannels, rates, misfits=None) -> Discrepancy:
    """The `Discrepancy` of a fit (module docstring): residuals `r` (m,) and Jacobian `jac`
    (m, p) in the fit's weighted, bias-projected rows, `runs` their layout (missing samples and
    those outside the fit's window are zero), `rates` [Hz] each run's sample rate, `misfits`
    (D, m) the track records' error draws or `None`."""
    mask = np.asarray(runs.mask, dtype=float)
    r, jac = np.asarray(r, dtype=float) * mask, np.asarray(jac, dtype=float).T * mask  # (p, m)
    misfits = None if misfits is None or not len(misfits) else np.asarray(misfits) * mask
    meat, bins = np.zeros((jac.shape[0],) * 2), 0
    for k in np.flatnonzero(runs.active):
        draws = None if misfits is None else _run_blocks(runs, k, misfits)
        jb = np.moveaxis(_run_blocks(runs, k, jac), 0, -1)  # (n, c, p)
        m_k, b_k = _run_meat(_run_blocks(runs, k, r), jb, draws, rates[k])
        meat, bins = meat + m_k, bins + b_k
    jac = jac.T
    h_pinv = np.linalg.pinv(jac.T @ jac, rcond=1e-12, hermitian=True)
    cov = h_pinv @ meat @ h_pinv
    w, v = np.linalg.eigh(0.5 * (cov + cov.T))
    return Discrepancy((v * np.maximum(w, 0.0)) @ v.T, float(max(bins, 1)))
