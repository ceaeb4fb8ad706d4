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
`dv = -J^+ D e` (J and r in the fitted coordinates, with the fit's weights and bias projection;
the run corrections take their share; D e the residuals' derivative along e). The term is the
mean of `dv dv^T` over `draws` realisations (Monte Carlo: the relative error of a variance is
about sqrt(2 / draws)). D e is the central difference (r(record + e) - r(record - e)) / 2:
exact where r is linear in the record (the linear contact model: the track enters the
equations of motion linearly), with an error of third order in e otherwise. The bias's refits
below solve the first pairs' records already (at the fit's tolerance); the other draws' are
solved at the Jacobian's looser one (`MonitorOptions.jacobian_rtol`) by the residuals' program
the fit compiled (no program of their own). On two 8 s runs (detection case 1) the differences
at rtol 1e-4 agreed with those at the fit's 1e-6 to 0.14-0.19 % (6 draws) at 0.41 times the
cost per solve; forward-mode derivatives along e at rtol 1e-4 differed from them by 0.8-2.8 %.

Bias (errors in the input variables): a record with error carries more irregularity than the
track, and the fit absorbs part of it by stiffening the model's response; the estimates are
biased by an amount of second order in the error, which the first-order shift above (mean zero)
does not show. It is removed by simulation-extrapolation (SIMEX: Cook and Stefanski, J. Am.
Stat. Assoc. 89 (1994) 1314-1328; Carroll et al., *Measurement Error in Nonlinear Models*, 2nd
ed. 2006, ch. 5) with one added level: the record plus a second error of the same variance is
refitted by `refit_steps` steps (below) from the fit's estimate, and the mean of the
refits' shifts is the bias at the record's own error level (bias linear in the error variance:
2 sigma^2 - sigma^2 = sigma^2), subtracted from the estimates. The refits come in antithetic
pairs, record + e and record - e (Hammersley and Morton, Proc. Camb. Phil. Soc. 52 (1956)
449-475): the pair's mean shift has no first-order term, so its spread is that of the
second-order term alone and a few pairs give the bias to a small fraction of the term's
spread, which independent draws give only as 1 / sqrt(draws) of it. The bias comes from the
Jacobian's dependence on the record (a step with the fit's own Jacobian, which needs only
residuals, leaves none of it), so a refit's first step evaluates the Jacobian on the perturbed
record. One step is linear in the shift while the bias is of second order, hence a second
step: a chord step, the first step's Jacobian with the residuals at the first step's end
(Dennis and Schnabel, *Numerical Methods for Unconstrained Optimization and Nonlinear
Equations*, 1983, sec. 5.4), at the cost of one solve instead of a Jacobian (the term's cost
is mostly these refits). The chord's end is not quite the refit's minimum: it sets the
first step's Jacobian, not the one at the minimum, orthogonal to the residuals left there;
the difference is of first order in e times those residuals, and its first order cancels in
an antithetic pair. On two 8 s runs (detection case 1) the chord's biases lay within 10 % of
two Gauss-Newton steps' (0.0001-0.0024 in ln p), the estimates within 0.074 of their standard
errors (median 0.026), the verdicts the same, a third chord step changing none of it (the
chord's end, not its convergence; docs/history.md has the timings). The pairs' spread gives
the Monte Carlo variance of the bias, added to a corrected estimate's. `monitor` removes
it only from well-determined element coordinates (`_judgement.estimate_of`).

Misfit (a goodness-of-fit yardstick): the part of a draw's residual change outside the span of
J, `(I - J J^+) D e`, is what a record's error leaves in the residuals
after the fit has absorbed what it can; the mean of its squared norm over the draws is the
residual sum of squares the records' error should leave at a fit in the right minimum (to first
order). `monitor` reports the fit's residual sum of squares over it plus the sensors' noise
(`FitSummary.misfit_ratio`): about 1 at the right minimum.
"""

import dataclasses
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numpy as np

from ..runtime.cores import core_count
from ..track import FADE_LENGTH, SPECTRA, TrackIrregularity, fade_envelope


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


def _synthetic(reference) -> bool:
    """Whether `reference` names a synthetic track (a `TrackReference` with a spectrum)."""
    return reference is not None and reference.file is None and reference.spectrum in SPECTRA


def record_error(values, rms: float, semi_distance: float, rng, reference=None) -> np.ndarray:
    """One realisation `(n, 3)` of a record's error (module docstring) for the record
    `values` `(n, 3)` (alignment [m], vertical [m], cross level [rad]); `rng`: a numpy
    `Generator`. Where `reference` is a synthetic `TrackReference` whose track has the record's
    n samples: `synthesis_error` with a seed drawn from `rng` (`integers(0, 2**31 - 1)`);
    otherwise the record with random Fourier phases. A channel without power gets no error."""
    v = np.asarray(values, dtype=float)
    n = v.shape[0]
    if _synthetic(reference):
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


BAND_BINS = 256  # Fourier bins inside a stationary band error's band, at least (`RecordError`)


def band_error(
    values, ds: float, rms: float, semi_distance: float, rng, band, fade: float = 0.0,
    bins: int = 0,
) -> np.ndarray:  # fmt: skip
    """One realisation `(n, 3)` of a record error white over the wavelength `band` (lo, hi) [m]
    on the record `values` `(n, 3)` sampled every `ds` [m]: independent complex normal Fourier
    coefficients at the wavenumbers 1 / hi to 1 / lo [1/m] of a periodic grid of N >= n
    samples that holds at least `bins` of them (0: the record's own grid), none elsewhere, its
    first n samples taken (with `bins`, waves longer than the record enter as the record's
    share of them, not as its periodic harmonics), faded in and out over `fade` [m]
    (`bogie_jax.track.fade_envelope`) and scaled (`scaled_error`); `rng`: a numpy `Generator`.
    A channel of the record without power gets no error."""
    v = np.asarray(values, dtype=float)
    n = v.shape[0]
    grid = max(n, int(np.ceil(bins / (ds * (1.0 / band[0] - 1.0 / band[1])))))
    wavenumbers = np.fft.rfftfreq(grid, d=ds)
    inside = (wavenumbers >= 1.0 / band[1]) & (wavenumbers <= 1.0 / band[0])
    shape = (wavenumbers.size, 3)
    coefficients = (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) * inside[:, None]
    powered = np.any(v != v[:1], axis=0)
    error = np.fft.irfft(coefficients, n=grid, axis=0)[:n]
    if fade > 0.0 and 2.0 * fade <= ds * (n - 1):
        error = error * fade_envelope(ds * np.arange(n), fade)[:, None]
    return scaled_error(error * powered, rms, semi_distance)


REFIT_STEPS = 2  # steps of each refit: Gauss-Newton, then chord (module docstring)
BIAS_PAIRS = 4  # antithetic pairs of refits for the bias (module docstring)


@dataclasses.dataclass(frozen=True)
class RecordError:
    """The records' error model: RMS `rms` [m] in alignment and vertical level, cross level over
    the contact distance 2 `semi_distance` [m] (module docstring); shaped like the track
    (`record_error`) where `band` is `None`, else white over that wavelength band (lo, hi) [m]
    (`band_error`): on the record's own Fourier grid, or with `stationary` on a grid of at
    least `BAND_BINS` bins in the band (waves longer than the record) and faded in and out as
    the track of a synthetic `TrackReference` is (that record starts from zero: an error that
    did not would be a step into the run). `_record_shape.py` says which term uses which."""

    rms: float
    semi_distance: float
    band: tuple[float, float] | None = None
    stationary: bool = False

    def draw(self, track, rng, reference=None) -> np.ndarray:
        """One realisation `(n, 3)` for the record `track` (a `TrackIrregularity`)."""
        if self.band is None:
            return record_error(track.values, self.rms, self.semi_distance, rng, reference)
        if not self.stationary:
            return band_error(track.values, track.ds, self.rms, self.semi_distance, rng, self.band)
        fade = FADE_LENGTH if _synthetic(reference) else 0.0
        return band_error(
            track.values, track.ds, self.rms, self.semi_distance, rng, self.band, fade, BAND_BINS
        )


class TrackErrorEffect(NamedTuple):
    """The track records' error in the fitted coordinates (module docstring)."""

    covariance: np.ndarray  # (n, n): of the estimates' shift by the records' error
    bias: np.ndarray  # (n,): the estimates' bias from it (SIMEX), to subtract
    draws: int  # realisations in the covariance (a failed solve's left out)
    misfit_ss: float  # mean |(I - J J^+) dr|^2: the residual SS it leaves
    bias_by_step: np.ndarray  # (steps, n): the bias after each refit step
    refit_draws: int  # antithetic pairs whose every refit step solved (the bias's mean)
    misfits: np.ndarray  # (draws, m): each draw's (I - J J^+) dr, in the fit's weighted rows
    bias_variance: np.ndarray  # (n,): the Monte Carlo variance of `bias` (inf: one pair)
    white_share: float = 0.0  # of the error's variance white over a band (`_record_shape.py`)
    long_wave_share: float = 0.0  # of it white over the long waves (`_record_shape.py`)
    mixed_misfits: np.ndarray | None = None  # (draws, m): the mixed error's, where `misfits`
    # are the track-shaped draws' (`_record_shape.py`); the misfit scale's tests use them
    calibrated: bool = False  # the fit repeated on records calibrated for the white share


def _finite(*arrays) -> bool:
    return all(np.all(np.isfinite(a)) for a in arrays)


def _refit(fit, records, phi, steps: int):
    """r (m,) at `phi` on `records`, and the path (steps, n) of `steps` steps from
    `phi` on them: the first with the Jacobian at `phi`, the later ones chord steps with that
    Jacobian and the residuals alone (module docstring); `None` where an evaluation is not
    finite (a failed solve)."""
    first, jac = (np.asarray(a, dtype=float) for a in fit.evaluate_on(records, phi))
    if not _finite(first, jac):
        return first, None
    pinv = np.linalg.pinv(jac)
    path = [phi - pinv @ first]
    for _ in range(steps - 1):
        r = np.asarray(fit.fit_residuals_on(records, path[-1]), dtype=float)
        if not _finite(r):
            return first, None
        path.append(path[-1] - pinv @ r)
    return first, np.array(path)


def _with_error(tracks, errors, sign: float = 1.0):
    """The records `tracks` plus `sign` times `errors` (one (n, 3) array per record)."""
    return [
        TrackIrregularity(t.s0, t.ds, np.asarray(t.values) + sign * e)
        for t, e in zip(tracks, errors)
    ]


def _pair_means(paths, phi, step0):
    """The antithetic pairs' mean refit shifts (pairs, steps, n), from the refit paths in pairs
    (+e, -e) order, a pair with a failed refit (`None`) left out."""
    pairs = zip(paths[0::2], paths[1::2])
    return [0.5 * (a + b) - phi + step0 for a, b in pairs if a is not None and b is not None]


def _bias(means, steps: int, n: int):
    """(by_step (steps, n), pairs used, Monte Carlo variance (n,) of the last step's mean)."""
    if not means:
        return np.full((steps, n), np.nan), 0, np.full(n, np.inf)
    means = np.array(means)
    spread = np.var(means[:, -1], axis=0, ddof=1) / len(means) if len(means) > 1 else np.inf
    return means.mean(axis=0), len(means), np.broadcast_to(spread, (n,)).copy()


@dataclasses.dataclass(frozen=True)
class Sampling:
    """How the records' error is sampled (module docstring): `draws` realisations from
    `numpy.random.default_rng(seed)` for the covariance and the misfit; the first `pairs` of
    them (>= 1), with and without their sign, refitted by `refit_steps` (>= 1) steps for the
    bias (a Gauss-Newton step, then chord steps); `workers` threads run the derivatives and the
    refits side by side (`None`: one per core; the compiled programs release the interpreter
    while they run)."""

    draws: int
    pairs: int = BIAS_PAIRS
    refit_steps: int = REFIT_STEPS
    seed: int = 0
    workers: int | None = None

    def __post_init__(self):
        for name in ("draws", "pairs", "refit_steps"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"`{name}` = {value!r} must be an integer >= 1")


def track_error_effect(
    fit, tracks, phi, error: RecordError, sampling: Sampling, *, references=None, start=None,
    refit_records=None,
):  # fmt: skip
    """The `TrackErrorEffect` (module docstring) at the fit's estimate `phi` (n,).

    - `fit`: the fit's residuals on other records, with three methods (a `FitSpace`):
      `evaluate_on(tracks, phi) -> (r (m,), J (m, n))`, its residuals and Jacobian at the
      coordinates `phi` with these track records (in the fit's weights, projection and
      coordinates), `residuals_on(tracks, phi) -> r (m,)`, the residuals alone from the
      Jacobian's solves (for differences), and `fit_residuals_on(tracks, phi) -> r (m,)`, the
      residuals alone at the fit's tolerance (for the refits' chord steps);
    - `tracks`: the runs' `TrackIrregularity` records; `error`: the `RecordError` model;
      `sampling`: `Sampling`; `references`: the runs' `TrackReference`s or `None`s
      (`record_error`); `start`: `fit.evaluate_on(tracks, phi)` where the caller has it;
      `refit_records`: where the estimate came from records prepared from `tracks` (calibrated,
      `_record_calibration.py`), the same preparation for the bias's perturbed records (a
      callable from a list of records to the list the refit runs on), so that the refits'
      shift is that of the whole procedure (SIMEX of the estimator as it is made).

    A draw whose derivative is not finite (a failed solve) is left out of the covariance and
    the misfit, a pair with a failed refit of the bias.
    """
    rng = np.random.default_rng(sampling.seed)
    phi = np.asarray(phi, dtype=float)
    references = [None] * len(tracks) if references is None else list(references)
    errors = [
        [error.draw(t, rng, ref) for t, ref in zip(tracks, references)]
        for _ in range(sampling.draws)
    ]  # fmt: skip
    start = fit.evaluate_on(list(tracks), phi) if start is None else start
    r0, j0 = (np.asarray(a, dtype=float) for a in start)
    pairs = len(errors[: sampling.pairs])
    perturbed = [_with_error(tracks, e, sign) for e in errors for sign in (1, -1)]
    steps = sampling.refit_steps
    prepare = refit_records or (lambda records: records)
    with ThreadPoolExecutor(sampling.workers or core_count()) as pool:
        refits = [
            pool.submit(_refit, fit, prepare(x), phi, steps) for x in perturbed[: 2 * pairs]
        ]  # fmt: skip
        others = [pool.submit(fit.residuals_on, x, phi) for x in perturbed[2 * pairs :]]
        refits = [f.result() for f in refits]
        shifted = [r for r, _ in refits] + [np.asarray(f.result(), dtype=float) for f in others]
    paths = [path for _, path in refits]
    d = 0.5 * (np.array(shifted[0::2]) - np.array(shifted[1::2]))  # (K, m): D e, by draw
    pinv = np.linalg.pinv(j0)
    step0 = pinv @ r0  # ~0 at a converged fit; subtracted so that no error gives no shift
    by_step, n_pairs, bias_var = _bias(_pair_means(paths, phi, step0), steps, phi.size)
    d = d[np.all(np.isfinite(d), axis=1)]
    first = -(pinv @ d.T).T  # (K, n): each draw's first-order shift
    misfits = d - (j0 @ (pinv @ d.T)).T
    n, k = j0.shape[1], d.shape[0]
    if not k:
        return TrackErrorEffect(
            np.full((n, n), np.nan), by_step[-1], 0, np.nan, by_step, n_pairs, misfits, bias_var
        )
    return TrackErrorEffect(
        first.T @ first / k, by_step[-1], k, float(np.mean(np.sum(misfits**2, axis=1))),
        by_step, n_pairs, misfits, bias_var,
    )  # fmt: skip
