"""Random track irregularities from a one-sided PSD, and the PSD's variance over a band.

Wavelength bands `(lambda_min, lambda_max)` [m] map to the spatial angular frequency band
`[2 pi / lambda_max, 2 pi / lambda_min]` [rad/m].
"""

import math

import equinox as eqx
import jax.numpy as jnp
import jax.random as jr
import numpy as np
from jaxtyping import Array, Float, PRNGKeyArray

from ._irregularity import TrackIrregularity
from ._psd import AbstractTrackPSD


# Gauss-Legendre rule on [-1, 1] used for every PSD integral in this module.
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(8)
# Log-spaced panels used by `band_variance`.
_NUM_PANELS = 128
# Frequency resolution of the synthesis: at least this many FFT bins inside the band.
_MIN_BINS_IN_BAND = 4096
FADE_LENGTH = 20.0  # [m]: the default fade-in and fade-out of a synthesised track


def _panel_integrals(psd: AbstractTrackPSD, lo: Array, hi: Array) -> Float[Array, "k 3"]:
    """Integral of `psd` over each interval `[lo[j], hi[j]]` [rad/m] (8-point Gauss-Legendre)."""
    half = 0.5 * (hi - lo)
    mid = 0.5 * (hi + lo)
    omega = mid[:, None] + half[:, None] * jnp.asarray(_GL_NODES)
    return half[:, None] * jnp.einsum("q,kqc->kc", jnp.asarray(_GL_WEIGHTS), psd(omega))


def band_variance(
    psd: AbstractTrackPSD, wavelength_band: tuple[float, float] = (3.0, 70.0)
) -> Float[Array, "3"]:
    """Variance of each channel over a wavelength band: the integral of the one-sided PSD.

    `sigma^2 = integral of S(omega) d omega` over `[2 pi / lambda_max, 2 pi / lambda_min]`
    (reference doc 6.1, 6.3), by Gauss-Legendre quadrature on log-spaced panels.

    **Arguments:** `psd`; `wavelength_band`: `(lambda_min, lambda_max)` [m].

    **Returns:** shape `(3,)`: alignment [m^2], vertical [m^2], cross level [rad^2].
    """
    _check_psd(psd)
    omega_lo, omega_hi = _check_band(wavelength_band)
    edges = np.exp(np.linspace(math.log(omega_lo), math.log(omega_hi), _NUM_PANELS + 1))
    return _summed_integrals(psd, edges[:-1], edges[1:])


@eqx.filter_jit
def _summed_integrals(psd, lo, hi) -> Float[Array, "3"]:
    return jnp.sum(_panel_integrals(psd, lo, hi), axis=0)


def synthesise_track(
    psd: AbstractTrackPSD,
    *,
    key: PRNGKeyArray,
    length: float,
    spacing: float = 0.25,
    wavelength_band: tuple[float, float] = (3.0, 70.0),
    fade_length: float = FADE_LENGTH,
    start: float = 0.0,
) -> TrackIrregularity:
    """A random track realisation with the one-sided spectrum `psd` inside a wavelength band.

    Random-phase cosine sum on the FFT frequency grid (reference doc 6.3):
    `w(s) = sum_k sqrt(2 P_k) cos(omega_k (s - start) + theta_k)`, `theta_k ~ U[0, 2 pi)`
    independent for every bin and channel, `P_k` the integral of the PSD over bin `k`
    intersected with the band, so the expected variance of each channel equals
    `band_variance(psd, wavelength_band)`. Evaluated by one inverse real FFT whose length gives at
    least 4096 bins inside the band (zero-padded beyond the track). The ends are multiplied by a
    quintic smoothstep over `fade_length` (reference doc 6.3), so the first and last samples are
    exactly zero and a vehicle starting at rest at `start` sees no step.

    **Arguments:**

    - `psd`: the spectrum.
    - `key`: JAX PRNG key (the only source of randomness).
    - `length`: track length [m]; samples at `start + j spacing` for `0 <= j spacing <= length`.
    - `spacing`: sample spacing [m]; must satisfy `spacing < lambda_min / 2` (Nyquist).
    - `wavelength_band`: `(lambda_min, lambda_max)` [m], `0 < lambda_min < lambda_max`.
    - `fade_length`: fade-in and fade-out length [m], `0 <= 2 fade_length <= length`.
    - `start`: distance of the first sample [m].

    `length`, `spacing`, `wavelength_band` and `fade_length` are Python numbers (static under
    `jit`); `key`, `psd` and `start` may be traced (e.g. `vmap` over keys).

    **Returns:** a `TrackIrregularity`.

    **Raises:** `ValueError` for invalid arguments, before any computation.
    """
    _check_psd(psd)
    omega_lo, omega_hi = _check_band(wavelength_band)
    num = _check_grid(length, spacing, fade_length, wavelength_band)
    spacing, fade_length = float(spacing), float(fade_length)
    num_fft = _fft_length(num, spacing, omega_lo, omega_hi)

    omega = 2.0 * math.pi * np.arange(num_fft // 2 + 1) / (num_fft * spacing)
    d_omega = omega[1]
    lo = np.clip(omega - 0.5 * d_omega, omega_lo, omega_hi)
    hi = np.clip(omega + 0.5 * d_omega, omega_lo, omega_hi)
    # DC gets nothing (omega_lo >= 2 d_omega); the last bin below Nyquist takes the band's top
    # end, the Nyquist bin nothing, so the bins tile the band exactly.
    hi[-2] = omega_hi
    lo[-1] = hi[-1] = omega_hi
    envelope = fade_envelope(spacing * np.arange(num), fade_length)
    values = _random_field(psd, key, lo, hi, envelope, num_fft)
    return TrackIrregularity(s0=start, ds=spacing, values=values)


@eqx.filter_jit
def _random_field(psd, key, lo, hi, envelope, num_fft: int) -> Float[Array, "n 3"]:
    """Cosine sum over the FFT bins `[lo, hi]` [rad/m] with random phases, times `envelope`."""
    power = _panel_integrals(psd, lo, hi)  # (bins, 3), integral of the PSD per bin
    theta = jr.uniform(key, power.shape, dtype=power.dtype, maxval=2.0 * math.pi)
    spectrum = (0.5 * num_fft) * jnp.sqrt(2.0 * power) * jnp.exp(1j * theta)
    raw = jnp.fft.irfft(spectrum, n=num_fft, axis=0)[: envelope.shape[0]]
    return raw * envelope[:, None]


def fade_envelope(s_local: np.ndarray, fade_length: float) -> np.ndarray:
    """The envelope of a synthesised track at the distances `s_local` [m] from its start (the
    last its end): 1 in the middle, a quintic smoothstep over `fade_length` [m] at both ends (0
    at the ends)."""
    if fade_length == 0.0:
        return np.ones(s_local.shape)
    rise = _smoothstep5(s_local / fade_length)
    fall = _smoothstep5((s_local[-1] - s_local) / fade_length)
    return rise * fall


def _smoothstep5(u: np.ndarray) -> np.ndarray:
    """Quintic smoothstep `6u^5 - 15u^4 + 10u^3` on `u` clipped to [0, 1] (reference doc 6.3)."""
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10.0 + u * (-15.0 + 6.0 * u))


def _fft_length(num: int, spacing: float, omega_lo: float, omega_hi: float) -> int:
    """Power of two >= `num` whose bin width is <= band / 4096 and <= omega_lo / 2."""
    d_omega = min((omega_hi - omega_lo) / _MIN_BINS_IN_BAND, 0.5 * omega_lo)
    needed = max(num, math.ceil(2.0 * math.pi / (spacing * d_omega)))
    return 1 << (needed - 1).bit_length()


def _check_psd(psd) -> None:
    if not isinstance(psd, AbstractTrackPSD):
        raise TypeError(f"`psd` must be an AbstractTrackPSD; got {type(psd).__name__}")


def _check_band(wavelength_band) -> tuple[float, float]:
    """Validate `(lambda_min, lambda_max)` [m]; return the band in rad/m."""
    try:
        lam_min, lam_max = (float(x) for x in wavelength_band)
    except (TypeError, ValueError):
        raise ValueError(
            f"`wavelength_band` must be a pair (lambda_min, lambda_max) in m; "
            f"got {wavelength_band!r}"
        ) from None
    if not (0.0 < lam_min < lam_max < math.inf):
        raise ValueError(
            f"`wavelength_band` must satisfy 0 < lambda_min < lambda_max < inf [m]; "
            f"got {wavelength_band!r}"
        )
    return 2.0 * math.pi / lam_max, 2.0 * math.pi / lam_min


def _check_grid(length, spacing, fade_length, wavelength_band) -> int:
    """Validate the sampling arguments; return the number of samples."""
    length = _number("length", length)
    spacing = _number("spacing", spacing)
    fade_length = _number("fade_length", fade_length)
    for name, value in (("length", length), ("spacing", spacing)):
        if not 0.0 < value < math.inf:
            raise ValueError(f"`{name}` must be a finite number > 0 [m]; got {value!r}")
    lam_min = float(wavelength_band[0])
    if not spacing < 0.5 * lam_min:
        raise ValueError(
            f"`spacing` must be < lambda_min / 2 = {0.5 * lam_min!r} m (Nyquist, "
            f"reference doc 6.3); got {spacing!r}"
        )
    if not length >= spacing:
        raise ValueError(f"`length` must be >= `spacing` = {spacing!r} m; got {length!r}")
    num = int(math.floor(length / spacing * (1.0 + 1e-12))) + 1
    span = (num - 1) * spacing
    if not 0.0 <= 2.0 * fade_length <= span:
        raise ValueError(
            f"`fade_length` must satisfy 0 <= 2 fade_length <= {span!r} m (the sampled "
            f"length); got {fade_length!r}"
        )
    return num


def _number(name: str, value) -> float:
    """`value` as a Python float, or a `ValueError` naming the argument."""
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"`{name}` must be a real number (static); got {value!r}") from None
