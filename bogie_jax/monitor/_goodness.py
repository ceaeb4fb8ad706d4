"""Does the fit explain the data? A goodness-of-fit test per run and channel group that the
per-channel noise estimate cannot absorb.

`PerChannelNoise` sets each run-channel's weight from its residual variance, so a structured
misfit (a failed element the fit does not judge, nonlinear contact, worn wheels) only raises that
channel's estimated noise, and the fit stays confident. The test separates the two by their
spectra: sensor noise is white, while a misfit of the model is the bogie's response to the track
and lies in its response band. For every active run and channel, the residual r(t) of the fit
(in the fit's weights, the sensor bias removed, the samples outside the fit's window or missing
set to zero) has the periodogram P(f) = |R(f)|^2 / n (n the present samples; the DC bin, which
the bias removal empties, and the Nyquist bin are left out). White noise of variance s^2 gives
P(f) / s^2 independent and exponential (chi^2_2 / 2) at every bin, whatever f.

- the response band `LOW_BAND` = 0.5-15 Hz: the frame's bounce, pitch and roll modes, the
  wheelsets' kinematic oscillation at 30-60 m/s and most of the track's excitation, where a
  changed element changes the response;
- the noise band `HIGH_BAND_START` = 25 Hz to the Nyquist frequency. Chosen by measurement: on
  the benchmark's 1 s runs at 100 Hz (0.3 mm record error, noise 1-3 % of each channel's RMS)
  the fit's residual held 10^2 to 10^3 times the sensor noise per bin below 15 Hz, 5 to 340
  times at 15-25 Hz (the track's excitation at the higher speeds), and 1 to 8 times above 25
  Hz, most of that excess the record error's share, which the draws below account for. Its mean
  periodogram, less the mean the record error's draws leave there (floored at a quarter of it),
  is the channel's noise level s^2;
- per channel group (`channel_groups`: frame lateral, frame vertical, yaw rate, axlebox
  lateral), the statistic T = the sum over its channels of the low band's mean periodogram
  over the channel's s^2: about the number of channels C for white residuals.

The null: white noise plus what the track record's error leaves (`MonitorOptions.track_error`;
`TrackErrorEffect.misfits`: each draw's residual change outside the Jacobian's span, in the
fit's weighted rows). Per channel, the low band's mean over the true noise level is N_c = 1 + q
+ (noise and noise-misfit cross term: variance (1 + 2 q) / n_L), q the draws' normalised misfit
power; the noise estimate over the true level is B_c ~ chi^2_{2 n_H} / (2 n_H). T = sum N_c /
B_c has its mean and variance from these (the draws' mean q per channel; their spread across
the D draws of the group's sum, times (1 + 1 / D) (D - 1) / (D - 3), Student's t predictive
variance for a new draw from an estimated spread), and is referred to kappa F(nu_1, nu_2) with
nu_1 from N's mean and variance and kappa, nu_2 matching T's (two-moment approximation, as
Satterthwaite, Biometrics Bulletin 2 (1946) 110). Without a track error, q = 0 and a one-channel
group's T / (mean) is exactly F(2 n_L, 2 n_H). On white noise the per-test rejection rate was
5.0 % at 0.05 and 0.7 % at 0.00625 (8000 tests, `tests/test_monitor_goodness.py`).

The run-group tests are decided together at the monitor's `false_alarm_rate` (Holm's step-down
Bonferroni, Scand. J. Statist. 6 (1979) 65) and the data are not explained where one rejects;
a misfit whose excess over the noise is under `MIN_EXCESS` of the sensors' stated noise
variance per bin is not called (a fit of noise-free data converged to a tiny residual). The
same null's lower tail, decided the same way (`GoodnessOfFit.overstated`), finds run-groups
that hold far less misfit than the records' error as told should leave: an error whose power
lies where the bogie hardly responds (`_record_shape.py`).
`benchmarks/goodness_of_fit.py` measures the false-alarm rate and power.
"""

import dataclasses

import numpy as np
import scipy.stats

from ..cost import RunChannels


LOW_BAND = (0.5, 15.0)  # [Hz]: the bogie's response band (module docstring)
HIGH_BAND_START = 25.0  # [Hz]: the noise band, up to the Nyquist frequency
MIN_BINS = 4  # a band of fewer bins in a run is not tested
MIN_EXCESS = 0.01  # [-] of the stated noise variance per bin: a smaller misfit is not called
DIRECTIONS = {"x": "longitudinal", "y": "lateral", "z": "vertical"}
RATES = {"x": "roll rate", "y": "pitch rate", "z": "yaw rate"}


def sensor_group(sensor) -> str:
    """The channel group of a sensor: `yaw rate` (a rate gyro about z), else its body and
    direction (`frame vertical`, `axlebox lateral`), `displacement` added for a displacement
    sensor."""
    description = sensor.describe()
    axis = description.get("axis", "z")
    if "location" not in description:
        return RATES.get(axis, f"rate {axis}")
    body = next(iter(description["location"]), "point")
    kind = " displacement" if description.get("unit") == "m" else ""
    return f"{body} {DIRECTIONS.get(axis, axis)}{kind}"


def channel_group(name: str, unit: str) -> str:
    """The group of a channel without a sensor layout, from its name (`frame_1L_z`: `frame
    vertical`; `frame_yaw_rate`: `yaw rate`) and unit."""
    parts = name.split("_")
    if unit == "rad/s":
        return next((r for r in RATES.values() if r.split()[0] in parts), f"{parts[0]} rate")
    kind = " displacement" if unit == "m" else ""
    return f"{parts[0]} {DIRECTIONS.get(parts[-1], parts[-1])}{kind}"


def channel_groups(measurement) -> tuple[tuple[str, tuple[int, ...]], ...]:
    """`((group, channel indices), ...)` of a measurement, in order of first appearance: from
    its sensor layout where it has one (`sensor_group`), else from the channels' names."""
    if measurement.layout:
        by_name = {s.name: sensor_group(s) for s in measurement.sensors()}
        names = [by_name[c] for c in measurement.channels]
    else:
        names = [channel_group(c, u) for c, u in zip(measurement.channels, measurement.units)]
    order = list(dict.fromkeys(names))
    return tuple((g, tuple(j for j, n in enumerate(names) if n == g)) for g in order)


@dataclasses.dataclass(frozen=True)
class Misfit:
    """One run-group test: `run`, `group` and its `channels`; `statistic` T (module docstring:
    the low band's power over the noise level, summed over the group's channels), `expected`
    its null mean (the channels plus `track_record`, the records' error share), `ratio` = T /
    `expected` (about 1 when the fit explains the data), `p_value` (of a T this large or
    larger), `p_lower` (of a T this small or smaller), and whether the family-wise test
    `rejected` it."""

    run: int
    group: str
    channels: tuple[str, ...]
    statistic: float
    expected: float
    track_record: float
    ratio: float
    p_value: float
    rejected: bool = False
    p_lower: float = float("nan")

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class GoodnessOfFit:
    """The goodness-of-fit test of a fit (module docstring): every run-group test, the family-
    wise `alpha`, the bands [Hz]; `suspects` (`_suspects.py`) where the data are not explained;
    `note` says why nothing was tested (empty otherwise)."""

    tests: tuple[Misfit, ...]
    alpha: float
    low_band: tuple[float, float] = LOW_BAND
    high_band_start: float = HIGH_BAND_START
    suspects: tuple = ()
    note: str = ""

    @property
    def explained(self) -> bool:
        return not self.misfits

    @property
    def misfits(self) -> tuple[Misfit, ...]:
        """The run-groups whose test rejects: where the fit does not explain the data."""
        return tuple(t for t in self.tests if t.rejected)

    @property
    def overstated(self) -> tuple[Misfit, ...]:
        """The run-groups whose lower-tail test (`p_lower`, Holm at `alpha`) rejects: they hold
        less misfit than the noise and the records' error as told allow."""
        reject = holm([t.p_lower for t in self.tests], self.alpha)
        return tuple(t for t, x in zip(self.tests, reject) if x)

    def to_dict(self) -> dict:
        return {
            "explained": self.explained,
            "alpha": self.alpha,
            "low_band_hz": list(self.low_band),
            "high_band_start_hz": self.high_band_start,
            "misfits": [t.to_dict() for t in self.misfits],
            "tests": [t.to_dict() for t in self.tests],
            "suspects": [s.to_dict() for s in self.suspects],
            "note": self.note,
        }


def band_powers(series, present, rate: float, low=LOW_BAND, high_start=HIGH_BAND_START):
    """(low mean, high mean, n_low, n_high) of the periodogram of `series` (n, c) per channel
    (module docstring), with `present` (n, c) the samples used (others set to zero); `None`
    where a band has fewer than `MIN_BINS` bins."""
    x = np.where(present, np.asarray(series, dtype=float), 0.0)
    n, axis = x.shape[-2], x.ndim - 2
    count = np.maximum(present.sum(axis=0), 1)
    p = np.abs(np.fft.rfft(x, axis=axis)) ** 2 / count
    f = np.fft.rfftfreq(n, 1.0 / rate)
    inner = (f > 0) & (f < rate / 2)
    lo = inner & (f >= low[0]) & (f <= low[1])
    hi = inner & (f >= high_start)
    if lo.sum() < MIN_BINS or hi.sum() < MIN_BINS:
        return None
    take = lambda sel: np.compress(sel, p, axis=axis).mean(axis=axis)
    return take(lo), take(hi), int(lo.sum()), int(hi.sum())


def null_distribution(q, n_low: int, n_high: int) -> tuple[float, float, float, float]:
    """(mean, kappa, nu_low, nu_high) of T under the null, T ~ kappa F(nu_low, nu_high) with
    T's mean and variance: T = sum over channels of N_c / B_c, N_c the low band's mean over
    the channel's noise level (noise, noise-misfit cross term and the misfit `q` (D, c) of the
    draws, normalised), B_c the noise estimate over it, chi^2_{2 n_H} / (2 n_H)."""
    q_group, q_mean = q.sum(axis=1), q.mean(axis=0)
    d2 = 2.0 * n_high
    inv1, inv2 = d2 / (d2 - 2), d2**2 / ((d2 - 2) * (d2 - 4))  # E 1/B, E 1/B^2
    var_n = (1 + 2 * q_mean) / n_low
    d, spread = q_group.size, 0.0
    if d >= 4:  # the spread of a new draw from D (Student's t predictive variance)
        spread = float(np.var(q_group, ddof=1)) * (1 + 1 / d) * (d - 1) / (d - 3)
    mean_n = float(np.sum(1 + q_mean))
    mean = mean_n * inv1
    var = float(np.sum(var_n * inv2 + (1 + q_mean) ** 2 * (inv2 - inv1**2))) + spread * inv2
    nu_low = 2 * mean_n**2 / (float(np.sum(var_n)) + spread)
    a = var / mean**2 * nu_low  # the squared coefficient of variation of kappa F, times nu_low
    nu_high = (2 * nu_low - 4 + 4 * a) / (a - 2) if a > 2.01 else 1e6
    return mean, mean * (nu_high - 2) / nu_high, nu_low, nu_high


def group_test(observed, draws, n_low: int, n_high: int, stated) -> tuple[float, ...]:
    """(T, expected, track-record share, p-value, lower-tail p-value) of one run-group (module
    docstring). `observed`: (low, high) band means (c,) of the residual; `draws`: (low, high)
    (D, c) of the track records' error draws or `None`; `stated`: (c,) the noise variance per
    bin at the sensors' stated noise (weights included)."""
    low, high = observed
    c = low.size
    if draws is None or draws[0].shape[0] < 4:
        q_low, q_high = np.zeros((1, c)), np.zeros((1, c))
    else:
        q_low, q_high = draws
    s2 = np.maximum(high - q_high.mean(axis=0), 0.25 * high)
    t = float(np.sum(low / s2))
    mean, kappa, nu_low, nu_high = null_distribution(q_low / s2, n_low, n_high)
    p = float(scipy.stats.f.sf(t / kappa, nu_low, nu_high))
    p_lower = float(scipy.stats.f.cdf(t / kappa, nu_low, nu_high))
    excess = float(np.sum(low - s2 - q_low.mean(axis=0)) / np.sum(stated))
    if excess < MIN_EXCESS:
        p = 1.0  # a misfit too small for the sensors to see at their stated noise
    share = float(np.sum(q_low.mean(axis=0) / s2)) * mean / (c + np.sum(q_low.mean(axis=0) / s2))
    return t, mean, share, p, p_lower


def holm(p_values, alpha: float) -> np.ndarray:
    """Holm's step-down rejections of `p_values` at family-wise level `alpha`."""
    p = np.asarray(p_values, dtype=float)
    reject = np.zeros(p.size, dtype=bool)
    for rank, i in enumerate(np.argsort(p)):
        if not p[i] <= alpha / (p.size - rank):
            break
        reject[i] = True
    return reject


def _run_blocks(runs: RunChannels, k: int, x):
    """Run k's rows of x (m,) or (D, m) as (n_times, c) or (D, n_times, c)."""
    sl = runs.slices[k]
    x = np.asarray(x)[..., sl]
    return x.reshape(*x.shape[:-1], -1, runs.n_channels)


def goodness_of_fit(r, runs: RunChannels, rows, measurements, misfits, alpha: float):
    """The `GoodnessOfFit` of a fit's residuals `r` (m,) in the weights `rows` (m,) (module
    docstring): `runs` the rows' layout (present samples within the fit's window, active runs),
    `measurements` the runs (sample rates, channel groups), `misfits` (D, m) the track records'
    error draws (`TrackErrorEffect.misfits`) or `None`, `alpha` the family-wise rate."""
    tests, rates = [], []
    for k, m in enumerate(measurements):
        if not runs.active[k]:
            continue
        present = _run_blocks(runs, k, runs.mask)
        observed = band_powers(_run_blocks(runs, k, r), present, m.sample_rate)
        if observed is None:
            rates.append(m.sample_rate)
            continue
        low, high, n_low, n_high = observed
        draws = None
        if misfits is not None and len(misfits):
            d_low, d_high, _, _ = band_powers(_run_blocks(runs, k, misfits), present, m.sample_rate)
            draws = (d_low, d_high)
        stated = _run_blocks(runs, k, rows)[0] ** 2
        for group, idx in channel_groups(m):
            pick = list(idx)
            sub = None if draws is None else (draws[0][:, pick], draws[1][:, pick])
            t, mean, share, p, p_lower = group_test(
                (low[pick], high[pick]), sub, n_low, n_high, stated[pick]
            )
            channels = tuple(m.channels[j] for j in idx)
            tests.append(Misfit(k, group, channels, t, mean, share, t / mean, p, p_lower=p_lower))
    if not tests:
        note = (
            f"not tested: no run has {MIN_BINS} frequency bins in {LOW_BAND[0]:g}-{LOW_BAND[1]:g} "
            f"Hz and above {HIGH_BAND_START:g} Hz (records too short or sampled below "
            f"{2 * HIGH_BAND_START:g} Hz)"
        )
        return GoodnessOfFit((), alpha, note=note)
    reject = holm([t.p_value for t in tests], alpha)
    tests = [dataclasses.replace(t, rejected=bool(x)) for t, x in zip(tests, reject)]
    return GoodnessOfFit(tuple(tests), alpha)


def not_explained_warning(goodness) -> str:
    """The line that says where the fit does not explain the data; `""` where it does (or
    `goodness` is `None`)."""
    return not_explained_line(None if goodness is None else goodness.to_dict())


def not_explained_line(record) -> str:
    """`not_explained_warning` of a `GoodnessOfFit.to_dict()` record (`verdicts.json`)."""
    if not record or record.get("explained", True):
        return ""
    where = "; ".join(
        f"run {t['run']} {t['group']} (x{t['ratio']:.3g}, p = {t['p_value']:.2g})"
        for t in record["misfits"]
    )
    line = (
        "DATA NOT EXPLAINED: the fit leaves more low-frequency residual than the sensors' noise "
        f"and the track records' error allow in {where}; no alarm is raised that does not hold "
        "with the suspects free"
    )
    if record.get("suspects"):
        line += "; suspects (elements not judged): " + ", ".join(
            f"{s['name']} (score {s['statistic']:.3g})" for s in record["suspects"][:3]
        )
    return line


def group_excess(r, runs: RunChannels, measurements, tests) -> dict:
    """`{(run, group): T}` of residuals `r` for the run-groups of `tests` (their statistics
    recomputed without the track records' draws: for comparing residuals of one fit)."""
    out = {}
    for k, m in enumerate(measurements):
        wanted = {t.group for t in tests if t.run == k}
        if not wanted or not runs.active[k]:
            continue
        observed = band_powers(_run_blocks(runs, k, r), _run_blocks(runs, k, runs.mask),
                               m.sample_rate)  # fmt: skip
        if observed is None:
            continue
        for group, idx in channel_groups(m):
            if group in wanted:
                out[(k, group)] = float(np.sum(observed[0][list(idx)]))
    return out


def fit_goodness(space, fit, effect) -> GoodnessOfFit:
    """`goodness_of_fit` of `monitor`'s fit in its `FitSpace` `space`, with the track records'
    `TrackErrorEffect` `effect` (or `None`)."""
    p = space.program.problem
    alpha = p.options.false_alarm_rate
    if fit.status == "failed":
        return GoodnessOfFit((), alpha, note="not tested: the fit failed")
    misfits = None if effect is None or not effect.draws else effect.misfits
    return goodness_of_fit(fit.r, space.runs(), space.rows, p.measurements, misfits, alpha)
