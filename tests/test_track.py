"""Track spectra, synthesis, spline evaluation and CSV IO, against independent oracles."""

import math

import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest
from scipy.integrate import quad
from scipy.interpolate import CubicSpline

from bogie_jax.io import load_track_csv, save_track_csv
from bogie_jax.track import (
    AbstractTrackPSD,
    ERRIB176Spectrum,
    FRASpectrum,
    TrackIrregularity,
    band_variance,
    perfect_track,
    synthesise_track,
)


# --- Oracles: the spectra of reference doc 6.1 / 6.2 written out independently --------------

ERRI = {"low": (4.032e-7, 2.119e-7), "high": (1.080e-6, 6.125e-7)}  # (A_v, A_a) [m^2 rad/m]
FRA = {  # class: (A_v, A_a) [cm^2 rad/m], omega_s [rad/m]
    1: (1.2107, 3.3634, 0.6046),
    2: (1.0181, 1.2107, 0.9308),
    3: (0.6816, 0.4128, 0.8520),
    4: (0.5376, 0.3027, 1.1312),
    5: (0.2095, 0.0762, 0.8209),
    6: (0.0339, 0.0339, 0.4380),
}


def erri_oracle(level, channel, om):
    a_v, a_a = ERRI[level]
    oc, orr, os_, b = 0.8246, 0.0206, 0.4380, 0.75
    den = (om**2 + orr**2) * (om**2 + oc**2)
    if channel == 0:
        return a_a * oc**2 / den
    if channel == 1:
        return a_v * oc**2 / den
    return a_v / b**2 * oc**2 * om**2 / (den * (om**2 + os_**2))


def fra_oracle(n, channel, om):
    a_v, a_a, os_ = FRA[n]
    k, oc = 0.25, 0.8245
    if channel < 2:
        a = (a_a, a_v)[channel] * 1e-4
        return k * a * oc**2 / (om**2 * (om**2 + oc**2))
    height = 4 * k * a_v * 1e-4 * oc**2 / ((om**2 + oc**2) * (om**2 + os_**2))
    return height / 1.5**2  # angle over the contact-point distance 2 b = 1.5 m


def quad_variance(oracle, band):
    lo, hi = 2 * math.pi / band[1], 2 * math.pi / band[0]
    return np.array(
        [
            quad(lambda w: oracle(c, w), lo, hi, epsabs=0, epsrel=1e-10, limit=200)[0]
            for c in range(3)
        ]
    )


OMEGAS = np.array([0.01, 0.09, 0.5, 0.8246, 2.0, 10.0])


@pytest.mark.parametrize("level", ["low", "high"])
def test_erri_psd_values(level):
    psd = getattr(ERRIB176Spectrum, level)()
    got = np.asarray(psd(OMEGAS))
    assert got.shape == (OMEGAS.size, 3)
    for c in range(3):
        np.testing.assert_allclose(got[:, c], erri_oracle(level, c, OMEGAS), rtol=1e-12)


@pytest.mark.parametrize("n", range(1, 7))
def test_fra_class_values(n):
    psd = FRASpectrum.track_class(n)
    a_v, a_a, os_ = FRA[n]
    np.testing.assert_allclose([psd.A_v, psd.A_a, psd.omega_s], [a_v * 1e-4, a_a * 1e-4, os_])
    got = np.asarray(psd(OMEGAS))
    for c in range(3):
        np.testing.assert_allclose(got[:, c], fra_oracle(n, c, OMEGAS), rtol=1e-12)


@pytest.mark.parametrize("n", [0, 7, -1, 2.0, "3", True])
def test_fra_bad_class(n):
    with pytest.raises(ValueError, match=r"`n`.*1\.\.6"):
        FRASpectrum.track_class(n)


def test_psd_constants_checked():
    with pytest.raises(ValueError, match=r"ERRIB176Spectrum.A_v.*> 0"):
        ERRIB176Spectrum(A_v=-1.0, A_a=1e-7, omega_c=0.8, omega_r=0.02, omega_s=0.4, b=0.75)


# --- band variance ----------------------------------------------------------------------------

BANDS = [(3.0, 70.0), (1.0, 120.0), (1.524, 304.8)]


@pytest.mark.parametrize("band", BANDS)
@pytest.mark.parametrize("level", ["low", "high"])
def test_band_variance_erri_vs_quad(level, band):
    got = np.asarray(band_variance(getattr(ERRIB176Spectrum, level)(), band))
    want = quad_variance(lambda c, w: erri_oracle(level, c, w), band)
    np.testing.assert_allclose(got, want, rtol=1e-6)


@pytest.mark.parametrize("band", BANDS)
@pytest.mark.parametrize("n", [1, 5, 6])
def test_band_variance_fra_vs_quad(n, band):
    got = np.asarray(band_variance(FRASpectrum.track_class(n), band))
    want = quad_variance(lambda c, w: fra_oracle(n, c, w), band)
    np.testing.assert_allclose(got, want, rtol=1e-6)


@pytest.mark.parametrize(
    "level, rms",  # reference doc 6.1, 3-70 m: (lateral [mm], vertical [mm], cross level [mrad])
    [("low", (1.39, 1.92, 1.15)), ("high", (2.37, 3.15, 1.88))],
)
def test_band_variance_reference_rms(level, rms):
    got = 1e3 * np.sqrt(np.asarray(band_variance(getattr(ERRIB176Spectrum, level)(), (3.0, 70.0))))
    np.testing.assert_allclose(got, rms, rtol=0.02)


def test_fra_vertical_reference_rms():
    # reference doc 6.2, vertical RMS [mm] over 1.524-304.8 m for classes 1..6
    want = [37.6, 34.5, 28.2, 25.0, 15.6, 6.3]
    got = [
        1e3 * math.sqrt(band_variance(FRASpectrum.track_class(n), (1.524, 304.8))[1])
        for n in range(1, 7)
    ]
    np.testing.assert_allclose(got, want, rtol=0.01)


# --- synthesis --------------------------------------------------------------------------------

SHORT = 300.0  # [m] one length for the short tracks, so their compilations are shared


@pytest.mark.parametrize(
    "psd", [ERRIB176Spectrum.low(), FRASpectrum.track_class(5)], ids=["erri-low", "fra-5"]
)
def test_synthesised_rms_and_independence(psd, getkey):
    fade = 20.0
    track = synthesise_track(psd, key=getkey(), length=20_000.0, fade_length=fade)
    values = np.asarray(track.values)
    assert values.shape == (80_001, 3)
    plateau = values[int(fade / 0.25) : -int(fade / 0.25)]
    target = np.sqrt(np.asarray(band_variance(psd, (3.0, 70.0))))
    np.testing.assert_allclose(plateau.std(axis=0), target, rtol=0.05)
    corr = np.corrcoef(plateau.T)
    assert np.all(np.abs(corr[np.triu_indices(3, 1)]) < 0.1)


def test_synthesis_keys(getkey):
    psd = ERRIB176Spectrum.high()  # same pytree structure as low(): shares compilations
    key = getkey()
    a = synthesise_track(psd, key=key, length=SHORT)
    b = synthesise_track(psd, key=key, length=SHORT)
    c = synthesise_track(psd, key=getkey(), length=SHORT)
    np.testing.assert_array_equal(a.values, b.values)
    assert np.max(np.abs(a.values - c.values)) > 1e-4


def test_fade_in(getkey):
    psd, key, fade = ERRIB176Spectrum.low(), getkey(), 20.0
    faded = synthesise_track(psd, key=key, length=SHORT, fade_length=fade, start=50.0)
    raw = synthesise_track(psd, key=key, length=SHORT, fade_length=0.0, start=50.0)
    w_faded, w_raw = np.asarray(faded.values), np.asarray(raw.values)
    assert np.all(w_faded[0] == 0.0) and np.all(w_faded[-1] == 0.0)
    s = 0.25 * np.arange(w_faded.shape[0])
    u = np.clip(s / fade, 0.0, 1.0)
    ramp = 6 * u**5 - 15 * u**4 + 10 * u**3
    head = s <= SHORT / 2
    np.testing.assert_allclose(
        w_faded[head], ramp[head, None] * w_raw[head], rtol=1e-12, atol=1e-15
    )
    # smooth start: the slope at the start is small against its plateau scale
    dw0 = np.asarray(faded.evaluate(50.0)[1])
    dw_scale = np.std(np.diff(w_raw, axis=0), axis=0) / 0.25
    assert np.all(np.abs(dw0) < 0.05 * dw_scale)
    assert float(faded.s0) == 50.0 and float(faded.ds) == 0.25


def test_synthesis_vmap_over_keys(getkey):
    keys = jr.split(getkey(), 3)
    make = lambda k: synthesise_track(ERRIB176Spectrum.low(), key=k, length=SHORT)
    batch = jax.vmap(make)(keys)
    np.testing.assert_allclose(batch.values[1], make(keys[1]).values, rtol=1e-12, atol=1e-15)


class _ExplodingPSD(AbstractTrackPSD):
    def __call__(self, omega):
        raise AssertionError("the PSD must not be evaluated for invalid arguments")


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(length=0.0), r"`length`.*> 0.*0\.0"),
        (dict(length=-5.0), r"`length`.*> 0"),
        (dict(length=math.inf), r"`length`.*finite"),
        (dict(spacing=0.0), r"`spacing`.*> 0"),
        (dict(spacing=1.6), r"`spacing`.*< lambda_min / 2 = 1\.5.*1\.6"),
        (dict(wavelength_band=(70.0, 3.0)), r"`wavelength_band`.*lambda_min < lambda_max"),
        (dict(wavelength_band=(0.0, 3.0)), r"`wavelength_band`.*0 < lambda_min"),
        (dict(wavelength_band=(3.0,)), r"`wavelength_band`.*pair"),
        (dict(fade_length=-1.0), r"`fade_length`.*0 <= 2 fade_length"),
        (dict(length=30.0, fade_length=20.0), r"`fade_length`.*<= 30\.0"),
    ],
)
def test_synthesis_bad_arguments_raise_before_work(kwargs, match, getkey):
    args = dict(length=1e9, spacing=0.25) | kwargs  # huge default length: fails fast or not at all
    with pytest.raises(ValueError, match=match):
        synthesise_track(_ExplodingPSD(), key=getkey(), **args)


def test_band_variance_bad_band():
    with pytest.raises(ValueError, match=r"`wavelength_band`"):
        band_variance(ERRIB176Spectrum.low(), (5.0, 5.0))
    with pytest.raises(TypeError, match=r"`psd`"):
        band_variance("erri", (3.0, 70.0))


# --- spline -----------------------------------------------------------------------------------


def smooth(s):
    k1, k2 = 2 * np.pi / 17, 2 * np.pi / 31
    w = np.sin(k1 * s) + 0.3 * np.cos(k2 * s)
    dw = k1 * np.cos(k1 * s) - 0.3 * k2 * np.sin(k2 * s)
    d2w = -(k1**2) * np.sin(k1 * s) - 0.3 * k2**2 * np.cos(k2 * s)
    return w, dw, d2w


def smooth_track():
    s = 10.0 + 0.25 * np.arange(801)  # 10 m .. 210 m
    w = smooth(s)[0]
    return TrackIrregularity.from_samples(s, np.stack([w, -w, 0.5 * w], axis=1)), s


def test_spline_matches_smooth_function(getkey):
    track, _ = smooth_track()
    points = np.asarray(jr.uniform(getkey(), (200,), minval=20.0, maxval=200.0))
    out = jax.vmap(track.evaluate)(jnp.asarray(points))
    amplitude = 1.3
    for got, want, tol in zip(out, smooth(points), (1e-6, 1e-4, 1e-2)):
        np.testing.assert_allclose(np.asarray(got[:, 0]), want, atol=tol * amplitude, rtol=0)
        np.testing.assert_allclose(np.asarray(got[:, 1]), -want, atol=tol * amplitude, rtol=0)


def test_spline_matches_scipy_natural_spline(getkey):
    s = 3.0 + 0.5 * np.arange(40)
    values = np.asarray(jr.normal(getkey(), (40, 3)))
    track = TrackIrregularity.from_samples(s, values)
    oracle = CubicSpline(s, values, bc_type="natural")
    points = np.linspace(s[0], s[-1], 333)
    out = jax.vmap(track.evaluate)(jnp.asarray(points))
    for order, got in enumerate(out):
        np.testing.assert_allclose(np.asarray(got), oracle(points, order), atol=1e-10)


def test_spline_is_c2_at_knots(getkey):
    s = 0.25 * np.arange(40)
    track = TrackIrregularity.from_samples(s, np.asarray(jr.normal(getkey(), (40, 3))))
    eps = 1e-7
    knots = jnp.asarray(s[1:-1])
    left = jax.vmap(track.evaluate)(knots - eps)
    right = jax.vmap(track.evaluate)(knots + eps)
    # jumps of O(eps * next derivative); a C0/C1-only spline would jump by O(1) in d2w
    for order, (a, b) in enumerate(zip(left, right)):
        assert np.max(np.abs(np.asarray(a - b))) < 1e-3 * 10**order, order


def test_zero_outside_and_perfect_track():
    track, s = smooth_track()
    for x in (s[0] - 1e-6, s[0] - 50.0, s[-1] + 1e-6, s[-1] + 1e3):
        for q in track.evaluate(x):
            assert np.all(np.asarray(q) == 0.0)
    assert np.all(np.asarray(track.evaluate(s[-1])[0]) != 0.0)
    perfect = perfect_track()
    for x in (-1.0, 0.0, 0.3, 1.0, 1e4):
        for q in perfect.evaluate(x):
            assert q.shape == (3,) and np.all(np.asarray(q) == 0.0)


def test_grad_through_evaluate():
    track, _ = smooth_track()
    s = 57.3
    ds_grad = jax.grad(lambda x: track.evaluate(x)[0][0])(s)
    np.testing.assert_allclose(ds_grad, track.evaluate(s)[1][0], rtol=1e-12)
    d2 = jax.grad(jax.grad(lambda x: track.evaluate(x)[0][1]))(s)
    np.testing.assert_allclose(d2, track.evaluate(s)[2][1], rtol=1e-10)

    def value_at(values):
        return TrackIrregularity(s0=track.s0, ds=track.ds, values=values).evaluate(s)[2].sum()

    g = jax.jit(jax.grad(value_at))(track.values)
    assert g.shape == track.values.shape and np.all(np.isfinite(np.asarray(g)))
    assert np.any(np.asarray(g) != 0.0)


@pytest.mark.parametrize(
    "distance, values, match",
    [
        ([0.0, 0.25, 0.5, 0.5], np.zeros((4, 3)), r"`distance` must be strictly increasing.*\[3\]"),
        ([0.0, 0.25, 0.5, 0.8], np.zeros((4, 3)), r"`distance` must be uniformly spaced.*\[3\]"),
        ([[0.0, 0.25]], np.zeros((2, 3)), r"`distance` must be 1-D"),
        ([0.0, 0.25], np.zeros((2, 2)), r"`values` must have shape \(2, 3\).*\(2, 2\)"),
        ([0.0, 0.25], [[0, 0, 0], [0, np.nan, 0]], r"`values` must be finite.*\[1, 1\] = nan"),
    ],
)
def test_from_samples_errors(distance, values, match):
    with pytest.raises(ValueError, match=match):
        TrackIrregularity.from_samples(distance, values)


def test_constructor_checks_shape():
    with pytest.raises(ValueError, match=r"`values` must have shape \(n, 3\).*\(5,\)"):
        TrackIrregularity(s0=0.0, ds=0.25, values=np.zeros(5))


# --- CSV --------------------------------------------------------------------------------------


def test_csv_round_trip(tmp_path, getkey):
    track = synthesise_track(ERRIB176Spectrum.low(), key=getkey(), length=SHORT, start=12.5)
    path = tmp_path / "track.csv"
    save_track_csv(path, track)
    back = load_track_csv(path)
    np.testing.assert_array_equal(np.asarray(back.values), np.asarray(track.values))
    np.testing.assert_allclose([back.s0, back.ds], [12.5, 0.25], rtol=1e-14)
    np.testing.assert_allclose(back.curvatures, track.curvatures, rtol=1e-9, atol=1e-15)


HEADER = "distance_m,alignment_m,vertical_m,cross_level_rad"


@pytest.mark.parametrize(
    "body, match",
    [
        ("0,0,0,0\n1,0,0,0\n", r"line 1: expected the header"),
        (f"{HEADER}\n0,0,0,0\n0.25,0,0,0\n0.6,0,0,0\n", r"line 4: `distance` must be uniformly"),
        (f"{HEADER}\n0,0,0,0\n0.25,0,0,0\n0.25,0,0,0\n", r"line 4: `distance` must be strictly"),
        (f"{HEADER}\n0,0,0,0\n# c\n0.25,0,0\n", r"line 4: expected 4 columns.*got 3"),
        (f"{HEADER}\n0,0,0,0\n0.25,0,nan,0\n", r"line 3, column 3 \(vertical_m\).*finite.*'nan'"),
        (f"{HEADER}\n0,0,0,0\n0.25,0,x,0\n", r"line 3, column 3 .*expected a finite number"),
        (f"# only\n{HEADER}\n0,0,0,0\n", r"at least 2 data rows"),
        ("# nothing here\n", r"expected the header"),
    ],
)
def test_csv_errors(tmp_path, body, match):
    path = tmp_path / "bad.csv"
    path.write_text(body)
    with pytest.raises(ValueError, match=match) as info:
        load_track_csv(path)
    assert str(path) in str(info.value)


def test_csv_comments_allowed(tmp_path):
    path = tmp_path / "ok.csv"
    path.write_text(f"# a\n\n{HEADER}\n# b\n0,1e-3,0,0\n0.5,0,2e-3,0\n1.0,0,0,1e-3\n")
    track = load_track_csv(path)
    assert track.values.shape == (3, 3) and float(track.ds) == 0.5
    np.testing.assert_allclose(track.evaluate(0.5)[0], [0.0, 2e-3, 0.0], atol=1e-18)
