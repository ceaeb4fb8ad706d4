"""The package's version, from its installed metadata (`bogie_jax.__version__`)."""

import importlib.metadata


try:
    VERSION = importlib.metadata.version("bogie-jax")
except importlib.metadata.PackageNotFoundError:  # a source checkout on `sys.path`, not installed
    VERSION = "unknown (not installed)"
