"""The fit repeated on track records calibrated for the white share of their error.

Where the data call for a record error partly white over the recording band
(`_record_shape.py`), the raw records carry, at the shortest wavelengths, an error as large as
the track itself (on the detection benchmark's `track-white` mode at 0.3 mm, 0.6-0.8 times the
track's RMS at 3-5 m and 1.6-2.4 times at 5-10 m in alignment and level). A fit on them is
attenuated there: the model's response to the record's short waves looks too large for the
measured response, and the fit stiffens or softens the primary suspension to shrink it. On
that mode's two 8 s runs a healthy primary vertical damper came out at 2.45 times nominal with
the stiffnesses beside it at 0.6, far beyond what the records' second-order bias
(`_track_error.py`, SIMEX) extrapolated (+0.007 in ln p). That is errors in the variables at a
signal-to-error ratio near one, where an expansion in the error's size fails.

Regression calibration (Carroll et al., *Measurement Error in Nonlinear Models*, 2nd ed. 2006,
ch. 4) replaces each record by its best estimate of the track given the record, here the
Wiener filter for the error's share (`bogie_jax.track.calibrated_record`): the bogie responds
linearly to the track, so the part of the track the estimate misses is uncorrelated with it,
and a fit on the estimate is not attenuated. On the `track-white` records the filter brought
the regression slopes of track on record from 0.26-0.38 (3-5 m) and 0.73-0.86 (5-10 m) to
0.86-1.05 in alignment and level.

`calibrated_fit` repeats the fit from its estimate on the calibrated records and keeps it only
where it explains the data better (a lower cost, the same rows and weights): where the error is
white, the calibrated record lies closer to the track than the raw one (the error left has the
spectrum S_x S_e / S_r <= S_e) and so does the response to it; where the error is not white,
calibration takes track out of the record and the fit gets worse. On a matched 8 s case whose
goodness test had failed (detection `two_8s_runs_rerun` case 35, a track-shaped error, a white
share of 0.70 chosen) the calibrated fit left a misfit ratio of 4.0 (1.2 in the committed run,
without calibration) and 8 of 13 intervals holding the truth (12); on the `track-white` cases
0-3 the calibrated fits' residual variance lay 1-22 % below the uncalibrated run's.

Where the calibrated fit is kept, its space's problem holds the calibrated records as its
tracks from then on, so the records' term, the profile tests and the goodness of fit see them
too. The records' term is then computed again at the new estimate
(`_record_shape.calibrated_terms`). Its white part's spread is drawn as before, a white error
of the share's RMS on the records (more than the error calibration leaves, whose spectrum is
S_x S_e / S_r <= S_e: the intervals err wide there). Its bias is that of the estimator as it
is made, calibration included (SIMEX, `_track_error.py`): each refit's perturbed record, the
raw record plus a second white error of the same variance, is calibrated for the doubled
variance before the refit, so the refits' mean shift is what calibration leaves of the bias
(from the filter's own estimation error, for one), not the raw records' bias. Calibration makes
that bias small, where SIMEX's expansion in the error's size holds.
"""

import dataclasses

import numpy as np

from ..cost import channel_variances
from ..identify import levenberg_marquardt
from ..track import calibrated_record
from ._fit import Reweighted


def calibrated_records(records, problem, rms: float, band) -> tuple:
    """The track `records` of `problem`'s runs calibrated (`bogie_jax.track.calibrated_record`)
    for an error white over the wavelength `band` (lo, hi) [m] of RMS `rms` [m]."""
    semi = float(np.asarray(problem.params.contact.contact_semi_distance))
    return tuple(calibrated_record(t, rms, band, semi) for t in records)


def calibrated_fit(done: Reweighted, rms: float, band, say) -> Reweighted:
    """`done` with the fit repeated from its estimate on the records calibrated for an error
    white over `band` [m] of RMS `rms` [m] (module docstring), the run-channels' residual
    variances estimated again from it; `done` itself where the refit fails or ends at a cost
    no lower than the fit on the raw records (module docstring)."""
    program = done.space.program
    space = done.space.with_program(
        program.with_tracks(calibrated_records(program.problem.tracks, program.problem, rms, band))
    )
    say(f"fitting again on the records calibrated for {1e3 * rms:.3g} mm of white error")
    refit = levenberg_marquardt(
        space.evaluate, done.fit.phi, max_steps=program.problem.options.max_steps
    )
    if refit.status == "failed":
        say("the fit on the calibrated records failed: keeping the records as they are")
        return done
    if not refit.cost < done.fit.cost:
        say("the calibrated records explain the data less well: keeping the records as they are")
        return done
    o = program.problem.options
    s2 = channel_variances(refit.r, refit.jac, space.runs(), remove_bias=o.remove_bias,
                           weights=done.weights)  # fmt: skip
    return dataclasses.replace(
        done, space=space, fit=refit, refits=done.refits + (refit,), s2_channels=s2
    )
