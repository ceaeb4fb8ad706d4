"""`TrackReference`: a typed, serialisable description of the track a run went over.

A reference names either a synthetic realisation (spectrum, PRNG seed, length, wavelength band)
or a measured irregularity file, and rebuilds the `TrackIrregularity` from it. Measurements and
results store it as structured metadata (`to_dict` / `from_dict`), never as free text.
"""

import dataclasses
import math

import jax.random as jr

from ._irregularity import TrackIrregularity, perfect_track
from ._psd import AbstractTrackPSD, ERRIB176Spectrum, FRASpectrum
from ._synthesis import synthesise_track


SPECTRA = ("erri-low", "erri-high", *(f"fra-{k}" for k in range(1, 7)))
"""Names of the built-in spectra (ERRI B176 low/high, FRA classes 1-6)."""
PERFECT = "perfect"
DEFAULT_BAND = (3.0, 70.0)  # [m] wavelength band of synthesised tracks
RUN_MARGIN = 50.0  # [m] extra track beyond the distance a run covers


def spectrum_from_name(name: str) -> AbstractTrackPSD:
    """`erri-low`, `erri-high` or `fra-1` ... `fra-6` -> a track PSD."""
    if name == "erri-low":
        return ERRIB176Spectrum.low()
    if name == "erri-high":
        return ERRIB176Spectrum.high()
    if name in SPECTRA:
        return FRASpectrum.track_class(int(name[4:]))
    raise ValueError(
        f"`spectrum` = {name!r} is not a known spectrum; valid: {', '.join(SPECTRA)}, {PERFECT}"
    )


@dataclasses.dataclass(frozen=True)
class TrackReference:
    """Which track a run went over.

    - `spectrum`: a name of `SPECTRA`, `"perfect"`, or `None` for a measured `file`;
    - `seed`: PRNG seed of the random phases (synthetic tracks);
    - `length` [m]: length of the synthesised track;
    - `band`: `(lambda_min, lambda_max)` [m], the synthesised wavelength band;
    - `file`: path of a measured irregularity CSV (`bogie_jax.io.load_track_csv` format).
    """

    spectrum: str | None = "erri-low"
    seed: int = 0
    length: float = 200.0
    band: tuple[float, float] = DEFAULT_BAND
    file: str | None = None

    def __post_init__(self):
        if (self.spectrum is None) == (self.file is None):
            raise ValueError(
                f"a TrackReference names exactly one of `spectrum` and `file`; got "
                f"spectrum={self.spectrum!r}, file={self.file!r}"
            )
        if self.spectrum is not None and self.spectrum != PERFECT:
            spectrum_from_name(self.spectrum)
        if not (math.isfinite(self.length) and self.length > 0):
            raise ValueError(f"`length` = {self.length!r} m must be finite and > 0")
        lo, hi = self.band
        if not 0 < lo < hi:
            raise ValueError(f"`band` = {self.band!r} m must satisfy 0 < lambda_min < lambda_max")
        object.__setattr__(self, "band", (float(lo), float(hi)))
        object.__setattr__(self, "length", float(self.length))
        object.__setattr__(self, "seed", int(self.seed))

    @classmethod
    def for_run(
        cls, spectrum: str, *, seed: int, speed: float, duration: float, wheelbase: float, **kw
    ) -> "TrackReference":
        """A synthetic track long enough for a run of `duration` [s] at `speed` [m/s]: the
        distance travelled plus the `wheelbase` [m] (the rear wheelset runs behind) and a
        50 m margin. A `spectrum` ending in `.csv` is taken as a `file`."""
        if spectrum.lower().endswith(".csv"):
            return cls(spectrum=None, file=spectrum)
        length = speed * duration + wheelbase + RUN_MARGIN
        return cls(spectrum=spectrum, seed=seed, length=length, **kw)

    def build(self) -> TrackIrregularity:
        """The synthetic `TrackIrregularity` this reference describes (a `file` reference is read
        by `bogie_jax.io.load_track`: only `io` touches files)."""
        if self.file is not None:
            raise ValueError(
                f"track reference {self.describe()!r} names a file: read it with "
                "`bogie_jax.io.load_track`"
            )
        if self.spectrum == PERFECT:
            return perfect_track()
        psd = spectrum_from_name(self.spectrum)
        return synthesise_track(
            psd, key=jr.PRNGKey(self.seed), length=self.length, wavelength_band=self.band
        )

    def describe(self) -> str:
        """One line for people, e.g. `erri-low, seed 0, 150 m, 3-70 m wavelengths`."""
        if self.file is not None:
            return f"file {self.file}"
        if self.spectrum == PERFECT:
            return PERFECT
        lo, hi = self.band
        return f"{self.spectrum}, seed {self.seed}, {self.length:g} m, {lo:g}-{hi:g} m wavelengths"

    def to_dict(self) -> dict:
        """JSON-ready metadata (inverse of `from_dict`)."""
        return {
            "spectrum": self.spectrum,
            "seed": self.seed,
            "length_m": self.length,
            "band_m": list(self.band),
            "file": self.file,
        }

    @classmethod
    def from_dict(cls, data: dict) -> "TrackReference":
        """Read `to_dict` output. **Raises:** `ValueError` naming a missing or bad key."""
        try:
            return cls(
                spectrum=data["spectrum"],
                seed=int(data["seed"]),
                length=float(data["length_m"]),
                band=tuple(data["band_m"]),
                file=data["file"],
            )
        except KeyError as e:
            raise ValueError(f"track reference without the key {e.args[0]!r}: {data!r}") from None
