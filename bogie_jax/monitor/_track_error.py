"""The track record's error as a model-error term of the estimates' covariance, its bias, and
the residual it should leave.

The fit takes a recording car's measurement of the track as the true track. The record's
error (about 0.3 mm RMS per channel) moves the estimates by a fixed amount per run, and most
of that shift lies in the span of the Jacobian, where the residuals do not show it: the
sandwich covariance, estimated from the residuals, misses it, and with longer records the
standard errors shrink while this shift does not.

Model: the error of each channel of a record is a random process, scaled to RMS `rms` [m] in
alignment and vertical level and `rms / (2 b_0)` [rad] in cross level (a level error of `rms`
on each rail over the contact distance 2 b_0); the runs' errors are independent
(`record_error`). Where the run names a synthetic `TrackReference`, a realisation is that
reference's synthesis with a new seed: its spectrum, wavelength band and fades (a recording
error shaped like the track is what `recorded_track` simulates). Otherwise it is the record
with its Fourier phases drawn at random (uniform; the amplitude spectrum kept): over a short
record its few long-wave bins set the RMS, so its share of the shorter waves can differ from
the process's. A measured error spectrum would replace both.

Propagation, to first order at the fit's end: the error e shifts the estimates by
`dv = -J^+ (r(record + e) - r(record))` (J and r in the fitted coordinates, with the fit's
weights and bias projection; the run corrections take their share). The term is the mean of
`dv dv^T` over `draws` realisations (Monte Carlo: the relative error of a variance is about
sqrt(2 / draws)); each draw is one evaluation of the compiled residual Jacobian.

Bias (errors in the input variables): a record with error carries more irregularity than the
track, and the fit absorbs part of it by stiffening the model's response; the estimates are
biased by an amount of second order in the error, which the first-order shift above (mean zero)
does not show. It is removed by simulation-extrapolation (SIMEX: Cook and Stefanski, J. Am.
Stat. Assoc. 89 (1994) 1314-1328; Carroll et al., *Measurement Error in Nonlinear Models*, 2nd
ed. 2006, ch. 5) with one added level: each draw refits the record plus a second error of the
same variance by `refit_steps` Gauss-Newton steps from the fit's estimate, and the mean of the
refits' shifts is the bias at the record's own error level (bias linear in the error variance:
2 sigma^2 - sigma^2 = sigma^2), subtracted from the estimates. A single step is linear in the
shift while the bias is of second order, hence two steps by default. The mean of `draws` shifts
adds `1 / draws` of the term's variance to a corrected estimate's. `monitor` removes it only
from well-determined element coordinates (`_judgement.estimate_of`).

Misfit (a goodness-of-fit yardstick): the part of a draw's residual change outside the span of
J, `(I - J J^+)(r(record + e) - r(record))`, is what a record's error leaves in the residuals
after the fit has absorbed what it can; the mean of its squared norm over the draws is the
residual sum of squares the records' error should leave at a fit in the right minimum (to first
order). `monitor` reports the fit's residual sum of squares over it plus the sensors' noise
(`FitSummary.misfit_ratio`): about 1 at the right minimum.
"""

import dataclasses
from typing import NamedTuple

import numpy as np

from ..track import SPECTRA, TrackIrregularity


def scaled_error(error, rms: float, semi_distance: float) -> np.ndarray:
    """`error` `(n, 3)` scaled per channel to RMS `rms` [m] in alignment and vertical level and
    `rms / (2 semi_distance)` [rad] in cross level; a channel without power stays zero."""
    error = np.asarray(error, dtype=float)
    now = np.sqrt(np.mean(error**2, axis=0))
    target = np.array([rms, rms, rms / (2.0 * semi_distance)])
    return error * np.where(now > 0, target / np.where(now > 0, now, 1.0), 0.0)


def synthesis_error(reference, seed: int, rms: float, semi_distance: float) -> np.ndarray:
    """A synthetic record's error `(n, 3)`: the synthesis of `reference` (a synthetic
    `TrackReference`: its spectrum, band and fades) with `seed`, scaled (`scaled_error`)."""
    other = dataclasses.replace(reference, seed=seed).build()
    return scaled_error(other.values, rms, semi_distance)


def record_error(values, rms: float, semi_distance: float, rng, reference=None) -> np.ndarray:
    """One realisation `(n, 3)` of a record's error (module docstring) for the record
    `values` `(n, 3)` (alignment [m], vertical [m], cross level [rad]); `rng`: a numpy
    `Generator`. Where `reference` is a synthetic `TrackReference` whose track has the record's
    n samples: `synthesis_error` with a seed drawn from `rng` (`integers(0, 2**31 - 1)`);
    otherwise the record with random Fourier phases. A channel without power gets no error."""
    v = np.asarray(values, dtype=float)
    n = v.shape[0]
    if reference is not None and reference.file is None and reference.spectrum in SPECTRA:
        seed = int(rng.integers(0, 2**31 - 1))
        error = synthesis_error(reference, seed, rms, semi_distance)
        if error.shape == v.shape:
            return error
    spectrum = np.abs(np.fft.rfft(v - v.mean(axis=0), axis=0))
    phases = rng.uniform(0.0, 2.0 * np.pi, spectrum.shape)
    phases[0] = 0.0  # the mean (zero) stays real
    if n % 2 == 0:
        phases[-1] = 0.0  # so does the Nyquist term
    return scaled_error(
        np.fft.irfft(spectrum * np.exp(1j * phases), n=n, axis=0), rms, semi_distance
    )


REFIT_STEPS = 2  # Gauss-Newton steps of each draw's refit (module docstring)


@dataclasses.dataclass(frozen=True)
class RecordError:
    """The records' error model: RMS `rms` [m] in alignment and vertical level, cross level over
    the contact distance 2 `semi_distance` [m] (module docstring); `draw` is `record_error`."""

    rms: float
    semi_distance: float

    def draw(self, values, rng, reference=None) -> np.ndarray:
        return record_error(values, self.rms, self.semi_distance, rng, reference)


class TrackErrorEffect(NamedTuple):
    """The track records' error in the fitted coordinates (module docstring)."""

    covariance: np.ndarray  # (n, n): of the estimates' shift by the records' error
    bias: np.ndarray  # (n,): the estimates' bias from it (SIMEX), to subtract
    draws: int  # realisations used (a failed solve's left out)
    misfit_ss: float  # mean |(I - J J^+) dr|^2: the residual SS it leaves
    bias_by_step: np.ndarray  # (steps, n): the bias after each refit step
    refit_draws: int  # realisations whose every refit step solved (the bias's mean)
    misfits: np.ndarray  # (draws, m): each draw's (I - J J^+) dr, in the fit's weighted rows


def track_error_effect(
    evaluate_at, tracks, phi, error: RecordError, *, draws, refit_steps=REFIT_STEPS,
    references=None, seed=0,
):  # fmt: skip
    """The `TrackErrorEffect` (module docstring) at the fit's estimate `phi` (n,).

    - `evaluate_at(tracks, phi) -> (r (m,), J (m, n))`: the fit's residuals and Jacobian at
      the coordinates `phi` with these track records (in the fit's weights, projection and
      coordinates);
    - `tracks`: the runs' `TrackIrregularity` records; `error`: the `RecordError` model;
      `references`: the runs' `TrackReference`s or `None`s (`record_error`);
    - `draws` realisations from `numpy.random.default_rng(seed)`, each refitted by
      `refit_steps` (>= 1) Gauss-Newton steps; a draw whose residuals or Jacobian are not
      finite (a failed solve) is left out: of everything at its first evaluation, of the bias
      at a later one.
    """
    if not (isinstance(refit_steps, int) and refit_steps >= 1):
        raise ValueError(f"`refit_steps` = {refit_steps!r} must be an integer >= 1")
    rng = np.random.default_rng(seed)
    phi = np.asarray(phi, dtype=float)
    references = [None] * len(tracks) if references is None else list(references)
    r0, j0 = (np.asarray(a, dtype=float) for a in evaluate_at(list(tracks), phi))
    pinv = np.linalg.pinv(j0)
    step0 = pinv @ r0  # ~0 at a converged fit; subtracted so that no error gives no shift
    first, refit, misfit = [], [], []
    for _ in range(draws):
        perturbed = [
            TrackIrregularity(
                t.s0,
                t.ds,
                np.asarray(t.values) + error.draw(t.values, rng, ref),
            )
            for t, ref in zip(tracks, references)
        ]
        r, jac = (np.asarray(a, dtype=float) for a in evaluate_at(perturbed, phi))
        if not (np.all(np.isfinite(r)) and np.all(np.isfinite(jac))):
            continue
        change = r - r0
        first.append(-pinv @ change)
        misfit.append(change - j0 @ (pinv @ change))
        path, x = [], phi
        for step in range(refit_steps):
            if step:
                r, jac = (np.asarray(a, dtype=float) for a in evaluate_at(perturbed, x))
                if not (np.all(np.isfinite(r)) and np.all(np.isfinite(jac))):
                    break
            x = x - np.linalg.pinv(jac) @ r
            path.append(x - phi + step0)
        if len(path) == refit_steps:
            refit.append(path)
    n = j0.shape[1]
    by_step = np.mean(refit, axis=0) if refit else np.full((refit_steps, n), np.nan)
    if not first:
        none = np.zeros((0, r0.size))
        return TrackErrorEffect(np.full((n, n), np.nan), by_step[-1], 0, np.nan, by_step, 0, none)
    s, misfits = np.array(first), np.array(misfit)
    return TrackErrorEffect(
        s.T @ s / len(first), by_step[-1], len(first), float(np.mean(np.sum(misfits**2, axis=1))),
        by_step, len(refit), misfits,
    )  # fmt: skip
