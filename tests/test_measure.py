"""Sensors and measurements: accelerations from the equations of motion against independent
oracles, noise and bias, the default layout, and Measurement IO (round trips and load errors)."""

import dataclasses
import json

import diffrax as dfx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

from bogie_jax.io import load_measurement, save_measurement
from bogie_jax.measure import (
    Accelerometer,
    Axlebox,
    DisplacementSensor,
    FramePoint,
    Measurement,
    MeasurementError,
    RateGyro,
    SampleState,
    default_sensor_layout,
    layout_description,
    point_motion,
    sensors_from_layout,
    synthetic_measurement,
)
from bogie_jax.model import build_model
from bogie_jax.track import TrackReference, perfect_track


try:
    from fixtures_cost import nominal, short_track  # noqa: F401
except ImportError:  # tests/ imported as a package
    from tests.fixtures_cost import nominal, short_track  # noqa: F401


DENSE_RATE = 4000.0  # [Hz] sampling of the finite-difference oracle
POINT = FramePoint(1.28, -1.0, 0.3)


def _oracle_sensors():
    sensors = []
    for loc, tag in (
        (POINT, "frame"),
        (Axlebox(1, "left"), "box1L"),
        (Axlebox(2, "right"), "box2R"),
    ):
        for axis in "xyz":
            sensors.append(Accelerometer(f"{tag}_a{axis}", loc, axis))
            sensors.append(DisplacementSensor(f"{tag}_d{axis}", loc, axis))
    return tuple(sensors)


DENSE_RUN = dict(
    speed=50.0,
    duration=0.2,
    sample_rate=DENSE_RATE,
    stepsize_controller=dfx.PIDController(rtol=1e-12, atol=1e-14),
)


@pytest.fixture(scope="module")
def dense(nominal, short_track):
    """A 0.2 s run sampled at 4 kHz, solved at rtol 1e-12: accelerometers and displacement
    sensors at the same points (frame point and two axleboxes, all three axes). The one compiled
    synthetic measurement of this file (sensor names are static, noise and bias traced)."""
    return synthetic_measurement(nominal, short_track, sensors=_oracle_sensors(), **DENSE_RUN)


def test_point_accelerations_match_second_differences_of_positions(dense):
    # Oracle: central second differences of the displacement channels (positions from q and the
    # track input only). Truncation error (omega dt)^2 / 12 of the signal: below 1e-3 of the peak
    # acceleration for the < 60 Hz content here; the solve (rtol 1e-12) adds < 1e-6.
    dt = 1.0 / DENSE_RATE
    for tag in ("frame", "box1L", "box2R"):
        for axis in "xyz":
            a = np.asarray(dense.channel(f"{tag}_a{axis}"))
            d = np.asarray(dense.channel(f"{tag}_d{axis}"))
            fd = (d[2:] - 2 * d[1:-1] + d[:-2]) / dt**2
            scale = np.max(np.abs(a))
            assert scale > 0
            np.testing.assert_allclose(
                a[1:-1], fd, rtol=0, atol=2e-3 * scale, err_msg=f"{tag} {axis}"
            )


def test_pure_yaw_rotation_has_the_analytic_acceleration(nominal):
    # Frame yawing only: r = R_z(psi) p, a = alpha e_z x r - omega^2 r (horizontal components).
    model = build_model(nominal, speed=50.0, track=perfect_track())
    psi, omega, alpha = 0.3, 0.7, -2.0
    q, qd, qdd = (
        jnp.zeros(10).at[5].set(psi),
        jnp.zeros(10).at[5].set(omega),
        jnp.zeros(10).at[5].set(alpha),
    )
    zero = jnp.zeros((2, 3))
    r_rel, _, a = jax.jit(
        lambda: point_motion(POINT, model, SampleState(q, qd, qdd, zero, zero, zero))
    )()
    r_rel = r_rel - jnp.array([0.0, 0.0, float(nominal.geometry.frame_cg_height)])
    expected = alpha * jnp.cross(jnp.array([0.0, 0.0, 1.0]), r_rel) - omega**2 * r_rel.at[2].set(
        0.0
    )
    np.testing.assert_allclose(a, expected, rtol=0, atol=1e-12)  # algebraic identity
    gyro = RateGyro("g", "z").read(model, SampleState(q, qd, qdd, zero, zero, zero))
    np.testing.assert_allclose(gyro, omega, rtol=1e-14)


def test_noise_and_bias_with_explicit_key(nominal, short_track, dense):
    # The run and sensors of `dense` (its compiled simulation: names, locations and axes are
    # static, noise_std and bias are array leaves), one accelerometer with a bias.
    biased = tuple(
        dataclasses.replace(s, bias=0.5) if s.name == "frame_ay" else s for s in _oracle_sensors()
    )
    args = dict(sensors=biased, **DENSE_RUN)
    clean = synthetic_measurement(nominal, short_track, **args)
    noisy = synthetic_measurement(nominal, short_track, key=jr.PRNGKey(7), **args)
    again = synthetic_measurement(nominal, short_track, key=jr.PRNGKey(7), **args)
    np.testing.assert_array_equal(noisy.data, again.data)  # the key alone fixes the noise
    i = clean.channels.index("frame_ay")
    np.testing.assert_allclose(clean.data[:, i] - dense.data[:, i], 0.5, atol=1e-12)
    others = [j for j in range(len(biased)) if j != i]
    np.testing.assert_array_equal(clean.data[:, others], dense.data[:, others])
    std = (np.asarray(noisy.data) - np.asarray(clean.data)).std(axis=0)
    expected = np.array([float(s.noise_std) for s in biased])
    assert len(set(expected)) == 2  # accelerometers and displacement sensors
    np.testing.assert_allclose(std, expected, rtol=0.3)  # 801 samples: sampling error ~ 3 %


def test_default_layout_and_json_round_trip(nominal):
    layout = default_sensor_layout(nominal)
    names = [s.name for s in layout]
    assert len(layout) == 13 and "frame_yaw_rate" in names
    for ws in "12":
        for side in "LR":
            assert {f"frame_{ws}{side}_y", f"frame_{ws}{side}_z", f"axlebox_{ws}{side}_y"} <= set(
                names
            )
    text = layout_description(layout)
    back = sensors_from_layout(text)
    assert layout_description(back) == text
    assert [s.unit for s in back] == [s.unit for s in layout]


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: Accelerometer("a", POINT, "w"), "`axis` must be one of"),
        (lambda: Accelerometer("a", POINT, "y", noise_std=0.0), "`noise_std` must be > 0"),
        (lambda: Axlebox(3, "left"), "`wheelset` must be 1 or 2"),
        (lambda: Axlebox(1, "middle"), "`side` must be 'left' or 'right'"),
        (
            lambda: sensors_from_layout('[{"type": "Thermometer", "name": "t"}]'),
            "unknown sensor type",
        ),
        (lambda: sensors_from_layout("[1, 2"), "not valid JSON"),
        (lambda: layout_description([RateGyro("g"), RateGyro("g")]), "repeated: g"),
    ],
)
def test_bad_sensors_are_rejected(make, match):
    with pytest.raises(ValueError, match=match):
        make()


# ----------------------------------------------------------------------------------------- IO
def _measurement(n=6, rate=100.0, layout=True):
    sensors = (Accelerometer("acc", POINT, "y"), RateGyro("gyro"))
    data = np.arange(2.0 * n).reshape(n, 2) / 7.0
    data[2, 0] = np.nan
    return Measurement(
        times=np.arange(n) / rate,
        data=data,
        channels=("acc", "gyro"),
        units=("m/s^2", "rad/s"),
        speed=42.5,
        track=TrackReference(spectrum="erri-low", seed=3, length=150.0),
        layout=layout_description(sensors) if layout else "",
        note="run 7",
    )


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_round_trip_keeps_data_missing_samples_and_metadata(tmp_path, suffix):
    m = _measurement()
    back = load_measurement(save_measurement(tmp_path / f"m{suffix}", m))
    np.testing.assert_array_equal(back.times, m.times)
    np.testing.assert_array_equal(back.data, m.data)  # NaN positions included
    assert (back.channels, back.units, back.track, back.layout, back.note) == (
        m.channels,
        m.units,
        m.track,
        m.layout,
        m.note,
    )
    assert float(back.speed) == 42.5 and back.sample_rate == pytest.approx(100.0, rel=1e-12)
    assert bool(back.missing[2, 0]) and int(back.missing.sum()) == 1


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_track_reference_is_structured_metadata(tmp_path, suffix):
    path = save_measurement(tmp_path / f"m{suffix}", _measurement())
    if suffix == ".csv":
        line = next(t for t in path.read_text().splitlines() if t.startswith("# track:"))
        stored = json.loads(line.partition(":")[2])
    else:
        with np.load(path) as z:
            stored = json.loads(str(z["track"]))
    assert stored == TrackReference(spectrum="erri-low", seed=3, length=150.0).to_dict()
    none = save_measurement(
        tmp_path / f"n{suffix}", dataclasses.replace(_measurement(), track=None)
    )
    assert load_measurement(none).track is None


def test_free_text_track_of_old_files_is_kept_as_a_note(tmp_path):
    meta = "# speed_m_s: 50\n# sample_rate_hz: 100\n# track: erri-low seed=0\n"
    m = load_measurement(_csv(tmp_path, "time_s,acc[m/s^2]\n0,1\n0.01,2\n", meta))
    assert m.track is None and m.note == "track: erri-low seed=0"
    path = tmp_path / "old.npz"
    np.savez(
        path,
        times=m.times,
        data=m.data,
        channels=np.array(m.channels),
        units=np.array(m.units),
        speed=np.asarray(50.0),
        track=np.array("fra-3 seed=2"),
    )
    assert load_measurement(path).note == "track: fra-3 seed=2"


def test_measurement_track_must_be_a_reference():
    with pytest.raises(MeasurementError, match="TrackReference"):
        Measurement(
            times=np.arange(3) / 10.0,
            data=np.zeros((3, 1)),
            channels=("a",),
            units=("m",),
            speed=1.0,
            track="erri-low seed=0",
        )


def _csv(tmp_path, body, meta="# speed_m_s: 50\n# sample_rate_hz: 100\n"):
    path = tmp_path / "m.csv"
    path.write_text(meta + body)
    return path


GOOD_ROWS = "0,1,2\n0.01,1,2\n0.02,,2\n"


@pytest.mark.parametrize(
    "body, meta, match",
    [
        (
            "time_s,a[m/s^2]\n0,1,2\n0.01,1\n",
            None,
            r"line 4: wrong shape: 3 columns, the header has 2",
        ),
        ("time_s,a[m/s^2],b[rad/s]\n0,1,2\n0.02,1,2\n0.01,1,2\n", None, "non-monotone times"),
        ("time_s,a[m/s^2],b[rad/s]\n0,1,2\n0.01,1,2\n0.03,1,2\n", None, "mismatched sample rates"),
        (
            "time_s,a[m/s^2],b[rad/s]\n0,1,2\n0.02,1,2\n0.04,1,2\n",
            None,
            r"sampled at 50 Hz, expected .*100 Hz",
        ),
        ("time_s,a[m/s^2],b\n" + GOOD_ROWS, None, r"column 3: expected `name\[unit\]`"),
        ("t,a[m/s^2],b[rad/s]\n" + GOOD_ROWS, None, "must start with `time_s`"),
        (
            "time_s,a[m/s^2],b[rad/s]\n0,x,2\n0.01,1,2\n",
            None,
            "line 4, column 2: expected a number",
        ),
        ("time_s,a[m/s^2],b[rad/s]\n0,inf,2\n0.01,1,2\n", None, "must be finite or NaN"),
        (
            "time_s,a[m/s^2],b[rad/s]\n" + GOOD_ROWS,
            "# speed_m_s: 50\n",
            "missing metadata line `# sample_rate_hz",
        ),
        ("time_s,a[m/s^2],a[m/s^2]\n" + GOOD_ROWS, None, "repeated: a"),
    ],
)
def test_csv_load_errors_name_the_problem(tmp_path, body, meta, match):
    path = _csv(tmp_path, body) if meta is None else _csv(tmp_path, body, meta)
    with pytest.raises(MeasurementError, match=match):
        load_measurement(path)


def test_unknown_channels_are_rejected(tmp_path):
    m = _measurement()
    path = save_measurement(tmp_path / "m.csv", m)
    text = path.read_text().replace("gyro[rad/s]", "thermo[rad/s]")
    path.write_text(text)
    with pytest.raises(MeasurementError, match="unknown channel 'thermo'"):
        load_measurement(path)
    bare = save_measurement(tmp_path / "bare.npz", _measurement(layout=False))
    with pytest.raises(MeasurementError, match="unknown channel 'gyro'"):
        load_measurement(bare, sensors=[Accelerometer("acc", POINT, "y")])
    loaded = load_measurement(bare, sensors=[RateGyro("gyro"), Accelerometer("acc", POINT, "y")])
    assert [s.name for s in loaded.sensors()] == ["acc", "gyro"]  # layout from `sensors`
    with pytest.raises(MeasurementError, match="has unit 'm/s\\^2', its sensor measures 'rad/s'"):
        load_measurement(bare, sensors=[RateGyro("acc"), RateGyro("gyro")])


def test_npz_load_errors_name_the_problem(tmp_path):
    m = _measurement()
    base = dict(
        times=np.asarray(m.times),
        data=np.asarray(m.data),
        channels=np.array(m.channels),
        units=np.array(m.units),
        speed=np.array(42.5),
        layout=np.array(m.layout),
    )
    cases = [
        (dict(data=np.zeros((5, 2))), r"`data` must have shape \(n_times, n_channels\) = \(6, 2\)"),
        (dict(units=np.array(["m/s^2"])), "`units` has 1 entries for 2 channels"),
        (dict(times=np.array([0, 0.01, 0.02, 0.02, 0.04, 0.05])), "non-monotone times"),
        (dict(speed=np.array([1.0, 2.0])), "`speed` must be a scalar"),
        (dict(speed=np.array(-3.0)), "`speed` must be > 0"),
    ]
    for i, (change, match) in enumerate(cases):
        path = tmp_path / f"bad{i}.npz"
        np.savez(path, **{**base, **change})
        with pytest.raises(MeasurementError, match=match):
            load_measurement(path)
    path = tmp_path / "missing.npz"
    np.savez(path, times=base["times"])
    with pytest.raises(MeasurementError, match="missing arrays data, channels, units, speed"):
        load_measurement(path)
    with pytest.raises(MeasurementError, match="expected 50 Hz|sampled at 100 Hz, expected"):
        load_measurement(save_measurement(tmp_path / "ok.npz", m), sample_rate=50.0)
    with pytest.raises(MeasurementError, match="expected a .npz or .csv"):
        load_measurement(tmp_path / "m.txt")


def test_measurement_layout_json_is_valid(tmp_path):
    m = _measurement()
    assert [d["name"] for d in json.loads(m.layout)] == ["acc", "gyro"]
