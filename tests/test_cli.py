"""The `bogie-jax` command line: outputs, one-line errors with exit code 2."""

import os
import subprocess
import sys

import numpy as np
import pytest

from bogie_jax.cli import main


def test_simulate_writes_npz_csv_and_plot(tmp_path, capsys):
    npz, png = tmp_path / "run.npz", tmp_path / "run.png"
    code = main(
        [
            "simulate",
            "--speed",
            "40",
            "--duration",
            "0.5",
            "--track",
            "erri-high",
            "--seed",
            "3",
            "--sample-rate",
            "100",
            "--out",
            str(npz),
            "--plot",
            str(png),
        ]
    )
    assert code == 0
    data = np.load(npz)
    assert data["q"].shape == (51, 10) and data["qdd"].shape == (51, 10)
    assert bool(data["successful"]) and float(data["speed"]) == 40.0
    assert png.stat().st_size > 10_000
    csv = tmp_path / "run.csv"
    # the run shapes of the first call (duration, rate, speed, track spectrum and length), so
    # its compiled solve is reused; another seed
    again = ["--speed", "40", "--duration", "0.5", "--track", "erri-high", "--seed", "4"]
    assert main(["simulate", *again, "--sample-rate", "100", "--out", str(csv)]) == 0
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
        (
            ["critical-speed", "--params", "crh380a", "--contact", "s1002-uic60"],
            "`--contact s1002-uic60` needs `--params manchester`",
        ),
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


# `bogie-jax demo` (the monitoring case end to end) is tested in tests/test_monitor.py.


# --- the console script in a fresh process ----------------------------------------------------


def _script(args, env=None, timeout=300):
    """Run `bogie-jax ARGS` (the installed console script's entry point) in a fresh process."""
    code = "import sys; from bogie_jax.cli import main; sys.exit(main(sys.argv[1:]))"
    environ = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "JAX_PLATFORMS")}
    environ.update(env or {})
    return subprocess.run(
        [sys.executable, "-c", code, *args],
        capture_output=True,
        text=True,
        env=environ,
        timeout=timeout,
    )


def test_help_of_every_command_in_a_fresh_process():
    from bogie_jax.cli import COMMANDS

    top = _script(["--help"])
    assert top.returncode == 0 and "--no-cache" in top.stdout
    assert all(name in top.stdout for name in COMMANDS)
    code = (
        "import contextlib, io, sys\n"
        "from bogie_jax.cli import COMMANDS, main\n"
        "for name in COMMANDS:\n"
        "    out = io.StringIO()\n"
        "    with contextlib.redirect_stdout(out):\n"
        "        try:\n"
        "            main([name, '--help'])\n"
        "        except SystemExit as e:\n"
        "            assert e.code == 0, (name, e.code)\n"
        "    assert f'usage: bogie-jax {name}' in out.getvalue(), name\n"
        "    assert '--no-cache' in out.getvalue(), name\n"
        "print('ok')\n"
    )
    each = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert each.returncode == 0 and each.stdout.strip() == "ok", each.stderr


def test_first_line_names_devices_and_cache(tmp_path):
    """A fresh process gets every core as a CPU device (unless XLA_FLAGS is set) and the cache
    directory of `BOGIE_JAX_CACHE_DIR`; `--no-cache` turns the cache off."""
    cache = tmp_path / "cache"
    run = _script(["identify", "--list-params"], {"BOGIE_JAX_CACHE_DIR": str(cache)})
    assert run.returncode == 0, run.stderr
    first, *rest = run.stdout.splitlines()
    n = len(os.sched_getaffinity(0))  # the cores this process may use
    assert first.startswith("bogie-jax ") and f" on {n} CPU device{'s' if n > 1 else ''} " in first
    assert f"(float64, cache {cache})" in first or "(float64, cache ~/" in first
    assert any("yaw_dampers.c" in line for line in rest)
    run = _script(["--no-cache", "identify", "--list-params"], {"XLA_FLAGS": ""})
    first = run.stdout.splitlines()[0]
    assert run.returncode == 0 and " on 1 CPU device (float64, no cache)" in first
    run = _script(
        ["identify", "--list-params", "--no-cache"],
        {"XLA_FLAGS": "--xla_force_host_platform_device_count=3"},
    )
    assert " on 3 CPU devices (float64, no cache)" in run.stdout.splitlines()[0]


def test_bad_value_in_a_fresh_process_is_one_line_and_exit_2():
    run = _script(["--no-cache", "identify", "--starts", "0"])
    assert run.returncode == 2
    message = "bogie-jax identify: error: `--starts` must be in [1, 100000], got 0"
    assert run.stderr.strip() == message


@pytest.mark.heavy
def test_critical_speed_ramp_down_on_the_s1002_table(capsys):
    """Supercritical on S1002/UIC60 1:40 (docs/contact.md, tests/test_hunting.py): the cycle the
    ramp-down reports dying must die within a few m/s of the linear critical speed it prints."""
    assert main(["critical-speed", "--contact", "s1002-uic60", "--ramp-down"]) == 0
    out = capsys.readouterr().out
    linear = float(out.split("linear critical speed: ")[1].split(" m/s")[0])
    lower, upper = (float(x) for x in out.split("dies between ")[1].split(" m/s")[0].split(" and "))
    assert upper - lower == pytest.approx(0.5)
    assert abs(upper - linear) < 4.0
