"""The persistent compilation cache, turned on by one call: the command line makes it at start-up,
a notebook in its first cell (`bogie_jax.use_compilation_cache()`). Off unless a process turns it
on; importing the package changes no configuration.

Where: `$BOGIE_JAX_CACHE_DIR`, else `$XDG_CACHE_HOME/bogie_jax/jax`, else
`~/.cache/bogie_jax/jax`. JAX keys every entry by a SHA-256 hash of the program's StableHLO, the
compile options, the jax and jaxlib versions, the backend's platform and version and the device
kind and count (`jax._src.cache_key.get`), so an entry written by another JAX version or on
another machine is never read for this one; a changed program is a new entry, not a stale hit.
Every compiled program is written (no minimum compile time or size): most of ours take seconds.

JAX writes no program with host callbacks to the cache, and equinox's runtime checks (`error_if`,
diffrax's `throw`) are host callbacks in its default `raise` mode. So the solves, fits and
statistics are cached only where the process set `EQX_ON_ERROR=nan` before equinox was imported
(the command line does; a notebook does it in its first cell): a failed check then gives NaN,
which the results report (an unsuccessful solve, a failed start).
"""

import os
from pathlib import Path


def default_cache_dir(environ=os.environ) -> Path:
    """The per-user cache directory (standard library only: the command line asks before JAX
    is imported)."""
    if environ.get("BOGIE_JAX_CACHE_DIR"):
        return Path(environ["BOGIE_JAX_CACHE_DIR"]).expanduser()
    base = environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "bogie_jax" / "jax"


def use_compilation_cache(directory: str | os.PathLike | None = None) -> Path:
    """Turn on JAX's persistent compilation cache for this process, and the store of traced
    batch programs (`bogie_jax.runtime.program_store`) in its `programs/` folder, so that a second
    identical run skips tracing and XLA's compile. `directory`: None keeps the cache this process
    already set, with its settings (a test session's), else takes `default_cache_dir()`.
    Returns the directory."""
    import jax

    from .program_store import use_program_store

    current = jax.config.jax_compilation_cache_dir
    if directory is None and current is not None:
        directory = Path(current)
    else:
        directory = Path(directory if directory is not None else default_cache_dir()).expanduser()
        jax.config.update("jax_enable_compilation_cache", True)
        jax.config.update("jax_compilation_cache_dir", str(directory))
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
        jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)
    use_program_store(directory / "programs")
    return directory
