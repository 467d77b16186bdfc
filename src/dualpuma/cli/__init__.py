"""The ``dualpuma`` command: one module per subcommand (fk, ik, plan, routine, envelope, serve).

Each subcommand module has ``register(subparsers)``, which adds its parser and sets ``func``; to
add a command, write a module with ``register`` and list it in :data:`COMMANDS`.

May import: every subpackage's public API.
"""

from __future__ import annotations

import argparse
import errno
import os
import select
import sys
from collections.abc import Sequence

from .. import __version__
from ..errors import DualpumaError
from . import envelope, fk, ik, plan, routine, serve
from .common import Parser, one_line

__all__ = ["COMMANDS", "build_parser", "main"]

COMMANDS = (fk, ik, plan, routine, envelope, serve)  #: the subcommand modules, in --help order
#: a write to stdout failed for want of room or a device (``> /dev/full``): exit 2, one line
_OUTPUT_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO})
_EPILOG = """examples:
  dualpuma fk --q 10 20 30 0 45 0
  dualpuma ik --xyz 500 150 -200 --rpy 0 90 0
  dualpuma plan --by -200 0 100 --rpy 0 0 -10 --out plan.json
  dualpuma routine 8
  dualpuma envelope --ideal --reach-mm 1000 --base-distance-mm 2500 --bar-length-mm 1000
  dualpuma serve --cell agv

'dualpuma COMMAND --help' describes each command."""


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every subcommand (argparse errors: one line, exit code 2)."""
    p = Parser(prog="dualpuma", description="Two PUMA 560 arms carrying one bar: kinematics, planning, work envelope, "
               "viewer. Millimetres and degrees on every flag; vectors as separate numbers or one quoted string.", epilog=_EPILOG,
               formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"dualpuma {__version__}")
    sub = p.add_subparsers(dest="cmd", required=True, metavar="COMMAND")
    for module in COMMANDS:
        module.register(sub)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code: 0 done, 1 a valid request without an answer (a
    plan that did not reach its goal, a pose no IK branch reaches), 2 bad input (arguments, files,
    outputs) with a one-line message on stderr, 70 an internal error (one line;
    ``DUALPUMA_TRACEBACK=1`` shows the traceback), 130 interrupted, 141 (quietly) when the reader
    of stdout has gone (``dualpuma plan ... | head``), as for a tool ended by SIGPIPE; 2 (one line)
    when stdout cannot be written (``> /dev/full``, a full disk). A stdout closed before the start
    (``>&-``) takes nothing: the command runs (its files are written) and exits with its code."""
    try:
        code = _command(argv)
        if sys.stdout is not None:  # None: closed at the start, and print wrote nowhere
            sys.stdout.flush()  # a closed stdout shows here, not as a warning at exit
    except BrokenPipeError:  # stdout's only: _command reports any other as an internal error
        return _stdout_gone()
    except OSError as exc:  # stdout's only, as above
        print(f"dualpuma: error: cannot write the output: {exc.strerror or exc}", file=sys.stderr)
        _stdout_gone()  # (the unwritten output is dropped, not retried at exit)
        return 2
    return code


def _command(argv: Sequence[str] | None) -> int:
    parser = build_parser()
    try:
        args, extra = parser.parse_known_args(argv)
        if extra:  # said by the subcommand, whose flags they were meant to be (argparse says 'dualpuma')
            parser.exit(2, f"dualpuma {args.cmd}: error: unrecognized arguments: {one_line(' '.join(extra))} "
                           f"(see 'dualpuma {args.cmd} --help')\n")
    except SystemExit as exc:  # --help (0) or an argparse error (2, already reported)
        return int(exc.code or 0) if isinstance(exc.code, int) else 2
    try:
        return int(args.func(args) or 0)
    except DualpumaError as exc:
        print(f"dualpuma {args.cmd}: error: {one_line(str(exc))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except Exception as exc:  # a bug: still one line, unless asked for the traceback
        if isinstance(exc, BrokenPipeError) and not _stdout_open():
            raise  # stdout's reader has gone: main stops quietly
        if isinstance(exc, OSError) and exc.filename is None and exc.errno in _OUTPUT_ERRNOS:
            raise  # an output stream cannot be written (files are named: FileError): main says so
        if os.environ.get("DUALPUMA_TRACEBACK"):
            raise
        print(f"dualpuma {args.cmd}: internal error: {type(exc).__name__}: {one_line(str(exc))} "
              "(DUALPUMA_TRACEBACK=1 shows the traceback)", file=sys.stderr)
        return 70


def _stdout_open() -> bool:
    """Does stdout still have a reader? (A pipe whose reader has closed polls as an error; a
    BrokenPipeError's buffered data is dropped, so flushing again cannot tell.)"""
    try:
        poller = select.poll()
        poller.register(sys.stdout.fileno(), select.POLLOUT)
        return not any(ev & select.POLLERR for _, ev in poller.poll(0))
    except (AttributeError, OSError, ValueError):  # no poll (Windows) or no real stdout: assume so
        return True


def _stdout_gone() -> int:
    """The reader of stdout went away: point stdout at the null device (so the interpreter's own
    flush at exit does not fail again) and stop quietly with 141 (128 + SIGPIPE)."""
    try:
        fd = os.open(os.devnull, os.O_WRONLY)
        os.dup2(fd, sys.stdout.fileno())
        os.close(fd)
    except (OSError, ValueError):
        pass
    return 141
