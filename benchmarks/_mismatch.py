"""Model-mismatch modes of the detection benchmark (issue 51, item 1): data that the monitor's
model does not fully explain, judged through the public path (`monitor(measurements,
tracks=..., params=..., options=...)`), and the report of how honestly it says so.

**Modes** (`--imperfection`, each alone or with the others of `detection.py`; each value drawn
per case from the case's own generator, after `detection.py`'s draws, whether the mode is on or
not, so a case is the same whatever the shard, worker, order or mode):
- `real-profile` (g): the data from the S1002 wheel on UIC60 rail inclined 1:40 (the Manchester
  Contact Benchmark pair, `manchester_benchmark(contact="s1002-uic60")`: its contact table,
  equivalent conicity 0.37 at 1 mm and 0.19 at 3 mm amplitude), the fit on the default 1:20 cone
  (`manchester_benchmark()`);
- `worn-profile` (h): the data from the measured worn wheel on the same rail (`"worn-uic60"`),
  the fit on the new-profile model (`"s1002-uic60"`) as the monitor's nominal `params`;
  `half-worn-profile`: the same with the data from the wheel halfway between the new and the
  worn profile (`"half-worn-uic60"`), which the blend of the two wheels' tables that the
  wear nuisance spans (`detection.py --fit-wear`) does not hold;
- `track-white` (i): the fit's track record carries an error that is white within the recording
  band `RECORD_BAND` (3-70 m wavelengths, the band of the synthesised tracks: EN 13848-1's D1
  and D2 ranges) instead of one shaped like the track: a `FlatSpectrum` synthesis over that
  band, fading in and out with the track (`TRACK_FADE`), scaled per run to RMS r in alignment
  and vertical level and r / (2 b_0) in cross level (the convention of `recorded_track`), r drawn
  uniformly in `WHITE_RMS` (0.1-0.3 mm) per case;
- `track-drift` (i): a long-wave drift: the same white synthesis over `DRIFT_BAND` (70-200 m,
  EN 13848-1's D3 range: 70-150 m in level, 70-200 m in alignment), fading in over `DRIFT_FADE`
  (35 m, half the band's shortest wavelength, so the fade adds little at recording-band
  wavelengths), RMS uniform in `DRIFT_RMS` (0.3-1 mm: up to about 40 % of the ERRI-low
  spectrum's own RMS over that band, 1.9 mm in alignment and 2.6 mm in level by
  `band_variance`). `detection.py --drift-band LO,HI` draws the drift over another band: the
  monitor's own long-wave term assumes D3 (`bogie_jax.monitor.LONG_BAND`), so a band unlike
  it tests that term on a drift it does not assume. In both track modes the monitor is told
  only the error's RMS
  (`MonitorOptions(track_error=...)`; with `--track-error` or both modes, the root sum of
  squares of the RMS values), and the record has no other error or offset unless `track` is on;
- `unjudged-defect` (j): a defect in an element outside the candidate list: the element drawn
  uniformly from `unjudged_elements()` (every element of `bogie_jax.params.element_names` that
  is not in `bogie_jax.monitor.DEFAULT_CANDIDATES`, less the anti-yaw dampers' blow-off
  parameters, which the linear model the data come from does not use: primary longitudinal
  stiffness, primary longitudinal and lateral damping, secondary longitudinal, lateral and
  vertical stiffness and vertical damping; 20 elements), a damper at a factor uniform in
  [`FAILED_FLOOR`, 0.25] of nominal (failed), a spring at a factor log-uniform in [0.5, 2];
  with probability `WITH_CANDIDATE` (1/2) together with the case's candidate defect
  (`detection.py`'s scenario draw), else alone; every third case stays healthy (no defect at
  all). Each defective case records how much the unjudged defect changes the signals: the
  same runs simulated without it, the difference's RMS per channel (both runs) over that
  channel's noise standard deviation, its maximum over the channels and per channel group
  (`bogie_jax.monitor.channel_groups`).

- `nonlinear-laws` (d'): with `nonlinear` on, the nonlinear laws of the data unlike the
  monitor's nonlinear model (`MonitorOptions.refit_model` at the nominal parameters): the wheel-
  rail friction coefficient `contact.friction` at nominal (0.3) times a factor uniform in
  `FRICTION_FACTOR` (0.5-1.5: 0.15-0.45, wet to dry rail), the anti-yaw dampers' relief
  velocity `yaw_dampers.blowoff_velocity` and their damping above it `yaw_dampers.c_blowoff`
  at nominal times factors log-uniform in `BLOWOFF_FACTOR` (0.6-1.6) and `C_BLOWOFF_FACTOR`
  (0.5-2), the same on both sides.

`_mismatch_report.report` adds issue 51's figures to `detection.py`'s tables.
"""

import math

import jax.random as jr
import numpy as np

from bogie_jax.contact import PROFILE_PAIRS
from bogie_jax.monitor import (
    DEFAULT_CANDIDATES,
    DEFECT_SCENARIOS,
    FAILED_FLOOR,
    channel_groups,
    channel_rms,
    worn_wheels,
)
from bogie_jax.params import element_names, get_parameter, manchester_benchmark, set_parameters
from bogie_jax.track import FlatSpectrum, synthesise_track


MODES = (
    "real-profile", "worn-profile", "half-worn-profile", "track-white", "track-drift",
    "unjudged-defect", "nonlinear-laws",
)  # fmt: skip
WHEELS = ("worn-wheels", "real-profile", "worn-profile", "half-worn-profile")  # one at most
RECORD_BAND = (3.0, 70.0)  # [m] wavelengths of the white record error
WHITE_RMS = (0.1e-3, 0.3e-3)  # [m]
TRACK_FADE = 20.0  # [m] the synthesised track's own fade (`synthesise_track`'s default)
DRIFT_BAND = (70.0, 200.0)  # [m]
DRIFT_RMS = (0.3e-3, 1.0e-3)  # [m]
DRIFT_FADE = 35.0  # [m]
DAMPER_FACTOR = (FAILED_FLOOR, 0.25)  # uniform
FRICTION_FACTOR = (0.5, 1.5)  # uniform
BLOWOFF_FACTOR = (0.6, 1.6)  # log-uniform
C_BLOWOFF_FACTOR = (0.5, 2.0)  # log-uniform
SPRING_FACTOR = (0.5, 2.0)  # log-uniform
WITH_CANDIDATE = 0.5
BLOW_OFF = ("blowoff_velocity", "c_blowoff")  # parameters of the nonlinear damper law
NONLINEAR_LAWS = {  # the truth's parameter: the case's factor on it
    "contact.friction": "friction_factor",
    "yaw_dampers.blowoff_velocity": "blowoff_velocity_factor",
    "yaw_dampers.c_blowoff": "c_blowoff_factor",
}
CONTACTS = {  # mode: (contact of the data, contact of the fit)
    "real-profile": ("s1002-uic60", "cone"),
    "worn-profile": ("worn-uic60", "s1002-uic60"),
    "half-worn-profile": ("half-worn-uic60", "s1002-uic60"),
}
CONTACT_NAMES = ("cone", *PROFILE_PAIRS)  # `manchester_benchmark(contact=...)`


def unjudged_elements() -> tuple[str, ...]:
    """The suspension elements of the model that `monitor` does not judge by default (module
    docstring), in `element_names` order."""
    names = element_names(manchester_benchmark())
    return tuple(
        n for n in names if n not in DEFAULT_CANDIDATES and n.rsplit(".", 1)[-1] not in BLOW_OFF
    )


def check_modes(imperfections) -> None:
    """`SystemExit` where two modes that set the true wheels are on together, or
    `nonlinear-laws` without `nonlinear`."""
    wheels = [n for n in imperfections if n in WHEELS]
    if len(wheels) > 1:
        raise SystemExit(f"--imperfection: {' and '.join(wheels)} both set the true wheels")
    if "nonlinear-laws" in imperfections and "nonlinear" not in imperfections:
        raise SystemExit("--imperfection: nonlinear-laws needs nonlinear (its data's model)")


def config(imperfections, drift_band=None) -> dict:
    """The mismatch modes' settings for `detection.config_of` (empty without a mode on, so the
    configurations of the other modes keep their hash); `drift_band` [m] replaces
    `DRIFT_BAND`."""
    if not set(imperfections) & set(MODES):
        return {}
    return {
        "mismatch": {
            "record_band_m": list(RECORD_BAND), "white_rms_m": list(WHITE_RMS),
            "drift_band_m": list(drift_band or DRIFT_BAND), "drift_rms_m": list(DRIFT_RMS),
            "drift_fade_m": DRIFT_FADE, "damper_factor": list(DAMPER_FACTOR),
            "spring_factor": list(SPRING_FACTOR), "with_candidate": WITH_CANDIDATE,
            "unjudged_elements": list(unjudged_elements()),
            **({"nonlinear_laws": {
                "friction_factor": list(FRICTION_FACTOR),
                "blowoff_velocity_factor": list(BLOWOFF_FACTOR),
                "c_blowoff_factor": list(C_BLOWOFF_FACTOR),
            }} if "nonlinear-laws" in imperfections else {}),
        }
    }  # fmt: skip


def draw(rng) -> dict:
    """The mismatch draws of a case from its generator `rng` (module docstring): a fixed
    sequence, whatever the mode."""
    names = unjudged_elements()
    element = names[int(rng.integers(len(names)))]
    u = float(rng.uniform())
    if element.rsplit(".", 1)[-1].startswith("c"):  # a damper (cx, cy, cz); else a spring
        factor = DAMPER_FACTOR[0] + u * (DAMPER_FACTOR[1] - DAMPER_FACTOR[0])
    else:
        lo, hi = np.log(SPRING_FACTOR)
        factor = float(np.exp(lo + u * (hi - lo)))
    return {
        "unjudged_element": element,
        "unjudged_factor": factor,
        "with_candidate": bool(rng.uniform() < WITH_CANDIDATE),
        "white_rms_m": float(rng.uniform(*WHITE_RMS)),
        "white_seeds": rng.integers(0, 2**31 - 1, 2).tolist(),
        "drift_rms_m": float(rng.uniform(*DRIFT_RMS)),
        "drift_seeds": rng.integers(0, 2**31 - 1, 2).tolist(),
        "friction_factor": float(rng.uniform(*FRICTION_FACTOR)),
        "blowoff_velocity_factor": float(np.exp(rng.uniform(*np.log(BLOWOFF_FACTOR)))),
        "c_blowoff_factor": float(np.exp(rng.uniform(*np.log(C_BLOWOFF_FACTOR)))),
    }


def bogies(on, case: dict, *, fit_contact: str | None = None, fit_wear=None) -> dict:
    """The bogies of a case (`detection.draw_case`'s `case`): `nominal` (the fit's `params`,
    on `fit_contact` where given, else on the mode's contact of the fit, `CONTACTS`, with the
    wheel wear `fit_wear` that `monitor` fits from there, `None`: none),
    `truth`, `without_unjudged` (the truth without the unjudged defect, `None` without one),
    the candidate `scenario` (`DefectScenario`), `changed` element names, the case's `label` for
    the tables and its `mismatch` record (what applies)."""
    truth_contact, mode_fit = next((CONTACTS[m] for m in CONTACTS if m in on), ("cone",) * 2)
    fit_contact = fit_contact or mode_fit
    nominal = manchester_benchmark(contact=fit_contact, wear=fit_wear)
    base = manchester_benchmark(contact=truth_contact)
    if "worn-wheels" in on:
        base = worn_wheels(base, case["cone_slope_factor"])
    laws = {}
    if "nonlinear-laws" in on:
        laws = {name: float(np.asarray(get_parameter(base, name))) * case[key]
                for name, key in NONLINEAR_LAWS.items()}  # fmt: skip
        base = set_parameters(base, laws)
    scenario, label = DEFECT_SCENARIOS[case["scenario"]], case["scenario"]
    unjudged = "unjudged-defect" in on and case["scenario"] != "healthy"
    if unjudged and not case["with_candidate"]:
        scenario = DEFECT_SCENARIOS["healthy"]
    truth = scenario.true_params(base)
    record = {"contact_truth": truth_contact, "contact_fit": fit_contact, "fit_wear": fit_wear}
    if laws:
        record["nonlinear_laws"] = laws
    without = None
    if unjudged:
        name, factor = case["unjudged_element"], case["unjudged_factor"]
        nominal_value = float(np.asarray(get_parameter(base, name)))
        without, truth = truth, set_parameters(truth, {name: nominal_value * factor})
        label = "unjudged" + (f" + {scenario.name}" if scenario.elements else " alone")
        record["unjudged"] = {
            "element": name, "factor": factor, "true": nominal_value * factor,
            "nominal": nominal_value, "with_candidate": bool(scenario.elements),
        }  # fmt: skip
    changed = list(scenario.elements) + ([case["unjudged_element"]] if unjudged else [])
    return dict(
        nominal=nominal, truth=truth, without_unjudged=without, scenario=scenario,
        changed=changed, label=label, mismatch=record,
    )  # fmt: skip


def band_error(ref, band, rms: float, semi_distance: float, seed: int, fade: float):
    """`(n, 3)` white error over the wavelength `band` [m] on the samples of the track `ref`
    (`TrackReference`), scaled to RMS `rms` [m] in alignment and level, `rms / (2
    semi_distance)` [rad] in cross level (module docstring)."""
    target = np.array([rms, rms, rms / (2.0 * semi_distance)])
    psd = FlatSpectrum.with_rms(*target, wavelength_band=band)
    error = np.asarray(
        synthesise_track(
            psd,
            key=jr.PRNGKey(int(seed)),
            length=ref.length,
            wavelength_band=band,
            fade_length=fade,
        ).values
    )
    return error * (target / np.sqrt(np.mean(error**2, axis=0)))


def record_errors(on, refs, case: dict, semi_distance: float, drift_band=DRIFT_BAND):
    """(the extra error `(n, 3)` of each run's record or `None`, the RMS [m] the monitor is told
    of it, its record entries) for the track modes that are on, the drift over `drift_band`
    [m]."""
    parts = []
    if "track-white" in on:
        parts.append(("white", RECORD_BAND, TRACK_FADE))
    if "track-drift" in on:
        parts.append(("drift", tuple(drift_band), DRIFT_FADE))
    if not parts:
        return None, 0.0, {}
    errors = [0.0] * len(refs)
    for kind, band, fade in parts:
        rms, seeds = case[f"{kind}_rms_m"], case[f"{kind}_seeds"]
        for k, ref in enumerate(refs):
            errors[k] = errors[k] + band_error(ref, band, rms, semi_distance, seeds[k], fade)
    told = math.sqrt(sum(case[f"{kind}_rms_m"] ** 2 for kind, *_ in parts))
    entries = {f"track_{kind}_rms_m": case[f"{kind}_rms_m"] for kind, *_ in parts}
    return errors, told, entries


def signal_change(clean, without, noise_fraction: float) -> dict:
    """How much a defect changes the signals relative to the noise: per channel the RMS over
    all runs of `clean - without` (the runs with and without it) over the channel's noise
    standard deviation (`noise_fraction` times its RMS over `clean`, as `with_channel_noise`);
    its maximum over the channels (`max`) and per channel group (`by_group`)."""
    std = noise_fraction * channel_rms(clean)
    diff = np.concatenate(
        [np.asarray(a.data, dtype=float) - np.asarray(b.data, dtype=float)
         for a, b in zip(clean, without)]
    )  # fmt: skip
    ratio = np.sqrt(np.nanmean(diff**2, axis=0)) / std
    groups = channel_groups(clean[0])
    return {
        "max": float(np.max(ratio)),
        "by_group": {g: float(np.max(ratio[list(idx)])) for g, idx in groups},
        "by_channel": dict(zip(clean[0].channels, ratio.tolist())),
    }
