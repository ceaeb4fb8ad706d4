"""Track irregularities: spectra, random synthesis, and the sampled C2 track model.

Channels, always in this order: 0 = lateral alignment `d_y` [m], 1 = vertical level `d_z` [m],
2 = cross-level angle `gamma_d` [rad] (positive = left rail higher).
"""

from ._calibration import calibrated_record as calibrated_record, wiener_gain as wiener_gain
from ._irregularity import (
    TrackIrregularity as TrackIrregularity,
    TrackSampleError as TrackSampleError,
    perfect_track as perfect_track,
)
from ._psd import (
    AbstractTrackPSD as AbstractTrackPSD,
    ERRIB176Spectrum as ERRIB176Spectrum,
    FlatSpectrum as FlatSpectrum,
    FRASpectrum as FRASpectrum,
)
from ._reference import (
    SPECTRA as SPECTRA,
    TrackReference as TrackReference,
    spectrum_from_name as spectrum_from_name,
)
from ._synthesis import (
    FADE_LENGTH as FADE_LENGTH,
    band_variance as band_variance,
    fade_envelope as fade_envelope,
    synthesise_track as synthesise_track,
)
