"""One-sided power spectral densities (PSDs) of the track irregularities.

Every spectrum maps the spatial angular frequency `omega` [rad/m] to the one-sided PSD of the three
track channels, in this order:

0. lateral alignment `d_y` [m^2/(rad/m)],
1. vertical level `d_z` [m^2/(rad/m)],
2. cross-level angle `gamma_d` [rad^2/(rad/m)] (positive = left rail higher).

One-sided means `variance = integral of S(omega) d omega over omega > 0` (reference doc 6.1 and
caveat 8.6: the one-sided reading reproduces the published RMS values). Cross level is always an
angle, `gamma_d = (z_left - z_right) / (2 b)` with `b` the half-distance between the contact
points (reference doc 6.1: 1.15 mrad corresponds to 1.7 mm over 1.5 m).
"""

import abc
import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float


def _as_float(x):
    """Python numbers become float64 numpy scalars (differentiable leaves); arrays pass through."""
    return np.asarray(x, dtype=float) if isinstance(x, int | float) else x


def _spectrum_field():
    return eqx.field(converter=_as_float)


def _check_positive_fields(spectrum: eqx.Module) -> None:
    """Every constant of a spectrum is finite and > 0 (values under tracing are skipped)."""
    for field in dataclasses.fields(spectrum):
        value = getattr(spectrum, field.name)
        if isinstance(value, jax.core.Tracer):
            continue
        v = np.asarray(value, dtype=float)
        if not np.all(np.isfinite(v) & (v > 0.0)):
            raise ValueError(
                f"`{type(spectrum).__name__}.{field.name}` must be finite and > 0; got {value!r}"
            )


class AbstractTrackPSD(eqx.Module):
    """Interface of a track irregularity spectrum (one-sided, per rad/m, three channels)."""

    @abc.abstractmethod
    def __call__(self, omega: ArrayLike) -> Float[Array, "*omega 3"]:
        """One-sided PSD at spatial angular frequency `omega` [rad/m].

        **Returns:** an array of shape `omega.shape + (3,)`: alignment and vertical level in
        m^2/(rad/m), cross-level angle in rad^2/(rad/m).
        """


# Shape constants shared by both ERRI levels (reference doc 6.1).
_ERRI_SHAPE = dict(omega_c=0.8246, omega_r=0.0206, omega_s=0.4380, b=0.75)


class ERRIB176Spectrum(AbstractTrackPSD):
    """ERRI B176 (German "low/high disturbance") spectra (reference doc 6.1).

    With `D = (omega^2 + omega_r^2)(omega^2 + omega_c^2)`:

    - alignment: `S_a = A_a omega_c^2 / D`
    - vertical: `S_v = A_v omega_c^2 / D`
    - cross level (angle): `S_c = (A_v / b^2) omega_c^2 omega^2 / (D (omega^2 + omega_s^2))`

    **Fields:** `A_v`, `A_a` [m^2 rad/m]; `omega_c`, `omega_r`, `omega_s` [rad/m]; `b` [m], half
    the distance between the contact points.

    All constants are tagged [S] in the reference doc (several public sources, consistent).
    Use `ERRIB176Spectrum.low()` or `ERRIB176Spectrum.high()`.
    """

    A_v: float = _spectrum_field()
    A_a: float = _spectrum_field()
    omega_c: float = _spectrum_field()
    omega_r: float = _spectrum_field()
    omega_s: float = _spectrum_field()
    b: float = _spectrum_field()

    def __check_init__(self):
        _check_positive_fields(self)

    @classmethod
    def low(cls) -> "ERRIB176Spectrum":
        """Low disturbance level (reference doc 6.1)."""
        return cls(A_v=4.032e-7, A_a=2.119e-7, **_ERRI_SHAPE)

    @classmethod
    def high(cls) -> "ERRIB176Spectrum":
        """High disturbance level (reference doc 6.1)."""
        return cls(A_v=1.080e-6, A_a=6.125e-7, **_ERRI_SHAPE)

    def __call__(self, omega: ArrayLike) -> Float[Array, "*omega 3"]:
        w2 = jnp.square(jnp.asarray(omega))
        base = self.omega_c**2 / ((w2 + self.omega_r**2) * (w2 + self.omega_c**2))
        cross = (self.A_v / self.b**2) * base * w2 / (w2 + self.omega_s**2)
        return jnp.stack([self.A_a * base, self.A_v * base, cross], axis=-1)


class FRASpectrum(AbstractTrackPSD):
    """US FRA track-class spectra, classes 1-6 (reference doc 6.2).

    - alignment: `S_a = k A_a omega_c^2 / (omega^2 (omega^2 + omega_c^2))`
    - vertical: `S_v = k A_v omega_c^2 / (omega^2 (omega^2 + omega_c^2))`
    - cross level: the height difference `u` between the rails has
      `S_u = 4 k A_v omega_c^2 / ((omega^2 + omega_c^2)(omega^2 + omega_s^2))` [m^2/(rad/m)]; it is
      returned as the angle `gamma_d = u / (2 b)`, so `S_c = S_u / (2 b)^2`. This is the same
      angle convention as ERRI (reference doc 6.1, `b` = 0.75 m is the half-distance, the base
      length `b_ref` of reference doc 6.2 is the full distance `2 b` = 1.5 m).

    **Fields:** `A_v`, `A_a` [m^2 rad/m] (the tabulated cm^2 rad/m times 1e-4); `omega_c`,
    `omega_s` [rad/m]; `k` [-]; `b` [m].

    Constants marked [M] (from memory, NOT verified) in the reference doc: `A_a` of classes 1-4
    and `omega_s` of all classes (hence the whole cross-level channel). `A_v` (all classes),
    `A_a` (classes 5-6), `k` and `omega_c` are tagged [S]. The cross-level formula itself is
    "theory only" in its source. Use `FRASpectrum.track_class(n)`.
    """

    A_v: float = _spectrum_field()
    A_a: float = _spectrum_field()
    omega_c: float = _spectrum_field()
    omega_s: float = _spectrum_field()
    k: float = _spectrum_field()
    b: float = _spectrum_field()

    def __check_init__(self):
        _check_positive_fields(self)

    @classmethod
    def track_class(cls, n: int) -> "FRASpectrum":
        """FRA track class `n` in 1..6 (6 is the best track; reference doc 6.2).

        **Raises:** `ValueError` if `n` is not an integer in 1..6.
        """
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or not 1 <= n <= 6:
            raise ValueError(f"`n` must be an FRA track class, an integer in 1..6; got {n!r}")
        a_v, a_a, omega_s = _FRA_CLASSES[int(n)]
        cm2_to_m2 = 1e-4
        return cls(
            A_v=a_v * cm2_to_m2,
            A_a=a_a * cm2_to_m2,
            omega_c=0.8245,
            omega_s=omega_s,
            k=0.25,
            b=0.75,
        )

    def __call__(self, omega: ArrayLike) -> Float[Array, "*omega 3"]:
        w2 = jnp.square(jnp.asarray(omega))
        base = self.k * self.omega_c**2 / (w2 * (w2 + self.omega_c**2))
        height = (
            4.0
            * self.k
            * self.A_v
            * self.omega_c**2
            / ((w2 + self.omega_c**2) * (w2 + self.omega_s**2))
        )
        cross = height / (2.0 * self.b) ** 2
        return jnp.stack([self.A_a * base, self.A_v * base, cross], axis=-1)


# class: (A_v [cm^2 rad/m], A_a [cm^2 rad/m], omega_s [rad/m]), reference doc 6.2 table.
_FRA_CLASSES = {
    1: (1.2107, 3.3634, 0.6046),
    2: (1.0181, 1.2107, 0.9308),
    3: (0.6816, 0.4128, 0.8520),
    4: (0.5376, 0.3027, 1.1312),
    5: (0.2095, 0.0762, 0.8209),
    6: (0.0339, 0.0339, 0.4380),
}


class FlatSpectrum(AbstractTrackPSD):
    """A white spectrum: one constant one-sided PSD per channel at every frequency.

    `S(omega) = (A_a, A_v, A_c)` for every `omega`. Synthesised over a wavelength band
    (`synthesise_track(..., wavelength_band=...)`) it gives band-limited white irregularity,
    whose variance is the level times the band's width in rad/m,
    `sigma^2 = A (2 pi / lambda_min - 2 pi / lambda_max)` (the one-sided convention of this
    module): a model of an irregularity, or of a measurement error, that is not shaped like a
    track spectrum (e.g. a recording system's sensor noise within its recording band).

    **Fields:** `alignment`, `vertical` [m^2/(rad/m)]; `cross_level` [rad^2/(rad/m)]. Build one
    from RMS values over a band with `FlatSpectrum.with_rms`.
    """

    alignment: float = _spectrum_field()
    vertical: float = _spectrum_field()
    cross_level: float = _spectrum_field()

    def __check_init__(self):
        _check_positive_fields(self)

    @classmethod
    def with_rms(
        cls,
        alignment: float,
        vertical: float,
        cross_level: float,
        wavelength_band: tuple[float, float] = (3.0, 70.0),
    ) -> "FlatSpectrum":
        """The levels whose variance over `wavelength_band` `(lambda_min, lambda_max)` [m] is
        each channel's RMS squared: `alignment`, `vertical` [m], `cross_level` [rad], each > 0.

        **Raises:** `ValueError` for a band that is not `0 < lambda_min < lambda_max < inf` or
        an RMS that is not finite and > 0.
        """
        lam_min, lam_max = (float(x) for x in wavelength_band)
        if not 0.0 < lam_min < lam_max < np.inf:
            raise ValueError(
                f"`wavelength_band` must satisfy 0 < lambda_min < lambda_max < inf [m]; "
                f"got {wavelength_band!r}"
            )
        width = 2.0 * np.pi / lam_min - 2.0 * np.pi / lam_max  # [rad/m]
        rms = {"alignment": alignment, "vertical": vertical, "cross_level": cross_level}
        for name, value in rms.items():
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"RMS `{name}` = {value!r} must be finite and > 0")
        return cls(**{name: float(value) ** 2 / width for name, value in rms.items()})

    def __call__(self, omega: ArrayLike) -> Float[Array, "*omega 3"]:
        levels = jnp.stack([self.alignment, self.vertical, self.cross_level])
        return jnp.ones_like(jnp.asarray(omega, dtype=levels.dtype))[..., None] * levels
