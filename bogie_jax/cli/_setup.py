"""Process setup of the command line, done before JAX is imported (standard library only).

- Every core: on a CPU host, `XLA_FLAGS=--xla_force_host_platform_device_count=<cores>` exposes
  each core as an XLA device (the batch runners shard over devices). Left alone when the user set
  `XLA_FLAGS`, when JAX is already imported (it would have no effect), or when an accelerator is
  hinted: `JAX_PLATFORMS` naming anything but `cpu`, a `CUDA_VISIBLE_DEVICES`,
  `HIP_VISIBLE_DEVICES`, `ROCR_VISIBLE_DEVICES` or `TPU_VISIBLE_CHIPS` that selects devices, or
  a GPU/TPU device node (`/dev/nvidia0`, `/dev/kfd`, `/dev/accel0`). JAX cannot be asked without
  importing it, and XLA reads the flag once, at import.
- The persistent compilation cache (`bogie_jax.use_compilation_cache`: `$BOGIE_JAX_CACHE_DIR`,
  else `$XDG_CACHE_HOME/bogie_jax/jax`, else `~/.cache/bogie_jax/jax`, every program written);
  `--no-cache` turns it off. Left alone when the caller already set a cache directory.
- `EQX_ON_ERROR=nan` (unless set): JAX never writes a program with host callbacks to the cache,
  and equinox's runtime checks (`error_if`, diffrax's `throw`) are host callbacks in its default
  `raise` mode; with `nan` a failed check gives NaN instead, which the commands report (failed
  starts, an unsuccessful solve). Without it the solves, fits and statistics are never cached.
- With it, the traced batch programs (multistart fits, `bogie_jax.runtime.program_store`) in
  `programs/` of the cache directory, so that a second identical run also skips JAX's tracing.

The library itself changes no global configuration; only `bogie_jax.cli.main` calls this.
"""

import dataclasses
import os
import sys
from pathlib import Path

from ..runtime.cores import core_count


_ACCELERATOR_VARIABLES = (
    "CUDA_VISIBLE_DEVICES",
    "HIP_VISIBLE_DEVICES",
    "ROCR_VISIBLE_DEVICES",
    "TPU_VISIBLE_CHIPS",
)
_ACCELERATOR_NODES = ("/dev/nvidia0", "/dev/kfd", "/dev/accel0")


@dataclasses.dataclass(frozen=True)
class Setup:
    """What `prepare` decided: the host device count it set (or None) and the cache directory
    (None: no cache)."""

    host_devices: int | None
    cache_dir: Path | None


def accelerator_hinted(environ=os.environ) -> bool:
    """Whether the environment points at a GPU or TPU (see the module docstring)."""
    platforms = [p.strip() for p in environ.get("JAX_PLATFORMS", "").split(",") if p.strip()]
    if platforms:
        return any(p != "cpu" for p in platforms)
    for name in _ACCELERATOR_VARIABLES:
        value = environ.get(name, "").strip()
        if value and value not in ("-1", "none", "NoDevFiles"):
            return True
    return any(os.path.exists(node) for node in _ACCELERATOR_NODES)


def prepare(*, use_cache: bool) -> Setup:
    """Set `XLA_FLAGS` (before JAX is imported) and configure JAX: float64 and the cache."""
    if "matplotlib" not in sys.modules:
        os.environ.setdefault("MPLBACKEND", "Agg")  # figures go to files
    if "equinox" not in sys.modules:
        os.environ.setdefault("EQX_ON_ERROR", "nan")  # read by equinox at import
    devices = None
    if "jax" not in sys.modules and "XLA_FLAGS" not in os.environ and not accelerator_hinted():
        devices = core_count()
        os.environ["XLA_FLAGS"] = f"--xla_force_host_platform_device_count={devices}"
    import jax  # after XLA_FLAGS: XLA reads it when JAX loads

    jax.config.update("jax_enable_x64", True)
    directory = None
    if use_cache:
        from ..runtime.compilation_cache import use_compilation_cache

        directory = use_compilation_cache()  # a cache the caller set (a test session's) wins
    else:
        from ..runtime.program_store import use_program_store

        jax.config.update("jax_enable_compilation_cache", False)
        use_program_store(None)
    return Setup(devices, directory)


def describe(setup: Setup, version: str) -> str:
    """The first line of every command, e.g.
    `bogie-jax 0.1.0 on 2 CPU devices (float64, cache ~/.cache/bogie_jax/jax)`."""
    import jax

    devices = jax.devices()
    kinds = sorted({d.platform.upper() for d in devices})
    plural = "s" if len(devices) != 1 else ""
    dtype = "float64" if jax.config.jax_enable_x64 else "float32"
    cache = "no cache" if setup.cache_dir is None else f"cache {_home(setup.cache_dir)}"
    on = f"{len(devices)} {'/'.join(kinds)} device{plural}"
    return f"bogie-jax {version} on {on} ({dtype}, {cache})"


def _home(path: Path) -> str:
    home = Path.home()
    try:
        return "~/" + str(path.resolve().relative_to(home.resolve()))
    except ValueError:
        return str(path)
