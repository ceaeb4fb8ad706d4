"""`HostFit` under the name `monitor`'s modules import it by; the Levenberg-Marquardt that makes
it, for `identify` and `monitor` alike, is `bogie_jax.identify.levenberg_marquardt_batch`."""

from ..identify import HostFit as HostFit
