"""`bogie-jax sensitivity`: screening, Sobol indices, Fisher information and profile likelihood
of the least-squares cost on synthetic data (paper sections 4.2 and 6.1).

Registered in `bogie_jax.cli` by `add_parser(subparsers)` and `run(args)`. Heavy imports (JAX,
matplotlib) happen inside `run`, after every input is checked.
"""

import time


METHODS = ("screening", "sobol", "fim", "profile")


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
    p.add_argument("--method", required=True, choices=METHODS, help="analysis to run")
    p.add_argument(
        "--params",
        required=True,
        help="comma-separated parameter names (e.g. primary.kz,yaw_dampers.c)",
    )
    p.add_argument("--out", required=True, help="output directory")
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
        help="sensor layout: default | displacement | frame-acc | frame+axlebox-acc",
    )
    p.add_argument(
        "--track", default="erri-low", help="erri-low | erri-high | fra-1..fra-6 (default erri-low)"
    )
    p.add_argument("--noise", action="store_true", help="add sensor noise to the synthetic data")
    p.add_argument("--chunk", type=int, default=None, help="vmap chunk size of the batch runner")
    p.add_argument("--seed", type=int, default=0, help="PRNG seed (track, noise, Sobol scrambling)")
    return p


def _split(text: str) -> list[str]:
    return [t.strip() for t in text.split(",") if t.strip()]


def _parse_bounds(text: str, names) -> dict:
    from .cli import UsageError

    bounds = {}
    for item in _split(text):
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
    from .cli import UsageError
    from .cost import select_parameters
    from .params import manchester_benchmark
    from .sensitivity import LAYOUTS
    from .sensitivity._validation import check_power_of_two

    if args.speed <= 0 or args.duration <= 0 or args.sample_rate <= 0:
        raise UsageError("`--speed`, `--duration` and `--sample-rate` must be > 0")
    if args.duration * args.sample_rate < 2:
        raise UsageError("`--duration` x `--sample-rate` must give at least 2 samples")
    if args.sensors not in LAYOUTS:
        raise UsageError(f"`--sensors` must be one of {', '.join(LAYOUTS)}, got {args.sensors!r}")
    if args.method == "sobol":
        try:
            check_power_of_two("--n", args.n)
        except (TypeError, ValueError) as e:
            raise UsageError(str(e)) from None
    lo_grid = 3 if args.method == "profile" else 2
    if args.grid < lo_grid:
        raise UsageError(
            f"`--grid` must be >= {lo_grid} for --method {args.method}, got {args.grid}"
        )
    if args.chunk is not None and args.chunk < 1:
        raise UsageError(f"`--chunk` must be >= 1, got {args.chunk}")
    names = _split(args.params)
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


class _Progress:
    def __init__(self, n_stages: int):
        self.n, self.k, self.t0 = n_stages, 0, time.perf_counter()

    def __call__(self, text: str):
        self.k += 1
        print(f"[{self.k}/{self.n}] {text} (t = {time.perf_counter() - self.t0:.1f} s)", flush=True)


def run(args) -> int:
    """Run `bogie-jax sensitivity`; returns the exit code (raises `UsageError` on bad input)."""
    import json
    from pathlib import Path

    params, names, bounds = _check(args)

    import jax.random as jr
    import matplotlib
    import numpy as np

    matplotlib.use("Agg")
    from . import _plot_sensitivity as plots
    from ._tracks import run_track
    from .cli import UsageError
    from .cost import synthetic_objective
    from .sensitivity import sensor_layouts

    out = Path(args.out)
    stages = {"screening": 3, "sobol": 2, "fim": 2, "profile": 3}[args.method]
    progress = _Progress(stages + 1)
    sensors = sensor_layouts(params)[args.sensors]
    try:
        track = run_track(
            args.track, params, seed=args.seed, speed=args.speed, duration=args.duration
        )
    except ValueError as e:
        raise UsageError(str(e)) from None
    objective, _ = synthetic_objective(
        params,
        track,
        names,
        speed=args.speed,
        duration=args.duration,
        sample_rate=args.sample_rate,
        sensors=sensors,
        key=jr.PRNGKey(args.seed + 1) if args.noise else None,
        track_name=f"{args.track} seed={args.seed}",
        bounds=bounds,
    )
    progress(
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
    ANALYSES[args.method](args, objective, results, figures, progress, plots)
    (out / "results.json").write_text(json.dumps(_jsonable(results), indent=1))
    for name, fig in figures.items():
        fig.savefig(out / name, dpi=110)
    import matplotlib.pyplot as plt

    plt.close("all")
    progress(f"wrote {out / 'results.json'} and {', '.join(figures) or 'no figures'}")
    return 0


def _jsonable(x):
    import numpy as np

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


def _screening(args, objective, results, figures, progress, plots):
    import numpy as np

    from .sensitivity import sensitivity_grid, sensitivity_sweeps

    sweeps = sensitivity_sweeps(objective, n_points=args.grid, chunk_size=args.chunk)
    progress(
        f"sweeps: {len(sweeps.names)} x {args.grid} solves, {int(np.sum(sweeps.failed))} failed"
    )
    results["sweeps"] = {
        "names": list(sweeps.names),
        "values": sweeps.values,
        "cost": sweeps.outputs,
        "failed": sweeps.failed,
    }
    figures["sweeps.png"] = plots.plot_sweeps(sweeps, all_names=objective.selection.names).figure
    names = objective.selection.names
    if len(names) >= 2:
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
        figures["cost_surface.png"] = plots.plot_cost_surface(grid)
    else:
        progress("cost surface skipped (needs two parameters)")


def _sobol(args, objective, results, figures, progress, plots):
    import jax.random as jr

    from .sensitivity import sensitivity_sobol

    s = sensitivity_sobol(objective, n=args.n, key=jr.PRNGKey(args.seed + 2), chunk_size=args.chunk)
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
    figures["sobol.png"] = plots.plot_sobol_indices(s).figure


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


def _fim(args, objective, results, figures, progress, plots):
    from .sensitivity import fisher_information

    f = fisher_information(objective)
    progress(
        f"Fisher information at the nominal parameters: condition {f.condition_number:.3g}; "
        + "; ".join(f.summary())
    )
    results["fim"] = _fim_dict(f)
    figures["fim_eigenvalues.png"] = plots.plot_fim_eigenvalues(f).figure


def _profile(args, objective, results, figures, progress, plots):
    import diffrax as dfx
    import numpy as np

    from .identify import fit
    from .sensitivity import profile_likelihood

    if args.noise:
        best = fit(objective.with_adjoint(dfx.ForwardMode()), method="lm", throw=False)
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
    figures["profiles.png"] = plots.plot_profiles(prof)


ANALYSES = {"screening": _screening, "sobol": _sobol, "fim": _fim, "profile": _profile}
