"""`bogie-jax demo`: the README's main job, a run of the default bogie plus its critical speed."""

import argparse
from pathlib import Path

from . import critical_speed, simulate


def add_parser(sub):
    p = sub.add_parser("demo", help="simulate the default bogie and write data and plots")
    p.add_argument("--out", default="demo_out", help="output directory (default demo_out)")
    return p


def run(args, progress) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    sim = argparse.Namespace(
        params="manchester",
        speed=50.0,
        duration=5.0,
        track="erri-low",
        seed=0,
        sample_rate=200.0,
        out=str(out / "simulation.npz"),
        plot=str(out / "simulation.png"),
    )
    simulate.run(sim, progress)
    crit = argparse.Namespace(
        params="manchester", v_min=5.0, v_max=150.0, plot=str(out / "stability.png")
    )
    return critical_speed.run(crit, progress)
