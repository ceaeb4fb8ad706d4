"""`monitor`'s checks: its input before anything is compiled, the tolerance bands, and which
runs a fit leaves out."""

import numpy as np

from .._validation import nonempty_tuple
from ..measure import Measurement
from ..params import resolve_parameter
from ._elements import element_band, nominal_values, tied_group
from ._verdict import ToleranceBand


RUN_MISFIT = 10.0


def failed_runs(r, slices, active, n_obs, run_misfit):
    """Runs to leave out after a fit: every active run with non-finite residuals (its
    simulation failed at the estimate); else, of two or more active runs, the worst-fitting
    run k if its mean squared weighted residual s2_k = |r_k|^2 / n_k exceeds `run_misfit` (its
    residuals are more than sqrt(run_misfit) times the sensors' noise) and `run_misfit` times
    the smallest s2 of the other active runs (the joint model explains them, not run k)."""
    live = [k for k in np.flatnonzero(active)]
    broken = [k for k in live if not np.all(np.isfinite(r[slices[k]]))]
    if broken:
        if len(broken) == len(live):
            return [], {}
        return broken, {k: "simulation failed at the estimate" for k in broken}
    if len(live) < 2:
        return [], {}
    s2 = {k: float(np.sum(r[slices[k]] ** 2)) / max(n_obs[k], 1) for k in live}
    worst = max(live, key=lambda k: s2[k])
    best = min(s2[k] for k in live if k != worst)
    if s2[worst] > run_misfit and s2[worst] > run_misfit * best:
        rms, other = np.sqrt(s2[worst]), np.sqrt(best)
        return [worst], {
            worst: f"the joint fit does not explain it: weighted residual RMS {rms:.3g} "
            f"(sensor noise units) against {other:.3g} for the best other run"
        }
    return [], {}


def as_measurements(measurements) -> tuple[Measurement, ...]:
    """One `Measurement` or a sequence of them as a non-empty tuple (`ValueError` if empty,
    `TypeError` naming the first entry that is not a `Measurement`)."""
    if isinstance(measurements, Measurement):
        measurements = (measurements,)
    return nonempty_tuple(
        "measurements", measurements, Measurement, "give at least one measurement run"
    )


def check_inputs(measurements, tracks):
    measurements = as_measurements(measurements)
    first = measurements[0]
    for k, m in enumerate(measurements[1:], start=1):
        if m.layout != first.layout or m.channels != first.channels:
            raise ValueError(
                f"`measurements` mix sensor layouts: run {k} has channels "
                f"{', '.join(m.channels)} with layout {m.layout[:80]!r}..., run 0 has "
                f"{', '.join(first.channels)} with layout {first.layout[:80]!r}...; monitor one "
                "bogie layout per call"
            )
    if tracks is None:
        tracks = []
        for k, m in enumerate(measurements):
            if m.track is None or m.track.file is not None:
                raise ValueError(
                    f"`tracks` is None and measurement {k} has track reference {m.track!r}: pass "
                    "the tracks (bogie_jax.io.load_track reads a track file)"
                )
            tracks.append(m.track.build())
    tracks = tuple(tracks)
    if len(tracks) != len(measurements):
        raise ValueError(
            f"`tracks` has {len(tracks)} entries for {len(measurements)} measurements: give one "
            "track per run, in the same order"
        )
    return measurements, tracks


def tolerance_bands(params, names, band):
    if isinstance(band, ToleranceBand) and len(names) > 1:
        raise ValueError(
            "`band` is one ToleranceBand for several candidates of different units: give a "
            "mapping {name: ToleranceBand or relative half-width} or one relative half-width"
        )
    nominal = nominal_values(params, names)
    bad = [f"{n} = {p:g}" for n, p in zip(names, nominal) if not p > 0]
    if bad:
        raise ValueError(f"candidates need nominal values > 0 (fitted in ln p): {', '.join(bad)}")
    return {
        n: element_band(n, p, resolve_parameter(params, n).spec.unit, band, tied_group(params, n))
        for n, p in zip(names, nominal)
    }
