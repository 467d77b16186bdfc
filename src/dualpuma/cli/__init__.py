"""The ``dualpuma`` command: one module per subcommand (fk, ik, plan, routine, envelope, serve).

Each subcommand module has ``register(subparsers)``, which adds its parser and sets ``func``; to
add a command, write a module with ``register`` and list it in :data:`COMMANDS`.

May import: every subpackage's public API.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from ..errors import DualpumaError
from . import envelope, fk, ik, plan, routine, serve

__all__ = ["COMMANDS", "build_parser", "main"]

COMMANDS = (fk, ik, plan, routine, envelope, serve)  #: the subcommand modules, in --help order


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every subcommand."""
    p = argparse.ArgumentParser(prog="dualpuma", description="Two PUMA 560 arms carrying one bar.")
    sub = p.add_subparsers(dest="cmd", required=True)
    for module in COMMANDS:
        module.register(sub)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code (2 for bad input, with a one-line message)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except DualpumaError as exc:
        print(f"dualpuma {args.cmd}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
