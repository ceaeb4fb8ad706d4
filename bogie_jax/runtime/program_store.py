"""Traced batch programs kept across processes (`jax.export`), so that a later run of the same
batch skips JAX's tracing and lowering; the persistent compilation cache then skips XLA's
compile. Off unless a process turns it on (`use_program_store`: the command line does, in its
cache directory).

A program is stored under a SHA-256 key of everything it depends on: the caller's `identity`
(the static structure it closes over, pickled; an identity that does not pickle is not stored),
the structure, shapes, dtypes and shardings of the arguments, the source of this package, the
versions of JAX, jaxlib, equinox, diffrax, optimistix and lineax, float64 and equinox's error
mode. Only programs without host callbacks can be exported, so the store is used only where
equinox's runtime errors are NaNs (`EQX_ON_ERROR=nan`, as the command line sets). A program that
cannot be exported or read runs the usual way (a warning says why). The files are pickles:
point the store only at a directory of your own (the command line's cache directory).
"""

import functools
import hashlib
import importlib.metadata
import os
import pickle
import warnings
from pathlib import Path

import jax


_STORE: dict = {"directory": None}
_CALLS: dict = {}  # key -> (jit of the exported call, output structure), this process
SUFFIX = ".jaxexport"


def use_program_store(directory) -> None:
    """Keep exported batch programs in `directory` (None: off). Process set-up, not a library
    default (the command line calls it with its cache directory)."""
    _STORE["directory"] = None if directory is None else Path(directory)


def program_store_directory() -> Path | None:
    """Where exported batch programs are kept in this process (None: off)."""
    return _STORE["directory"]


@functools.cache
def _environment() -> bytes:
    root = Path(__file__).parent
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes())
    versions = []
    for name in ("jax", "jaxlib", "equinox", "diffrax", "optimistix", "lineax"):
        try:
            versions.append((name, importlib.metadata.version(name)))
        except importlib.metadata.PackageNotFoundError:
            versions.append((name, None))
    return pickle.dumps((digest.hexdigest(), versions), protocol=5)


def _error_mode() -> str:
    """The mode equinox read at its import (its private config; else the variable it reads)."""
    try:
        import equinox._config as eqx_config

        return eqx_config.EQX_ON_ERROR
    except (ImportError, AttributeError):  # another equinox layout: its documented variable
        return os.environ.get("EQX_ON_ERROR", "raise")


def program_key(identity, args) -> str | None:
    """The store's key of a program (see module docstring), or None if `identity` does not
    pickle."""
    try:
        who = pickle.dumps(identity, protocol=5)
    except Exception:  # closures, lambdas, arrays of a tracer: not stored
        return None
    leaves, treedef = jax.tree.flatten(args)
    avals = [(tuple(x.shape), str(x.dtype), repr(getattr(x, "sharding", None))) for x in leaves]
    context = (str(treedef), avals, jax.config.jax_enable_x64, _error_mode())
    digest = hashlib.sha256(who + _environment() + pickle.dumps(context, protocol=5))
    return digest.hexdigest()


def stored_program(jitted, args: tuple, identity):
    """`(call, out_tree)`: `call(*leaves)` runs `jitted(*args)` on the flat leaves of `args` from
    the exported program (loaded, or exported and written now) and `out_tree` rebuilds its
    output; None where the store is off or the program cannot be stored."""
    directory = _STORE["directory"]
    if directory is None or identity is None or _error_mode() != "nan":
        return None
    key = program_key(identity, args)
    if key is None:
        return None
    if key in _CALLS:
        return _CALLS[key]
    path = directory / f"{key}{SUFFIX}"
    try:
        if path.exists():
            blob, skeleton = pickle.loads(path.read_bytes())
            exported = jax.export.deserialize(bytearray(blob))
        else:
            exported, skeleton = _export(jitted, args)
            try:
                _write(path, pickle.dumps((exported.serialize(), skeleton), protocol=5))
            except OSError as error:  # e.g. a read-only cache: this run still uses the export
                warnings.warn(f"batch program not written ({error})", stacklevel=3)
        # the output's structure from its skeleton (a pickled tree with the leaf indices as
        # leaves: pickled tree definitions of equinox modules do not round-trip)
        out_tree = jax.tree.structure(skeleton)
        if out_tree.num_leaves != len(exported.out_avals):
            raise ValueError("the stored output structure does not match the program")
    except Exception as error:  # noqa: BLE001 - any failure: the usual path
        warnings.warn(f"batch program not stored ({type(error).__name__}: {error})", stacklevel=3)
        return None
    _CALLS[key] = (jax.jit(exported.call), out_tree)
    return _CALLS[key]


def _export(jitted, args):
    """The exported program of `jitted(*args)` on flat leaves, and its output's skeleton."""
    _, in_tree = jax.tree.flatten(args)
    out_trees = []

    def flat(*leaves):
        out = jitted(*jax.tree.unflatten(in_tree, leaves))
        leaves_out, tree = jax.tree.flatten(out)
        out_trees.append(tree)
        return leaves_out

    exported = jax.export.export(jax.jit(flat))(*jax.tree.leaves(args))
    tree = out_trees[0]
    return exported, jax.tree.unflatten(tree, list(range(tree.num_leaves)))


def _write(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)  # atomic: a concurrent reader sees the whole file or none
