"""The contact table from wheel and rail profiles, against independent oracles.

- a cone on a circular rail head given as profiles: the exact offset-surface solution
  (`tests/reference/contact_brute_force.py`) over the whole table, and the linearised geometry
  functions of the model (`bogie_jax.contact.cone_geometry`) at the centre;
- S1002 on UIC60 1:40: an independent brute-force search (quintic splines, plain grid minimum);
- the equivalent conicity: a cone gives its own slope; S1002/UIC60 at 3 mm lies in the band of
  published values; the worn wheel gives another curve.
"""

import numpy as np
import pytest

from bogie_jax.contact import (
    PROFILE_PAIRS,
    Profile,
    ProfileError,
    ProfileSetup,
    cone_geometry,
    contact_table,
    equivalent_conicity,
    measured_wheel,
    named_contact_table,
    place_profiles,
    profile_pair,
    read_profile,
    shipped_profile,
    write_csv,
)
from bogie_jax.params import manchester_benchmark


try:  # run from tests/ (CI) or from the repository root
    from reference.contact_brute_force import BruteForce, cone_on_circle_exact, read_points
except ImportError:
    from tests.reference.contact_brute_force import BruteForce, cone_on_circle_exact, read_points


R0, E0, SLOPE, RAIL_RADIUS = 0.46, 0.75, 0.05, 0.3


def _cone_table(step=1e-4):
    """A 1:20 cone on a 0.3 m circle as point profiles, placed with nominal contacts at +-e0."""
    yw = np.arange(-0.0696, 0.06, 1e-4)
    wheel = Profile(yw, -SLOPE * yw, "wheel")  # z downward: the radius falls outwards
    yr = np.arange(-0.05, 0.05, 1e-4)
    rail = Profile(yr, RAIL_RADIUS - np.sqrt(RAIL_RADIUS**2 - yr**2), "rail")
    depth = 0.003
    y_gauge = -np.sqrt(RAIL_RADIUS**2 - (RAIL_RADIUS - depth) ** 2)
    top = E0 + RAIL_RADIUS * np.sin(np.arctan(SLOPE))  # circle top, so the contact is at e0
    setup = ProfileSetup(
        gauge=2 * (top + y_gauge), gauge_height=depth, flange_back_spacing=2 * (E0 - 0.070)
    )
    return contact_table(place_profiles(wheel, rail, setup), step=step)


@pytest.fixture(scope="module")
def cone():
    return _cone_table()


@pytest.fixture(scope="module")
def s1002():
    return named_contact_table("s1002-uic60")


def test_cone_profiles_match_the_exact_cone_on_circle(cone):
    centre = cone.lateral.size // 2
    worst = {}
    for k, y in enumerate(cone.lateral):
        exact = cone_on_circle_exact(y, r0=R0, e0=E0, slope=SLOPE, rail_radius=RAIL_RADIUS)
        got = {
            "roll": cone.roll[k],
            "height": cone.height[k] - cone.height[centre],
            "rolling_radius": cone.rolling_radius[k],
            "contact_angle": cone.contact_angle[k],
            "wheel_contact_y": cone.wheel_contact_y[k],
        }
        for name, value in got.items():
            scale = max(np.max(np.abs(exact[name])), 1e-12)
            err = np.max(np.abs(np.asarray(value) - exact[name])) / scale
            worst[name] = max(worst.get(name, 0.0), err)
    # 1e-6 relative: the issue's bound; the search is exact to the splines' rounding
    assert max(worst.values()) < 1e-6, worst


def test_cone_profiles_reproduce_the_linearised_geometry(cone):
    """The table's slopes at the centre are the model's lambda, sigma, eps, zeta (ref doc 1.2)."""
    geo = cone_geometry(R0, E0, SLOPE, RAIL_RADIUS)
    i, h = cone.lateral.size // 2, cone.lateral[1] - cone.lateral[0]

    def slope(f):
        return (f[i + 1] - f[i - 1]) / (2 * h)

    got = {
        "conicity": slope(cone.rolling_radius[:, 0]),
        "roll_coefficient": E0 * slope(cone.roll),
        "contact_angle_coefficient": E0 * slope(np.tan(cone.contact_angle[:, 0])),
        "vertical_lateral_coefficient": np.diff(cone.height[i - 1 : i + 2], 2)[0] / h**2,
    }
    for name, value in got.items():
        # 1e-6 relative; central differences of 0.1 mm add below 1e-7 (third derivatives)
        assert value == pytest.approx(float(getattr(geo, name)), rel=1e-6), name
    assert cone.contact_angle[i, 0] == pytest.approx(np.arctan(SLOPE), rel=1e-9)
    assert cone.rolling_radius[i, 0] == pytest.approx(R0, rel=1e-8)  # spline of the circle


def test_cone_conicity_is_its_slope_at_every_amplitude(cone):
    amplitudes = np.array([1e-3, 3e-3, 6e-3, 10e-3])
    gamma = equivalent_conicity(cone.lateral, cone.rolling_radius_difference, amplitudes)
    lam = float(cone_geometry(R0, E0, SLOPE, RAIL_RADIUS).conicity)
    np.testing.assert_allclose(gamma, lam, rtol=2e-3)  # the exact Delta r is odd, near-linear


def test_s1002_table_agrees_with_a_brute_force_search(s1002):
    brute = BruteForce(
        read_points(shipped_profile("MBench_S1002_v3.prw")),
        read_points(shipped_profile("MBench_UIC60_v3.prr")),
    )
    # away from the contact-point jumps (near 0, 4.7 and 6.2 mm), where two minima tie
    for y in (1.5e-3, 3.0e-3, -5.5e-3, 9.0e-3):
        k = int(np.argmin(np.abs(s1002.lateral - y)))
        roll, radii, rail_y = brute.contact(float(s1002.lateral[k]))
        assert np.max(np.abs(rail_y - s1002.rail_contact_y[k])) < 5e-5  # 0.05 mm
        assert np.max(np.abs(radii - s1002.rolling_radius[k])) < 1e-6  # 1 um
        assert abs(roll - s1002.roll[k]) < 1e-8


def test_s1002_conicity_and_the_worn_wheel(s1002):
    """S1002 on UIC60 1:40 at gauge 1435 mm, flange-back spacing 1360 mm, at 3 mm amplitude.

    Reference: Commission Regulation (EU) No 1302/2014 (TSI LOC&PAS), 6.2.3.6, tables 11 and 12:
    unworn S1002 wheelsets with a flange-face distance of 1420-1426 mm (flange-back 1360 mm plus
    two flange thicknesses) are deemed to keep the equivalent conicity at or below 0.20 on test
    condition 2 (rail 60E1 = UIC60, inclination 1:40, gauge 1435 mm). The band 0.15-0.20 is the
    value range quoted for this pair (issue brief); no single published value with its set-up
    could be opened in this work."""
    gamma_3mm = float(equivalent_conicity(s1002.lateral, s1002.rolling_radius_difference, 3e-3))
    assert 0.15 <= gamma_3mm <= 0.20, gamma_3mm
    worn = named_contact_table("worn-uic60")
    amplitudes = np.linspace(1e-3, 8e-3, 15)
    new_curve = equivalent_conicity(s1002.lateral, s1002.rolling_radius_difference, amplitudes)
    worn_curve = equivalent_conicity(worn.lateral, worn.rolling_radius_difference, amplitudes)
    assert np.max(np.abs(worn_curve - new_curve)) > 0.05


def test_the_half_worn_wheel_is_the_mean_profile_outside_the_table_blend():
    """Placed in the wheelset frame, the half-worn wheel is the mean of the new and the worn
    wheel at every lateral position both cover; its equivalent conicity at 1 mm amplitude is
    not that of any blend (1 - w) new + w worn of the two tables, w in [0, 1] (the blend is
    linear in w, so its range is the interval between the ends)."""
    placed = {
        name: place_profiles(*profile_pair(name))
        for name in ("s1002-uic60", "worn-uic60", "half-worn-uic60")
    }
    half = placed["half-worn-uic60"]
    big_y = np.linspace(half.wheel_span[0] + 1e-3, half.wheel_span[1] - 1e-3, 200)
    mean = 0.5 * (placed["s1002-uic60"].wheel(big_y) + placed["worn-uic60"].wheel(big_y))
    np.testing.assert_allclose(half.wheel(big_y), mean, atol=2e-6)
    conicity = {
        name: float(
            equivalent_conicity(
                named_contact_table(name).lateral,
                named_contact_table(name).rolling_radius_difference,
                1e-3,
            )
        )
        for name in placed
    }
    ends = sorted((conicity["s1002-uic60"], conicity["worn-uic60"]))
    gap = max(ends[0] - conicity["half-worn-uic60"], conicity["half-worn-uic60"] - ends[1])
    assert gap > 0.01, conicity


def test_a_measured_wheel_is_a_contact_of_the_manchester_set(tmp_path):
    """A measured wheel file on the shipped rail: the S1002 file at its flange back gives the
    `s1002-uic60` table bit for bit; the name changes with the file's bytes, and a file changed
    after it was named is refused rather than read."""
    s1002 = shipped_profile("MBench_S1002_v3.prw")
    copy = tmp_path / "wheel.prw"
    copy.write_bytes(s1002.read_bytes())
    name = measured_wheel(copy, flange_back=-0.070)
    assert manchester_benchmark(contact=name).contact_geometry == name
    table, named = named_contact_table(name), named_contact_table("s1002-uic60")
    for column in ("lateral", "rolling_radius", "contact_angle", "wheel_contact_y", "roll"):
        np.testing.assert_array_equal(getattr(table, column), getattr(named, column))
    copy.write_text(copy.read_text().replace("0.0", "0.00", 1))
    assert measured_wheel(copy, flange_back=-0.070) != name
    with pytest.raises(ProfileError, match="changed since `measured_wheel` read it"):
        profile_pair(name)


def test_every_shipped_pair_is_a_contact_of_the_manchester_set():
    for name in PROFILE_PAIRS:
        assert manchester_benchmark(contact=name).contact_geometry == name
    with pytest.raises(ValueError, match="unknown contact 's1002'; choose one of cone, s1002"):
        manchester_benchmark(contact="s1002")


def test_table_is_mirror_symmetric_and_continuous_in_roll(s1002):
    np.testing.assert_allclose(s1002.roll, -s1002.roll[::-1], atol=1e-15)
    np.testing.assert_allclose(s1002.rolling_radius, s1002.rolling_radius[::-1, ::-1], atol=1e-15)
    assert np.all(np.isfinite(s1002.wheel_lateral_curvature))
    assert np.all(s1002.rail_lateral_curvature + s1002.wheel_lateral_curvature > 0)


# ------------------------------------------------------------------------------- bad input
def test_csv_round_trip(tmp_path):
    wheel = read_profile(shipped_profile("MBench_S1002_v3.prw"))
    write_csv(wheel, tmp_path / "w.csv")
    again = read_profile(tmp_path / "w.csv", kind="wheel")
    np.testing.assert_allclose(again.y, wheel.y, atol=1e-12)
    np.testing.assert_allclose(again.z, wheel.z, atol=1e-12)


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("y [mm],z [mm]\n", "no points"),
        ("y,z\n1,2\n3,x\n", "line 3"),
        ("y,z\n1,0\n3,0\n2,0\n4,0\n5,0\n", "monotone"),
        ("y [m],z [m]\n1,0\n2,0\n", "in mm"),
    ],
)
def test_bad_csv_names_file_and_line(tmp_path, text, fragment):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ProfileError, match=fragment) as info:
        read_profile(path, kind="wheel")
    assert "bad.csv" in str(info.value)


def test_bad_simpack_files(tmp_path):
    source = shipped_profile("MBench_S1002_v3.prw").read_text()
    no_points = tmp_path / "a.prw"
    no_points.write_text(source.split("point.begin")[0])
    with pytest.raises(ProfileError, match="no points"):
        read_profile(no_points)
    no_unit = tmp_path / "b.prw"
    no_unit.write_text(source.replace("units.len.f", "units.other"))
    with pytest.raises(ProfileError, match="length unit"):
        read_profile(no_unit)
    rail_as_wheel = tmp_path / "c.prw"
    rail_as_wheel.write_text(shipped_profile("MBench_UIC60_v3.prr").read_text())
    with pytest.raises(ProfileError, match="must hold a wheel"):
        read_profile(rail_as_wheel)


def test_profiles_that_do_not_touch_name_the_displacement():
    wheel = read_profile(shipped_profile("MBench_S1002_v3.prw"))
    rail = read_profile(shipped_profile("MBench_UIC60_v3.prr"))
    far = ProfileSetup(gauge=1.8, flange_back_spacing=1.36)  # rails beyond the wheels
    with pytest.raises(ProfileError, match="do not touch .* lateral displacement"):
        contact_table(place_profiles(wheel, rail, far), max_lateral=0.002, step=1e-4)


# ------------------------------------------------------------------------------ command line
def _run_contact(argv):
    import argparse

    from bogie_jax.cli import Progress, contact as command

    sub = argparse.ArgumentParser().add_subparsers()
    args = command.add_parser(sub).parse_args(argv)
    return command.run(args, Progress())


def test_contact_command_writes_table_conicity_and_plot(tmp_path, s1002):
    import json

    out = tmp_path / "out"
    assert _run_contact(["--out", str(out), "--step", "0.1"]) == 0
    header = (out / "contact_table.csv").read_text().splitlines()[0].split(",")
    assert header[0] == "lateral [mm]" and all("[" in h for h in header)
    rows = np.loadtxt(out / "contact_table.csv", delimiter=",", skiprows=1)
    assert rows.shape == (s1002.lateral.size, 19)
    np.testing.assert_allclose(rows[:, 3], 1e3 * s1002.rolling_radius[:, 0], atol=1e-9)
    report = json.loads((out / "conicity.json").read_text())
    assert 0.15 <= report["equivalent_conicity_3mm"] <= 0.2
    assert len(report["amplitude_mm"]) == len(report["equivalent_conicity"]) == 20
    assert (out / "contact.png").stat().st_size > 10_000


def test_contact_command_bad_input_is_a_usage_error(tmp_path):
    from bogie_jax.cli import UsageError

    with pytest.raises(UsageError, match="both"):
        _run_contact(["--wheel", str(shipped_profile("MBench_S1002_v3.prw"))])
    bad = tmp_path / "rail.csv"
    bad.write_text("y,z\n1,0\n")
    with pytest.raises(UsageError, match="rail.csv"):
        _run_contact(["--wheel", str(shipped_profile("MBench_S1002_v3.prw")), "--rail", str(bad)])
