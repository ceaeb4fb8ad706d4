"""`bogie-jax sensitivity`: screening, Sobol indices, Fisher information and profile likelihood
of the least-squares cost on synthetic data (paper sections 4.2 and 6.1).

Every input is checked before anything is simulated; each analysis writes DIR/results.json and
PNG figures, and reports its stages as `[k/n] ... (t = s)`.
"""

import json
from pathlib import Path

import jax.random as jr
import matplotlib.pyplot as plt
import numpy as np

from ..cost import select_parameters, synthetic_objective
from ..identify import fit
from ..params import manchester_benchmark
from ..plot import (
    plot_cost_surface,
    plot_fim_eigenvalues,
    plot_profiles,
    plot_sobol_indices,
    plot_sweeps,
)
from ..sensitivity import sensitivity_grid, sensor_layouts
from ._common import UsageError, split_names
from ._names import default_parameters, lookup, names as table_names
from ._track import TRACK_HELP, build_track, track_reference


def add_parser(subparsers):
    """Add the `sensitivity` sub-command to an argparse `subparsers`; returns its parser."""
    p = subparsers.add_parser(
        "sensitivity",
        help="sensitivity and identifiability of suspension parameters "
        "(screening, Sobol, FIM, profiles)",
        description="Synthetic measurement of the Manchester bogie, the least-squares cost (paper "
        "eq. 12) over the selected parameters, and one analysis: one-parameter sweeps and a "
        "two-parameter cost surface (screening), Sobol first-order and total indices (sobol), "
        "the Fisher information with collinearity indices (fim), or profile likelihoods with "
        "95 %% intervals (profile). Writes DIR/results.json and PNG figures.",
    )
    p.add_argument(
        "--method",
        default="fim",
        choices=table_names("analysis"),
        help="analysis to run (default fim)",
    )
    p.add_argument(
        "--params",
        default=",".join(default_parameters()),
        help="comma-separated parameter names (default: the default identification "
        f"scenario's, {','.join(default_parameters())})",
    )
    p.add_argument(
        "--out", default="sensitivity_out", help="output directory (default sensitivity_out)"
    )
    p.add_argument(
        "--n",
        type=int,
        default=256,
        help="Sobol base sample size, a power of two (n (d + 2) solves; default 256)",
    )
    p.add_argument(
        "--grid",
        type=int,
        default=11,
        help="points per parameter of sweeps, cost surface and profiles (default 11)",
    )
    p.add_argument(
        "--bounds",
        default="",
        help="NAME=LO:HI,... physical bounds (default: each parameter's plausible bounds)",
    )
    p.add_argument("--speed", type=float, default=50.0, help="forward speed [m/s] (default 50)")
    p.add_argument("--duration", type=float, default=2.0, help="simulated time [s] (default 2)")
    p.add_argument(
        "--sample-rate", type=float, default=100.0, help="sample rate [Hz] (default 100)"
    )
    p.add_argument(
        "--sensors",
        default="default",
        help=f"sensor layout: {' | '.join(table_names('sensors'))} (default default)",
    )
    p.add_argument("--track", default="erri-low", help=f"{TRACK_HELP} (default erri-low)")
    p.add_argument("--noise", action="store_true", help="add sensor noise to the synthetic data")
    p.add_argument("--chunk", type=int, default=None, help="vmap chunk size of the batch runner")
    p.add_argument("--seed", type=int, default=0, help="PRNG seed (track, noise, Sobol scrambling)")
    return p


def _parse_bounds(text: str, names) -> dict:
    bounds = {}
    for item in split_names(text):
        name, sep, rng = item.partition("=")
        lo_s, sep2, hi_s = rng.partition(":")
        if not sep or not sep2:
            raise UsageError(f"`--bounds` item {item!r} must read NAME=LO:HI")
        name = name.strip()
        if name not in names:
            raise UsageError(
                f"`--bounds` names `{name}`, which is not in `--params` ({', '.join(names)})"
            )
        try:
            lo, hi = float(lo_s), float(hi_s)
        except ValueError:
            raise UsageError(f"`--bounds` item {item!r}: LO and HI must be numbers") from None
        if not lo < hi:
            raise UsageError(
                f"bounds of `{name}` need lower < upper, got lower = {lo:g} >= upper = {hi:g}"
            )
        bounds[name] = (lo, hi)
    return bounds


def _check(args):
    """Every check that needs no evaluation; returns (params, names, bounds)."""
    if args.speed <= 0 or args.duration <= 0 or args.sample_rate <= 0:
        raise UsageError("`--speed`, `--duration` and `--sample-rate` must be > 0")
    if args.duration * args.sample_rate < 2:
        raise UsageError("`--duration` x `--sample-rate` must give at least 2 samples")
    lookup("sensors", args.sensors)
    if args.method == "sobol":
        if args.n < 2 or args.n & (args.n - 1):
            raise UsageError(
                f"`--n` must be a power of two >= 2 (the balance properties of a Sobol' design "
                f"hold only then), got {args.n}"
            )
    lo_grid = 3 if args.method == "profile" else 2
    if args.grid < lo_grid:
        raise UsageError(
            f"`--grid` must be >= {lo_grid} for --method {args.method}, got {args.grid}"
        )
    if args.chunk is not None and args.chunk < 1:
        raise UsageError(f"`--chunk` must be >= 1, got {args.chunk}")
    names = split_names(args.params)
    if args.method == "screening" and len(names) < 1:
        raise UsageError("`--params` must name at least one parameter")
    params = manchester_benchmark()
    try:
        select_parameters(params, names)  # unknown / repeated names, before anything compiles
    except ValueError as e:
        raise UsageError(str(e)) from None
    explicit = _parse_bounds(args.bounds, names)
    bounds = {n: explicit.get(n, "spec") for n in names}
    try:
        select_parameters(params, names, bounds=bounds)
    except ValueError as e:
        raise UsageError(str(e)) from None
    return params, names, bounds


class _Stages:
    """`[k/n] text (t = s)` lines: stage k of n done, `t` since the command began."""

    def __init__(self, progress, n_stages: int):
        self.progress, self.n, self.k = progress, n_stages, 0

    def __call__(self, text: str):
        self.k += 1
        self.progress.say(f"[{self.k}/{self.n}] {text} (t = {self.progress.elapsed():.1f} s)")

    def compiling(self, what: str):
        self.progress.compiling(what)


def run(args, progress) -> int:
    """Run `bogie-jax sensitivity`; returns the exit code (raises `UsageError` on bad input)."""
    params, names, bounds = _check(args)
    analyse = lookup("analysis", args.method, "--method")
    out = Path(args.out)
    stages = {"screening": 3, "sobol": 2, "fim": 2, "profile": 3}[args.method]
    stage = _Stages(progress, stages + 1)
    sensors = sensor_layouts(params)[args.sensors]
    reference = track_reference(
        args.track, params, seed=args.seed, speed=args.speed, duration=args.duration
    )
    track = build_track(reference)
    stage.compiling("the synthetic measurement")
    objective, _ = synthetic_objective(
        params,
        track,
        names,
        speed=args.speed,
        duration=args.duration,
        sample_rate=args.sample_rate,
        sensors=sensors,
        key=jr.PRNGKey(args.seed + 1) if args.noise else None,
        track_reference=reference,
        bounds=bounds,
    )
    stage(
        f"synthetic objective: {len(names)} parameters, {args.sensors} sensors "
        f"({len(sensors)} channels), {args.duration:g} s at {args.speed:g} m/s"
    )
    out.mkdir(parents=True, exist_ok=True)
    sel = objective.selection
    results = {
        "method": args.method,
        "names": list(sel.names),
        "units": list(sel.units),
        "nominal": np.asarray(sel.nominal).tolist(),
        "lower": np.asarray(sel.lower).tolist(),
        "upper": np.asarray(sel.upper).tolist(),
        "settings": {k: v for k, v in vars(args).items() if k != "func"},
    }
    figures = {}
    ANALYSES[args.method](args, objective, results, figures, stage, analyse)
    (out / "results.json").write_text(json.dumps(_jsonable(results), indent=1))
    for name, fig in figures.items():
        fig.savefig(out / name, dpi=110)
    plt.close("all")
    stage(f"wrote {out / 'results.json'} and {', '.join(figures) or 'no figures'}")
    return 0


def _jsonable(x):
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, float | np.floating):
        x = float(x)
        return x if np.isfinite(x) else str(x)  # JSON has no inf / nan
    if hasattr(x, "shape"):
        return _jsonable(np.asarray(x).tolist())
    return x


def _screening(args, objective, results, figures, progress, sweep):
    n_solves = len(objective.selection.names) * args.grid
    progress.compiling(f"the sweeps ({n_solves} solves)")
    sweeps = sweep(objective, n_points=args.grid, chunk_size=args.chunk)
    progress(
        f"sweeps: {len(sweeps.names)} x {args.grid} solves, {int(np.sum(sweeps.failed))} failed"
    )
    results["sweeps"] = {
        "names": list(sweeps.names),
        "values": sweeps.values,
        "cost": sweeps.outputs,
        "failed": sweeps.failed,
    }
    figures["sweeps.png"] = plot_sweeps(sweeps, all_names=objective.selection.names).figure
    names = objective.selection.names
    if len(names) >= 2:
        progress.compiling(f"the cost surface ({args.grid**2} solves)")
        grid = sensitivity_grid(
            objective, params=(names[0], names[1]), n_points=args.grid, chunk_size=args.chunk
        )
        progress(
            f"cost surface {names[0]} x {names[1]}: {args.grid**2} solves, "
            f"{int(np.sum(grid.failed))} failed"
        )
        results["grid"] = {
            "names": list(grid.names),
            "x": grid.x_values,
            "y": grid.y_values,
            "cost": grid.outputs,
            "failed": grid.failed,
        }
        figures["cost_surface.png"] = plot_cost_surface(grid)
    else:
        progress("cost surface skipped (needs two parameters)")


def _sobol(args, objective, results, figures, progress, sobol):
    d = len(objective.selection.names)
    progress.compiling(f"the Sobol sample ({args.n * (d + 2)} solves)")
    s = sobol(objective, n=args.n, key=jr.PRNGKey(args.seed + 2), chunk_size=args.chunk)
    progress(f"Sobol indices: {s.n_evaluations} solves, {int(s.n_failed)} failed")
    results["sobol"] = {
        "first_order": s.first_order,
        "total": s.total,
        "first_order_ci": s.first_order_ci,
        "total_ci": s.total_ci,
        "confidence": s.confidence,
        "n_evaluations": s.n_evaluations,
        "n_failed": int(s.n_failed),
    }
    figures["sobol.png"] = plot_sobol_indices(s).figure


def _fim_dict(f):
    return {
        "values": f.values,
        "fim": f.fim,
        "fim_relative": f.fim_relative,
        "eigenvalues": f.eigenvalues,
        "eigenvectors": f.eigenvectors,
        "covariance": f.covariance,
        "std_errors": f.std_errors,
        "relative_std_errors": f.relative_std_errors,
        "correlation": f.correlation,
        "condition_number": f.condition_number,
        "collinearity": [
            {"subset": list(k), "index": float(g)}
            for k, g in zip(f.collinearity.subsets, f.collinearity.index)
        ],
        "inseparable": f.summary(),
    }


def _fim(args, objective, results, figures, progress, fisher_information):
    progress.compiling("the residual Jacobian (forward mode)")
    f = fisher_information(objective)
    progress(
        f"Fisher information at the nominal parameters: condition {f.condition_number:.3g}; "
        + "; ".join(f.summary())
    )
    results["fim"] = _fim_dict(f)
    figures["fim_eigenvalues.png"] = plot_fim_eigenvalues(f).figure


def _profile(args, objective, results, figures, progress, profile_likelihood):
    if args.noise:
        progress.compiling("the LM fit")
        best = fit(objective, method="lm", throw=False)
        estimate = best.estimates
        progress(f"fit: cost {float(best.cost):.4g}, status {best.status_name}")
        results["fit"] = {
            "estimates": estimate,
            "cost": float(best.cost),
            "status": best.status_name,
        }
    else:
        estimate = np.asarray(objective.selection.nominal)
        progress("noise-free data: the true (nominal) parameters are the best fit")
    progress.compiling(f"the profiles ({len(objective.selection.names) * args.grid} fits)")
    prof = profile_likelihood(objective, estimate, n_points=args.grid, chunk_size=args.chunk)
    progress("profiles: " + ", ".join(f"{n} {s}" for n, s in zip(prof.names, prof.status)))
    results["profile"] = {
        "values": prof.values,
        "cost": prof.cost,
        "delta_cost": prof.delta_cost,
        "failed": prof.failed,
        "interval": prof.interval,
        "status": list(prof.status),
        "threshold": prof.threshold,
        "cost_min": prof.cost_min,
    }
    figures["profiles.png"] = plot_profiles(prof)


# the command's writer of each analysis (the analysis itself: `lookup("analysis", name)`)
ANALYSES = {"screening": _screening, "sobol": _sobol, "fim": _fim, "profile": _profile}
