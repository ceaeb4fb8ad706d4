"""What every command shares: the one-line usage error, the parser, comma lists, text tables and
progress lines. Standard library only (imported before JAX is set up)."""

import argparse
import time


class UsageError(Exception):
    """A bad command-line value (reported in one line, exit code 2)."""


class Parser(argparse.ArgumentParser):
    """An `ArgumentParser` whose errors are one line and exit code 2."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message}\n")


def split_names(text: str) -> list[str]:
    """`"a, b,,c"` -> `["a", "b", "c"]`."""
    return [t.strip() for t in text.split(",") if t.strip()]


def text_table(rows) -> str:
    """Rows of cells as aligned columns, the first row a header underlined with dashes."""
    widths = [max(len(str(r[i])) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(str(c).ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def require_suffix(option: str, value: str | None, *suffixes: str) -> None:
    """A `UsageError` unless `value` (if given) ends in one of `suffixes`."""
    if value is not None and not value.lower().endswith(suffixes):
        raise UsageError(f"`{option}` must end in {' or '.join(suffixes)}, got {value!r}")


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.1f} min"


class Progress:
    """Progress lines on stdout: `compiling(what)` before a compile, `done(n, total, note)`
    after each piece of work with the elapsed time and an ETA from the mean rate so far."""

    def __init__(self):
        self.t0 = time.perf_counter()
        self._work_t0 = None
        self._work_n0 = 0

    def elapsed(self) -> float:
        return time.perf_counter() - self.t0

    def say(self, text: str) -> None:
        print(text, flush=True)

    def compiling(self, what: str) -> None:
        self.say(f"compiling {what} ...")

    def start_work(self, n_done: int = 0) -> None:
        """Time the work (for the ETA) from now, with `n_done` pieces already done."""
        self._work_t0, self._work_n0 = time.perf_counter(), n_done

    def done(self, n: int, total: int, what: str, note: str = "", eta: float | None = None):
        """`n` of `total` `what` done, with `eta` [s] (default: from the mean rate since
        `start_work`, else since the start)."""
        if eta is None:
            start = self.t0 if self._work_t0 is None else self._work_t0
            rate = (n - self._work_n0) / max(time.perf_counter() - start, 1e-9)
            eta = (total - n) / rate if rate > 0 else float("nan")
        eta = "" if n >= total or not eta >= 0 else f", ETA {_duration(eta)}"
        extra = f", {note}" if note else ""
        self.say(f"  {what} {n}/{total} done{extra}, {_duration(self.elapsed())}{eta}")
