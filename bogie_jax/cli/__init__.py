"""The `bogie-jax` command line: one module per command (`simulate`, `critical_speed`, `demo`,
`gradcheck`, `identify`, `sensitivity`, `monitor`, `fleet`), each with `add_parser(subparsers)` and
`run(args, progress)`.

`main` sets the process up before JAX is imported (every CPU core as a device, the persistent
compilation cache; see `_setup`) and prints what it runs on as its first line. Every option has
a default and `--help` gives units; bad values get a one-line error and exit code 2.
"""

import argparse
import importlib
import sys

from .._version import VERSION
from . import _setup
from ._common import Parser as Parser, Progress as Progress, UsageError as UsageError


COMMANDS = {
    "simulate": "simulate",
    "critical-speed": "critical_speed",
    "demo": "demo",
    "gradcheck": "gradcheck",
    "identify": "identify",
    "sensitivity": "sensitivity",
    "monitor": "monitor",
    "contact": "contact",
    "fleet": "fleet",
}
"""Command name -> module of `bogie_jax.cli`."""


def _global_flags(parser, default) -> None:
    parser.add_argument(
        "--no-cache",
        action="store_true",
        default=default,
        help="do not use the persistent compilation cache (default: $BOGIE_JAX_CACHE_DIR, else "
        "$XDG_CACHE_HOME/bogie_jax/jax or ~/.cache/bogie_jax/jax)",
    )


def _wants_cache(argv) -> bool:
    """`--no-cache` read before JAX is imported (the full parser needs the command modules)."""
    pre = Parser(add_help=False)
    _global_flags(pre, False)
    known, _ = pre.parse_known_args(argv)
    return not known.no_cache


def _command_modules():
    # Deferred on purpose: the command modules import JAX, which must load only after
    # `_setup.prepare` has set XLA_FLAGS (not a cycle: nothing imports this package back).
    return {name: importlib.import_module(f".{mod}", __name__) for name, mod in COMMANDS.items()}


def build_parser(modules=None) -> Parser:
    """The whole `bogie-jax` parser (imports the command modules, hence JAX)."""
    modules = modules or _command_modules()
    parser = Parser(prog="bogie-jax", description="Railway bogie dynamics and identification.")
    _global_flags(parser, False)
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for module in modules.values():
        _global_flags(module.add_parser(sub), argparse.SUPPRESS)  # also after the command
    return parser


def main(argv=None) -> int:
    """Entry point of the `bogie-jax` console script; returns the exit code."""
    argv = sys.argv[1:] if argv is None else list(argv)
    setup = _setup.prepare(use_cache=_wants_cache(argv))
    modules = _command_modules()
    args = build_parser(modules).parse_args(argv)
    progress = Progress()
    progress.say(_setup.describe(setup, VERSION))
    try:
        return modules[args.command].run(args, progress)
    except UsageError as e:
        print(f"bogie-jax {args.command}: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
