"""`--candidates NAME...` and `--list-elements` of `monitor` and `demo`: the user chooses what is
judged, and the names are checked here, before anything compiles.

A candidate is any name `bogie_jax.monitor.MonitorOptions(candidates=...)` accepts: an element
(`yaw_dampers.left.c`), the tied name of a per-element field (`yaw_dampers.c`: all its elements
moving as one factor), or another parameter name (`bogie-jax identify --list-params`).
"""

from ..monitor import DEFAULT_CANDIDATES, check_candidates as check_monitor_candidates
from ..params import element_names, resolve_parameter
from ._common import UsageError


def add_options(p) -> None:
    """Add `--candidates` and `--list-elements` to the parser `p`."""
    p.add_argument(
        "--candidates",
        nargs="+",
        metavar="NAME",
        default=None,
        help="the elements judged, e.g. yaw_dampers.left.c primary.1L.kz; a tied name such as "
        "yaw_dampers.c judges all its elements as one (default: those marked `default` by "
        "--list-elements)",
    )
    p.add_argument(
        "--list-elements",
        action="store_true",
        help="print the names --candidates takes, one a line (each field's tied name, then its "
        "elements; the default candidates marked), then exit",
    )


def check_candidates(params, names) -> tuple[str, ...] | None:
    """`--candidates` as a tuple, or `None` (the default candidates) where it is not given.

    **Raises:** `UsageError` for an unknown name (with the nearest valid names) or a repeated
    one (`bogie_jax.monitor.check_candidates`)."""
    if names is None:
        return None
    try:
        return check_monitor_candidates(params, names, label="--candidates")
    except ValueError as e:
        raise UsageError(str(e)) from None


def list_elements(params) -> str:
    """The text of `--list-elements`: per field with elements, its tied name (noted `all as
    one`), then its elements, one name a line; the default candidates noted `default`."""
    fields: dict[str, list[str]] = {}
    for name in element_names(params):
        fields.setdefault(resolve_parameter(params, name).tied_name, []).append(name)
    rows = []
    for tied, elements in fields.items():
        rows.append((tied, "all as one"))
        rows += [(e, "default" if e in DEFAULT_CANDIDATES else "") for e in elements]
    width = max(len(name) for name, _ in rows)
    return "\n".join(f"{name.ljust(width)}  {note}".rstrip() for name, note in rows)
