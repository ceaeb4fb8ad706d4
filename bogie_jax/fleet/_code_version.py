"""The code version stored with every run and judgement: the package version and, in a git
checkout, the commit (`+dirty` with uncommitted changes)."""

import functools
import subprocess
from pathlib import Path

from .._version import VERSION


@functools.cache
def code_version() -> str:
    """E.g. `0.1.0+g0924a65` (a checkout), `0.1.0` (an installed package)."""
    root = Path(__file__).resolve().parents[2]
    if not (root / ".git").exists():
        return VERSION
    try:
        commit = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "--short", "HEAD"],
            capture_output=True, text=True, timeout=10, check=True,
        ).stdout.strip()  # fmt: skip
        dirty = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True, text=True, timeout=10, check=True,
        ).stdout.strip()  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return VERSION
    return f"{VERSION}+g{commit}{'.dirty' if dirty else ''}"
