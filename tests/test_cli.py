"""The `bogie-jax` command line: outputs, one-line errors with exit code 2."""

import json

import numpy as np
import pytest

from bogie_jax.cli import main


def test_simulate_writes_npz_csv_and_plot(tmp_path, capsys):
    npz, png = tmp_path / "run.npz", tmp_path / "run.png"
    code = main(["simulate", "--speed", "40", "--duration", "0.5", "--track", "erri-high",
                 "--seed", "3", "--sample-rate", "100", "--out", str(npz), "--plot", str(png)])
    assert code == 0
    data = np.load(npz)
    assert data["q"].shape == (51, 10) and data["qdd"].shape == (51, 10)
    assert bool(data["successful"]) and float(data["speed"]) == 40.0
    assert png.stat().st_size > 10_000
    csv = tmp_path / "run.csv"
    assert main(["simulate", "--duration", "0.2", "--sample-rate", "50", "--out", str(csv)]) == 0
    header = csv.read_text().splitlines()[0].split(",")
    assert header[0] == "time_s" and "wheelset1.y[m]" in header and len(header) == 31
    assert "wrote" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, message",
    [
        (["simulate", "--speed", "-5"], "`speed` = -5 m/s is outside the valid range"),
        (["simulate", "--duration", "0"], "`duration` = 0 s is outside the valid range"),
        (["simulate", "--track", "erri-medium"], "is not a known spectrum"),
        (["simulate", "--track", "missing.csv"], "does not exist"),
        (["simulate", "--out", "run.txt"], "`--out` must end in .npz or .csv"),
        (["simulate", "--speed", "fast"], "invalid float value: 'fast'"),
        (["critical-speed", "--v-min", "90", "--v-max", "20"], "need 0 < `--v-min` < `--v-max`"),
        (["simulate", "--params", "tgv"], "invalid choice: 'tgv'"),
    ],
)
def test_bad_values_give_one_line_error_and_exit_2(argv, message, capsys):
    try:
        code = main(argv)
    except SystemExit as e:  # argparse's own errors
        code = e.code
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert message in err and len(err.splitlines()) == 1


def test_help_gives_units(capsys):
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    out = capsys.readouterr().out
    assert "[m/s]" in out and "[s]" in out and "[Hz]" in out


def test_demo_writes_data_and_plots(tmp_path, capsys):
    """The README's main job: simulation data and plots plus the critical speed."""
    assert main(["demo", "--out", str(tmp_path)]) == 0
    for name in ("simulation.npz", "simulation.png", "stability.png"):
        assert (tmp_path / name).stat().st_size > 1000
    out = capsys.readouterr().out
    assert "critical speed" in out or "stable over the whole range" in out
    assert json.dumps(out)  # printable
