"""What `bogie-jax identify` prints and writes: the parameter table, the results' records and
the figures."""

import matplotlib.pyplot as plt
import numpy as np

from ..cost import get_parameter
from ..params import parameter_specs
from ..plot import plot_estimates, plot_waterfall
from ._common import text_table


def list_params(params) -> str:
    """The table printed by `--list-params`: name, unit, nominal value, plausible bounds. Each
    suspension parameter appears as its tied group (`primary.kz`: all four axleboxes, one value)
    followed by its single elements (`primary.1L.kz`, ...)."""
    rows = [("parameter", "unit", "nominal", "lower", "upper", "description")]
    for name, spec in parameter_specs(params, elements=True).items():
        p0 = float(np.asarray(get_parameter(params, name)))
        rows.append(
            (
                name,
                spec.unit,
                f"{p0:.6g}",
                f"{spec.bounds[0]:.6g}",
                f"{spec.bounds[1]:.6g}",
                spec.doc,
            )
        )
    return text_table(rows)


def parameter_records(objective, result, truth):
    """`[{name, unit, true, nominal, estimate, ci95, std_error, on_bound}]` (JSON-ready)."""
    sel = objective.selection
    best = None if result is None else result.best
    out = []
    for i, (name, unit) in enumerate(zip(sel.names, sel.units)):
        est = None if best is None else float(best.estimates[i])
        ci = None if best is None else [float(v) for v in np.asarray(best.ci95[i])]
        out.append(
            dict(
                name=name,
                unit=unit,
                true=None if truth is None else float(truth[i]),
                nominal=float(sel.nominal[i]),
                lower=float(sel.lower[i]),
                upper=float(sel.upper[i]),
                estimate=est,
                ci95=ci,
                std_error=None if best is None else float(best.std_errors[i]),
                on_bound=None if best is None else bool(best.on_bound[i]),
            )
        )
    return out


def results_table(parameters) -> str:
    """Estimates against the true (or nominal) values, with 95 % intervals."""

    def f(x):
        return "-" if x is None else f"{x:.6g}"

    rows = [
        (
            "parameter",
            "true" if parameters and parameters[0]["true"] is not None else "nominal",
            "estimate",
            "95% interval",
            "unit",
        )
    ]
    for p in parameters:
        ref = p["true"] if p["true"] is not None else p["nominal"]
        ci = "-" if p["ci95"] is None else f"[{f(p['ci95'][0])}, {f(p['ci95'][1])}]"
        flag = " (on bound)" if p["on_bound"] else ""
        rows.append((p["name"], f(ref), f(p["estimate"]) + flag, ci, p["unit"]))
    return text_table(rows)


def write_plots(out, result, parameters):
    """`waterfall.png` and (if a start succeeded) `estimates.png` in `out`; returns the paths."""
    paths = []
    ax = plot_waterfall(result.costs, failed=result.failed)
    ax.figure.savefig(out / "waterfall.png", dpi=110)
    plt.close(ax.figure)
    paths.append(out / "waterfall.png")
    if result.best is not None:
        truth = None if parameters[0]["true"] is None else np.array([p["true"] for p in parameters])
        ax = plot_estimates(
            [p["name"] for p in parameters],
            np.array([p["estimate"] for p in parameters]),
            np.array([p["ci95"] for p in parameters]),
            truth=truth,
            nominal=np.array([p["nominal"] for p in parameters]),
        )
        ax.figure.savefig(out / "estimates.png", dpi=110)
        plt.close(ax.figure)
        paths.append(out / "estimates.png")
    return paths
