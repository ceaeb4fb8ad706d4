"""What the command-line tests of `monitor` share: a measurement file of zeros and the exit
code of a command (argparse's own errors included). Nothing here simulates or compiles."""

from bogie_jax.cli import main
from bogie_jax.io import save_measurement
from bogie_jax.measure import default_sensor_layout
from bogie_jax.params import manchester_benchmark


try:
    from blank_data import blank_measurement
except ImportError:  # tests/ imported as a package
    from tests.blank_data import blank_measurement


def blank_file(path, channels=None, speed=30.0) -> str:
    """A measurement file of zeros at `path` (51 samples at 100 Hz on the default layout, or
    its `channels`, at `speed` [m/s], on an ERRI-low track of 100 m); returns the path."""
    sensors = default_sensor_layout(manchester_benchmark())
    if channels is not None:
        sensors = tuple(s for s in sensors if s.name in channels)
    m = blank_measurement(sensors, n=51, rate=100.0, speed=speed, track_length=100.0)
    return str(save_measurement(path, m))


def exit_code(argv) -> int:
    """`bogie-jax ARGV`'s exit code (argparse's `SystemExit` included)."""
    try:
        return main(argv)
    except SystemExit as e:
        return e.code
