"""`bogie-jax monitor` and `demo`: what the user chooses to fit (`--candidates`,
`--list-elements`, `--contact`, `--fit-model`) reaches the library, and bad choices exit 2
before anything compiles. A stand-in `monitor` takes the options; nothing is fitted.
"""

import types

import pytest

from bogie_jax.cli import main
from bogie_jax.contact import measured_wheel, shipped_profile
from bogie_jax.monitor import DEFAULT_CANDIDATES, nonlinear_options
from bogie_jax.params import ModelOptions


try:
    from cli_files import blank_file, exit_code
except ImportError:  # tests/ imported as a package
    from tests.cli_files import blank_file, exit_code


# --- the stand-in monitor ---------------------------------------------------------------------


class _Captured(Exception):
    """Raised by the stand-in `monitor` once it has the options (no fit is run)."""


def _capture_monitor(monkeypatch, module, params_seen=None):
    """Replace `monitor` in `bogie_jax.cli.<module>` by one that keeps its options (and its
    parameters in `params_seen`) and raises `_Captured`; returns the list the options go to."""
    seen = []

    def fake(measurements, tracks, *, params, options, progress=None):
        seen.append(options)
        if params_seen is not None:
            params_seen.append(params)
        raise _Captured

    monkeypatch.setattr(f"bogie_jax.cli.{module}.monitor", fake)
    return seen


@pytest.mark.parametrize("command", ["monitor", "demo"])
def test_list_elements_prints_names_and_compiles_nothing(command, monkeypatch, capsys):
    seen = _capture_monitor(monkeypatch, command)
    monkeypatch.setattr("bogie_jax.cli.demo.scenario_measurements", None)  # never called
    assert exit_code([command, "--list-elements"]) == 0
    lines = capsys.readouterr().out.splitlines()[1:]  # after the "what it runs on" line
    marked = {line.split()[0] for line in lines if line.split()[1:] == ["default"]}
    assert marked == set(DEFAULT_CANDIDATES) and not seen
    names = {line.split()[0] for line in lines}
    assert {"yaw_dampers.c", "primary.1L.kx", "secondary.left.kz"} <= names


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--candidates", "primary.1L.kzz"], "did you mean primary.1L.kz"),
        (["--candidates", "primary.3L.kz"], "unknown element '3L' in parameter 'primary.3L.kz'"),
        (["--candidates", "yaw_dampers.c", "yaw_dampers.c"], "`--candidates` repeats"),
    ],
)
@pytest.mark.parametrize("command", ["monitor", "demo"])
def test_bad_candidates_exit_2_before_anything_runs(command, argv, message, tmp_path, capsys):
    data = ["--data", str(tmp_path / "missing.csv")] if command == "monitor" else []
    assert exit_code([command, *data, *argv, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "`--candidates`" in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "o").exists()


def test_candidates_go_with_data_only(capsys):
    assert exit_code(["monitor", "--history", "x", "--candidates", "yaw_dampers.c"]) == 2
    assert "`--candidates` goes with `--data`" in capsys.readouterr().err


CHOSEN = ["yaw_dampers.c", "primary.1L.kz"]
S1002 = shipped_profile("MBench_S1002_v3.prw")


def test_monitor_candidates_reach_the_options(tmp_path, monkeypatch):
    seen = _capture_monitor(monkeypatch, "monitor")
    a = blank_file(tmp_path / "a.csv")
    with pytest.raises(_Captured):
        main(["monitor", "--data", a, "--candidates", *CHOSEN, "--out", str(tmp_path / "o")])
    assert seen[0].candidates == tuple(CHOSEN)


def test_monitor_contact_and_fit_model_reach_the_fit(tmp_path, monkeypatch):
    params = []
    seen = _capture_monitor(monkeypatch, "monitor", params)
    a = blank_file(tmp_path / "a.csv")
    with pytest.raises(_Captured):
        main(["monitor", "--data", a, "--out", str(tmp_path / "o")])
    with pytest.raises(_Captured):
        argv = ["--contact", "s1002-uic60", "--fit-model", "nonlinear"]
        main(["monitor", "--data", a, *argv, "--out", str(tmp_path / "o")])
    with pytest.raises(_Captured):
        argv = ["--contact", "s1002-uic60", "--wear", "0.4"]
        main(["monitor", "--data", a, *argv, "--out", str(tmp_path / "o")])
    wheel = str(shipped_profile("worn_high_mileage.prw"))
    with pytest.raises(_Captured):
        argv = ["--wheel-profile", wheel, "--flange-back", "0"]
        main(["monitor", "--data", a, *argv, "--out", str(tmp_path / "o")])
    assert [p.contact_geometry for p in params[:3]] == ["cone", "s1002-uic60", "s1002-uic60"]
    assert params[3].contact_geometry == measured_wheel(wheel, 0.0)
    assert seen[0].model == ModelOptions() and seen[1].model == nonlinear_options()
    assert seen[1].model.creep_saturation and seen[1].model.nonlinear_dampers
    assert params[1].wear is None and float(params[2].wear.level) == 0.4


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--vehicle", "crh380a", "--contact", "s1002-uic60"], "needs `--vehicle manchester`"),
        (["--fit-model", "cubic"], "invalid choice: 'cubic'"),
        (["--contact", "s1002"], "invalid choice: 's1002'"),
        (["--wear", "0.5"], "`--wear` needs `--contact s1002-uic60`, got `--contact cone`"),
        (["--contact", "s1002-uic60", "--wear", "0"], "`--wear` = 0.0 must lie in (0, 1]"),
        (["--contact", "s1002-uic60", "--wear", "1.5"], "`--wear` = 1.5 must lie in (0, 1]"),
        (["--wheel-profile", "no.prw"], "no.prw: no such profile file"),
        (
            ["--wheel-profile", str(S1002), "--flange-back", "900"],
            "`--flange-back` = 900 mm must lie in [-500, 500]",
        ),
        (
            ["--wheel-profile", str(shipped_profile("MBench_UIC60_v3.prr"))],
            "expected a wheel profile, the file holds a rail",
        ),
        (
            ["--contact", "s1002-uic60", "--wheel-profile", "x.prw"],
            "`--wheel-profile` takes the place of `--contact` and `--wear`",
        ),
    ],
)
def test_monitor_bad_model_choice_exits_2_before_fitting(argv, message, tmp_path, capsys):
    a = blank_file(tmp_path / "a.csv")
    assert exit_code(["monitor", "--data", a, *argv, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err, err
    assert not (tmp_path / "o").exists()


def test_model_choice_goes_with_data_only(capsys):
    assert exit_code(["monitor", "--history", "x", "--fit-model", "nonlinear"]) == 2
    err = capsys.readouterr().err
    assert "`--contact`, `--wear`, `--wheel-profile` and `--fit-model` go with `--data`" in err


def test_demo_candidates_reach_the_options(tmp_path, monkeypatch):
    """The chosen candidates reach `monitor` and the programs compiled beside the simulation
    (`compile_programs`), the same options."""
    seen = _capture_monitor(monkeypatch, "demo")
    blank = lambda *a, **k: [types.SimpleNamespace(track=None)]
    monkeypatch.setattr("bogie_jax.cli.demo.scenario_measurements", blank)
    monkeypatch.setattr("bogie_jax.cli.demo.recorded_track", lambda *a, **k: None)
    compiled = []
    fake_compile = lambda layout, tracks, *, params, options: compiled.append(options)
    monkeypatch.setattr("bogie_jax.cli.demo.compile_programs", fake_compile)
    with pytest.raises(_Captured):
        main(["demo", "--noise", "0", "--candidates", *CHOSEN, "--out", str(tmp_path / "o")])
    assert seen[0].candidates == tuple(CHOSEN)
    assert compiled == seen
