"""`bogie-jax sensitivity` in-process, with tiny settings (argparse + `add_parser`)."""

import argparse
import json

import numpy as np
import pytest

import bogie_jax.cli.sensitivity as command
from bogie_jax.cli import Progress, UsageError
from bogie_jax.cli.sensitivity import add_parser


def parse(argv):
    parser = argparse.ArgumentParser(prog="bogie-jax")
    add_parser(parser.add_subparsers(dest="command", required=True))
    return parser.parse_args(["sensitivity", *argv])


def run(args):
    return command.run(args, Progress())


TINY = ["--speed", "50", "--duration", "0.2", "--sample-rate", "50", "--sensors", "frame-acc"]


@pytest.mark.parametrize(
    "argv, match",
    [
        (
            ["--method", "sobol", "--params", "primary.kz,primary.kq"],
            "unknown parameter 'primary.kq'",
        ),
        (["--method", "sobol", "--params", "primary.kz", "--n", "100"], "power of two"),
        (
            ["--method", "screening", "--params", "primary.kz", "--bounds", "primary.kz=2e6:1e6"],
            "lower < upper",
        ),
        (
            ["--method", "screening", "--params", "primary.kz", "--bounds", "primary.ky=1e6:2e6"],
            "not in `--params`",
        ),
        (["--method", "fim", "--params", "primary.kz", "--sensors", "nope"], "--sensors"),
        (["--method", "profile", "--params", "primary.kz", "--grid", "2"], "--grid"),
    ],
)
def test_bad_input_is_a_usage_error_before_evaluation(argv, match, tmp_path, monkeypatch):
    def fail(*a, **k):
        pytest.fail("evaluated although the input was invalid")

    monkeypatch.setattr(command, "synthetic_objective", fail)
    with pytest.raises(UsageError, match=match) as e:
        run(parse([*argv, "--out", str(tmp_path)]))
    assert "\n" not in str(e.value)
    assert not (tmp_path / "results.json").exists()


@pytest.mark.slow
@pytest.mark.heavy  # 3-6 min of compile on 2 cores: see README, Tests
def test_sobol_and_fim_write_results_and_pngs(tmp_path, capsys):
    out = tmp_path / "sobol"
    assert (
        run(
            parse(
                [
                    "--method",
                    "sobol",
                    "--params",
                    "primary.kz,yaw_dampers.c",
                    "--n",
                    "4",
                    "--out",
                    str(out),
                    *TINY,
                ]
            )
        )
        == 0
    )
    res = json.loads((out / "results.json").read_text())
    assert res["names"] == ["primary.kz", "yaw_dampers.c"]
    assert len(res["sobol"]["total"]) == 2 and res["sobol"]["n_evaluations"] == 16
    assert (out / "sobol.png").stat().st_size > 0
    assert "[1/3]" in capsys.readouterr().out

    out = tmp_path / "fim"
    assert (
        run(
            parse(
                [
                    "--method",
                    "fim",
                    "--params",
                    "primary.kz,yaw_dampers.c",
                    "--out",
                    str(out),
                    *TINY,
                ]
            )
        )
        == 0
    )
    res = json.loads((out / "results.json").read_text())
    assert len(res["fim"]["eigenvalues"]) == 2
    assert all(isinstance(v, float) for v in res["fim"]["eigenvalues"])
    assert (out / "fim_eigenvalues.png").stat().st_size > 0


@pytest.mark.slow
@pytest.mark.heavy  # 3-6 min of compile on 2 cores: see README, Tests
def test_screening_and_profile_write_results_and_pngs(tmp_path, capsys):
    names = ["primary.kz", "yaw_dampers.c"]
    out = tmp_path / "screening"
    argv = ["--method", "screening", "--params", ",".join(names), "--grid", "3"]
    assert run(parse([*argv, "--out", str(out), *TINY])) == 0
    res = json.loads((out / "results.json").read_text())
    sweeps, grid = res["sweeps"], res["grid"]
    assert sweeps["names"] == names and np.shape(sweeps["cost"]) == (2, 3)
    assert np.shape(grid["cost"]) == (3, 3) and not np.any(grid["failed"])
    # a sum of squares
    assert np.all(np.asarray(sweeps["cost"]) >= 0) and np.all(np.asarray(grid["cost"]) >= 0)
    for png in ("sweeps.png", "cost_surface.png"):
        assert (out / png).stat().st_size > 1000
    assert "[1/4]" in capsys.readouterr().out

    out = tmp_path / "profile"
    argv = ["--method", "profile", "--params", ",".join(names), "--grid", "3"]
    assert run(parse([*argv, "--out", str(out), *TINY])) == 0
    res = json.loads((out / "results.json").read_text())
    prof = res["profile"]
    assert np.shape(prof["values"]) == (2, 3) and np.shape(prof["interval"]) == (2, 2)
    # noise-free: the profile's minimum is the nominal point, every other grid point costs more
    nominal = np.asarray(res["nominal"])
    for delta, (lo, hi), x0 in zip(prof["delta_cost"], prof["interval"], nominal):
        assert np.all(np.asarray(delta, float) >= -1e-9)
        assert float(lo) <= x0 <= float(hi)
    assert (out / "profiles.png").stat().st_size > 1000
