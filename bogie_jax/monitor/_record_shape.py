"""The shape of the track records' error, chosen by the misfit it leaves.

`MonitorOptions.track_error` states only the records' error RMS. The records' term
(`_track_error.py`) draws that error shaped like the track, which puts nearly all of its power
at the longest wavelengths. A recording car's error need not look like that: noise of its
sensors is closer to white over the recording band, `RECORD_BAND` = 3-70 m (EN 13848-1:2019's
wavelength ranges D1 and D2). At the same RMS such an error carries far more short-wave power
than the track, which excites the primary suspension's vertical modes: on the detection
benchmark's `track-white` mode (50 cases, 0.1-0.3 mm) the primary vertical stiffnesses came
out 18-24 % low on average, an errors-in-variables bias the track-shaped term put at under 1 %,
while the goodness-of-fit test (`_goodness.py`) rejected every case. The two shapes leave
different misfits, so the data choose between them:

- where the fit explains the data with the track-shaped error, that term stands;
- otherwise the term is computed again with an error white over `RECORD_BAND` of the same RMS,
  and the error is taken as sqrt(1 - w) times a track-shaped and sqrt(w) times a white one,
  independent, with the stated RMS in all. Every quantity of the term is of second order in
  the error, so each mixes linearly in w: the covariance, the bias (SIMEX: second order), the
  misfit and each draw's misfit power (`mixed_effect`);
- w is the share, in steps of 0.05 from 0 to 1, under which the goodness-of-fit tests of every
  run-group are least surprised together (Fisher's combined statistic of their p-values, each
  test with its own null spread and the noise level it estimates given the term): a misfit
  spread over the groups as the white error spreads it calls for a white share, one that sits
  in a few groups (a failed element the fit does not judge) much less. (The share cannot be
  read off the statistics' excess over their null means linearly: each test's noise level,
  estimated from the high band less the draws' share there, moves with the term.)

The white share explains the size of the misfit but is not taken as explaining the data: the
term keeps the track-shaped draws' misfit, so the data stay not explained and an alarm must
hold under the misfit's scale with the suspects free (`_suspects.py`). That scale
(`_misfit_scale.py`) reads the tests of the misfit the mixture leaves (`mixed_record_term`):
what the white share accounts for widens the intervals once, through the term's covariance,
not again through the scale. Measured on `track-white`
with the data counted as explained by the mixture: a white error acts on the estimates beyond
first order, where the term understates it. At 0.225 mm the extrapolated biases of the primary
vertical stiffnesses were -0.17 to -0.24 against fitted errors of -0.14 to -0.30; at 0.3 mm a
healthy bogie's primary vertical dampers came out at 3.5 times nominal (4.9 standard errors
off) with an extrapolated bias of -0.18; at 0.147 mm one came out at 1.77 times nominal and was
called `degraded`. The mixture's covariance and, where it is too large to remove, its bias
(`_judgement._track_covariance`) widen the intervals. With two 8 s runs that was not enough:
the standard errors shrink while such a bias stays (a healthy primary damper called `degraded`
at 2.45 times nominal, 0.3 mm, its extrapolated bias +0.007). So where a white share is chosen
the fit is repeated on records calibrated for it (`_record_calibration.py`: the Wiener
estimate of the track, regression calibration), kept where it explains the data better, and
both terms are computed again there.

The other way round: a record's error can also hold less power where the bogie responds than
the track shape puts there, as a recording car's long-wave drift does (EN 13848-1:2019's range
D3, `LONG_BAND` = 70-200 m, below the suspension's modes at 30-60 m/s). Told only the RMS, the
track-shaped term then predicts a misfit the residuals do not hold and a second-order bias the
estimates do not have, and removing that bias moves sound estimates: on the detection
benchmark's `track-drift` mode with two 8 s runs (16 cases, 0.3-1 mm) the fitted estimates lay
within 0.1 % of the truth while the term's bias moved the primary vertical stiffnesses by 1-8 %,
and 4 to 10 of the 16 intervals of each missed. The data show it: the run-groups' statistics
stood below 1 % of their null means (their lower tail, `GoodnessOfFit.overstated`), where on the
benchmark's other modes they stood at 20 % or more. So where the data are explained with the
track-shaped term and a lower tail rejects:

- the term is computed again with an error white over `LONG_BAND` of the same RMS and the error
  is taken as sqrt(1 - w) times a track-shaped and sqrt(w) times a long-wave one (`mixed_effect`,
  its share in `long_wave_share`): covariance, bias and misfits of the mixture;
- w is chosen among `LONG_SHARES` (1 - w from 1 down to 1e-4 in quarter decades, and 0: the
  statistics span decades) as the least surprising in both tails together (Fisher's statistic of
  the two-sided p-values, 2 min(p, p_lower));
- the mixture's misfits are the term's: the data are explained only if they are explained with
  the error so shaped.

The long-wave error is drawn as a stationary process (`RecordError.stationary`): on a grid long
enough for waves longer than the record, faded in and out as the synthetic record is. Drawn on
the record's own Fourier grid, a 120 m record holds one wave of D3, periodic over the record;
drawn without the fade, it starts as a step into the run, whose transient the term then took
for frame vertical misfit (with that term alone, 11 of 20 intervals held the truth in two 2 s
drift cases; stationary, 20 of 20). The white term keeps the record's own grid without a fade:
drawn stationary, it gave a healthy bogie of `track-white` (case 0, 2 s runs, before
calibration) a primary damper alarm and 6 of 10 intervals (on the record's grid: none, 9 of
10).
"""

import numpy as np

from ._fit import Reweighted
from ._goodness import fit_goodness
from ._judgement import track_record_term
from ._record_calibration import calibrated_fit, calibrated_records
from ._track_error import TrackErrorEffect


RECORD_BAND = (3.0, 70.0)  # [m]: EN 13848-1:2019, wavelength ranges D1 (3-25 m) and D2 (25-70 m)
LONG_BAND = (70.0, 200.0)  # [m]: EN 13848-1:2019, wavelength range D3 (70-150 m level, -200 m)


SHARES = np.linspace(0.0, 1.0, 21)  # the white shares tried (module docstring)
LONG_SHARES = 1.0 - np.concatenate([[1.0], np.logspace(-0.25, -4.0, 16), [0.0]])
P_FLOOR = 1e-300  # a p-value below this counts as this in the combined statistic


def least_surprising_share(goodness_at, shares=SHARES, two_sided: bool = False) -> float:
    """The share w among `shares` (module docstring) under which the run-group tests are least
    surprised together: the smallest of Fisher's combined statistic -2 sum_g ln p_g (Fisher,
    *Statistical Methods for Research Workers*, 1925, sec. 21.1) of their p-values (upper tail;
    with `two_sided`, 2 min(p, p_lower)), `goodness_at(w)` giving the `GoodnessOfFit` with the
    term of that share; the smallest share at a tie."""
    combined = [_fisher(goodness_at(float(w)), two_sided) for w in shares]
    return float(shares[int(np.argmin(combined))])


def _fisher(goodness, two_sided: bool = False) -> float:
    """Fisher's combined statistic of a fit's run-group tests; inf where none is finite."""
    p = np.array([t.p_value for t in goodness.tests], dtype=float)
    if two_sided:
        lower = np.array([t.p_lower for t in goodness.tests], dtype=float)
        p = np.minimum(2.0 * np.minimum(p, lower), 1.0)
    p = p[np.isfinite(p)]
    return float(-2.0 * np.sum(np.log(np.maximum(p, P_FLOOR)))) if p.size else np.inf


def mixed_effect(
    track: TrackErrorEffect, other: TrackErrorEffect, w: float, share: str = "white_share"
) -> TrackErrorEffect:
    """The records' term of an error sqrt(1 - w) `track`-shaped and sqrt(w) shaped as `other`
    (module docstring), w recorded in the field `share` (`white_share`, `long_wave_share`);
    each draw's misfit scaled so that the draws' mean power mixes as the rest."""
    if w <= 0.0 or not other.draws:
        return track
    if w >= 1.0 or not track.draws:
        return other._replace(**{share: 1.0})
    a, b = 1.0 - w, w
    k = track.draws + other.draws
    misfits = np.concatenate(
        [np.sqrt(a * k / track.draws) * track.misfits, np.sqrt(b * k / other.draws) * other.misfits]
    )  # fmt: skip
    return TrackErrorEffect(
        covariance=a * track.covariance + b * other.covariance,
        bias=a * track.bias + b * other.bias,
        draws=k,
        misfit_ss=a * track.misfit_ss + b * other.misfit_ss,
        bias_by_step=a * track.bias_by_step + b * other.bias_by_step,
        refit_draws=min(track.refit_draws, other.refit_draws),
        misfits=misfits,
        bias_variance=a**2 * track.bias_variance + b**2 * other.bias_variance,
        **{share: w},
    )


def record_term(done: Reweighted, say) -> tuple[Reweighted, TrackErrorEffect | None]:
    """`monitor`'s step 6: the records' term (`_judgement.track_record_term`) with its shape
    chosen by the misfit (module docstring), and the fit it belongs to: the track-shaped term
    where it is `None`, has no draws or the fit explains the data with it; else mixed with the
    term of an error white over `RECORD_BAND`, its white share in `white_share`, the fit
    repeated on records calibrated for that share where that explains the data better
    (`_record_calibration.py`) and both terms computed again there (`calibrated` then true),
    the track-shaped term's misfit kept (so the data stay not explained)
    and the mixture's in `mixed_misfits` (for the misfit scale); where the data are explained
    but hold far less misfit than the term leaves (`GoodnessOfFit.overstated`),
    `long_wave_term`."""
    space, fit = done.space, done.fit
    track = track_record_term(space, fit, say)
    if track is None or not track.draws:
        return done, track
    goodness = fit_goodness(space, fit, track)
    if goodness.explained:
        return done, long_wave_term(space, fit, track, say) if goodness.overstated else track
    say("the data are not explained with a track-shaped record error: trying a white one")
    white = track_record_term(space, fit, say, band=RECORD_BAND)
    w = least_surprising_share(
        lambda share: fit_goodness(space, fit, mixed_effect(track, white, share))
    )
    say(f"record error: {100 * w:.0f} % of its variance white over the recording band")
    calibrated = done
    if w > 0.0:
        calibrated, track, white = calibrated_terms(done, w, track, white, say)
    mixed = mixed_effect(track, white, w)
    return calibrated, mixed._replace(
        misfits=track.misfits, misfit_ss=track.misfit_ss, mixed_misfits=mixed.misfits,
        calibrated=calibrated is not done,
    )  # fmt: skip


def calibrated_terms(done: Reweighted, w: float, track, white, say):
    """For a white share `w` of the records' error: the fit repeated on records calibrated for
    it (`_record_calibration.py`), and there the track-shaped term and the white one, whose
    bias's refits calibrate their perturbed records for the doubled white variance (SIMEX of
    the calibrated estimator; `_record_calibration.py`): (fit, track-shaped, white); `done` and
    the terms `track` and `white` where that fit fails or does not explain the data better."""
    raw = done.space.program.problem.tracks
    rms = done.space.program.problem.options.track_error * np.sqrt(w)
    calibrated = calibrated_fit(done, rms, RECORD_BAND, say)
    if calibrated is done:
        return done, track, white
    space, fit = calibrated.space, calibrated.fit
    twice = lambda records: calibrated_records(
        records, space.program.problem, rms * np.sqrt(2.0), RECORD_BAND
    )
    track = track_record_term(space, fit, say)
    white = track_record_term(space, fit, say, band=RECORD_BAND, raw=raw, prepare=twice)
    return calibrated, track, white


def long_wave_term(space, fit, track: TrackErrorEffect, say) -> TrackErrorEffect:
    """The records' term `track` mixed with that of an error white over `LONG_BAND`, its share
    the least surprising in both tails among `LONG_SHARES` (module docstring)."""
    say("the data hold far less misfit than a track-shaped record error leaves: trying drift")
    long = track_record_term(space, fit, say, band=LONG_BAND, stationary=True)
    w = least_surprising_share(
        lambda share: fit_goodness(space, fit, mixed_effect(track, long, share, "long_wave_share")),
        LONG_SHARES,
        two_sided=True,
    )
    say(f"record error: {100 * w:.2f} % of its variance long-wave ({LONG_BAND[0]:g}-"
        f"{LONG_BAND[1]:g} m)")  # fmt: skip
    return mixed_effect(track, long, w, "long_wave_share")


def mixed_record_term(effect: TrackErrorEffect | None) -> TrackErrorEffect | None:
    """`effect` with the misfits of its chosen shape (the mixture's where a white share was
    chosen): the misfit that remains beyond the records' error as the data chose its shape."""
    if effect is None or effect.mixed_misfits is None:
        return effect
    return effect._replace(misfits=effect.mixed_misfits)
