"""What `bogie-jax demo` and `bogie-jax monitor` share: the model's signals at the estimate,
the verdict table, and the output directory (`verdicts.json`, figures, `report.md`)."""

from pathlib import Path

import numpy as np

from ..cost import window_lead_in
from ..io import verdicts_record, write_report, write_verdicts
from ..measure import sensors_from_layout, synthetic_measurement
from ..monitor import WATCH_NOTE, misfit_warning, not_explained_warning, verdict_label
from ..params import ModelOptions, get_parameter, set_parameters
from ._common import text_table


SIGNAL_CHANNELS = 4  # channels shown in the measured-against-fitted figure


def fitted_params(result, params):
    """The bogie at the estimate: every judged element or group at its estimate (a group's
    members by one factor, as `monitor` fits them), the nuisance parameters at theirs, the
    others nominal."""
    nuisance = result.fit.nuisance.items()
    values = {name: n["estimate"] for name, n in nuisance if np.isfinite(n["estimate"])}
    for v in result.verdicts:
        members = v.evidence.get("members") or []
        if v.evidence.get("identifiable") == "no" or not np.isfinite(v.std_error) or not members:
            continue
        nominal = {m: float(np.asarray(get_parameter(params, m))) for m in members}
        factor = v.estimate / float(np.mean(list(nominal.values())))
        values.update({m: p * factor for m, p in nominal.items()})
    return set_parameters(params, values) if values else params


def fitted_signals(result, measurements, tracks, params, progress, *, equations=ModelOptions()):
    """The model's readings (n, c) per run at the estimate, on the tracks used in the fit
    (simulated by `synthetic_measurement` with the fitted `equations`, without noise;
    the lead-in as `make_objective`'s)."""
    at = fitted_params(result, params)
    out = []
    for k, (m, track) in enumerate(zip(measurements, tracks)):
        times = np.asarray(m.times, dtype=float)
        rate = float(m.sample_rate)
        speed, start = float(np.asarray(m.speed)), float(np.asarray(m.start_position))
        if k == 0:
            progress.compiling("the simulation at the estimate (reused if already compiled)")
            progress.start_work()
        model = synthetic_measurement(
            at,
            track,
            speed=speed,
            duration=(times.size - 1) / rate,
            sample_rate=rate,
            start_position=start,
            lead_in=window_lead_in(None, params, speed, start),
            sensors=sensors_from_layout(m.layout) if m.layout else None,
            options=equations,
        )
        by_name = dict(zip(model.channels, np.asarray(model.data).T))
        out.append(np.stack([by_name[c] for c in m.channels], axis=1))
        progress.done(k + 1, len(measurements), "fitted runs")
    return out


def verdict_table(result) -> str:
    """The verdicts as an aligned text table."""
    rows = [("element", "verdict", "estimate", "95 % interval", "healthy band", "unit")]
    for v in result.verdicts:
        lo, hi = v.band.healthy
        known = np.isfinite(v.std_error) and v.evidence.get("identifiable") != "no"
        rows.append(
            (
                v.name,
                verdict_label(v.verdict, v.watch),
                f"{v.estimate:.4g}" if known else "-",
                f"[{v.ci95[0]:.4g}, {v.ci95[1]:.4g}]" if known else "-",
                f"[{lo:.4g}, {hi:.4g}]",
                v.band.unit,
            )
        )
    notes = [WATCH_NOTE] if result.watches else []
    warning = misfit_warning(result.fit.misfit_ratio)
    notes += [warning] if warning else []
    if not result.explained:
        notes.append(not_explained_warning(result.goodness))
    return "\n".join([text_table(rows), *notes])


def _signal_channels(measurements, n: int) -> list[int]:
    """Up to `n` channels of different kinds (first the first channel of each body and
    direction, e.g. `frame_*_y`, `frame_*_z`, `frame_yaw_rate`, `axlebox_*_y`), then the rest."""
    names = measurements[0].channels
    first = {}
    for j, c in enumerate(names):
        parts = c.split("_")
        first.setdefault((parts[0], parts[-1]), j)
    picked = list(first.values())[:n]
    picked += [j for j in range(len(names)) if j not in picked][: n - len(picked)]
    return sorted(picked)


def _figure_signals(path, measurements, fitted):
    import matplotlib.pyplot as plt

    from ..plot import plot_signal_fit

    channels = _signal_channels(measurements, SIGNAL_CHANNELS)
    runs = len(measurements)
    fig, axes = plt.subplots(
        len(channels), runs, figsize=(5.2 * runs, 2.2 * len(channels) + 0.6), squeeze=False,
        layout="constrained",
    )  # fmt: skip
    for k, (m, f) in enumerate(zip(measurements, fitted)):
        data, times = np.asarray(m.data, dtype=float), np.asarray(m.times, dtype=float)
        for row, j in enumerate(channels):
            plot_signal_fit(
                times, data[:, j], f[:, j], name=m.channels[j], unit=m.units[j],
                ax=axes[row, k], title=f"run {k} ({float(np.asarray(m.speed)):g} m/s): "
                f"{m.channels[j]}",
            )  # fmt: skip
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _figure_verdicts(path, result):
    import matplotlib.pyplot as plt

    from ..plot import plot_verdicts

    ax = plot_verdicts(result.verdicts)
    ax.figure.savefig(path, dpi=110)
    plt.close(ax.figure)


def write_outputs(out, result, measurements, fitted, *, date, source, notes, extra, progress):
    """Write `verdicts.json`, `verdicts.png`, `signals.png` (when `fitted` is given) and
    `report.md` to `out`; returns the paths."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    verdicts = write_verdicts(out, result, date=date, source=source, **extra)
    record = verdicts_record(result, date=date, source=source, **extra)
    figures = [("every element's estimate and 95 % interval against its band", "verdicts.png")]
    _figure_verdicts(out / "verdicts.png", result)
    if fitted is not None:
        _figure_signals(out / "signals.png", measurements, fitted)
        figures.append(("measured against fitted signals (a few channels per run)", "signals.png"))
    timing = {
        "total": progress.elapsed(),
        "first residual Jacobian (compile)": result.timings.get("first_jacobian_s"),
        "fit": result.timings.get("fit_s"),
    }
    report = write_report(
        out / "report.md",
        record,
        figures=figures,
        notes=notes,
        timing={k: v for k, v in timing.items() if v is not None},
    )
    return [verdicts, *(out / f for _, f in figures), report]
