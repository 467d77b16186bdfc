"""``dualpuma serve``: the browser viewer (viser) on a cell."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ..errors import ParameterError
from ..model.cell_file import EXAMPLE_CELLS, cell_from_spec

__all__ = ["parse_port", "register"]

DESCRIPTION = """Start the browser viewer: the cell in 3-D, a teach pendant (joints, Cartesian jog, the
object frame), the seed's routines 1-8 with playback, planning to a goal, cells and waypoint files.

Anyone who can open the page controls the viewer and can write files in its data directory:
it listens on this machine only (127.0.0.1) unless --host says otherwise, refuses pages from other
sites (WebSocket Origin) and foreign host names (DNS rebinding), and reads or writes files only in
--data-dir, by short names. See docs/security.md before using --host on a network."""

EXAMPLES = """examples:
  dualpuma serve                              # default cell on http://127.0.0.1:8080
  dualpuma serve --cell agv --port auto       # a shipped cell on the first free port from 8080
  dualpuma serve --cell my.toml --data-dir ~/dualpuma-data
  dualpuma serve --host 0.0.0.0 --allow-host robots.lab.example   # on the network: read docs/security.md"""


def parse_port(text: str) -> int | str:
    """``--port``: 0..65535 or ``auto``."""
    if text == "auto":
        return "auto"
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a port number 0..65535 or 'auto', got {text!r}") from None
    if not 0 <= v <= 65535:
        raise argparse.ArgumentTypeError(f"expected a port number 0..65535 or 'auto', got {v}")
    return v


def _run(args: argparse.Namespace) -> int:
    from ..viewer import (  # the viewer's dependencies load only for this command
        check_listen,
        is_loopback,
        serve,
    )

    cell = cell_from_spec(args.cell)
    label = f"startup: {args.cell}" if args.cell else None
    data = Path(args.data_dir)
    if data.exists() and not data.is_dir():
        raise ParameterError(f"--data-dir {data}: exists and is not a directory")
    port = check_listen(args.host, args.port)  # exits 2 (via ParameterError) before anything starts
    if args.port == "auto":
        print(f"dualpuma serve: --port auto: using port {port}", flush=True)
    if not is_loopback(args.host):
        print(f"dualpuma serve: WARNING: listening on {args.host}: anyone who can reach this machine on port {port} "
              "gets full control of the viewer and can write files in its data directory "
              f"({data.absolute()}). There is no login and no encryption. See docs/security.md.",
              file=sys.stderr, flush=True)
    serve(cell, args.host, port, data_dir=data, allow_hosts=tuple(args.allow_host), cell_label=label)
    return 0


def register(sub: Any) -> None:
    """Add the ``serve`` command."""
    s = sub.add_parser("serve", help="start the browser viewer (viser)", description=DESCRIPTION, epilog=EXAMPLES,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    s.add_argument("--cell", default=None,
                   help=f"cell TOML file or a shipped example ({', '.join(EXAMPLE_CELLS)}); default: the seed's cell; "
                        "a file named like an example: ./NAME")
    s.add_argument("--host", default="127.0.0.1",
                   help="address to listen on (default 127.0.0.1: this machine only; anything else prints a warning)")
    s.add_argument("--port", type=parse_port, default=8080,
                   help="port 0..65535 (default 8080; 0 = any free port) or 'auto' (the first free one from 8080); "
                        "a port in use is an error, not silently replaced")
    s.add_argument("--data-dir", default="dualpuma-data",
                   help="the only directory the viewer reads and writes (cells *.toml, waypoints *.json); "
                        "default ./dualpuma-data, created on the first save")
    s.add_argument("--allow-host", action="append", default=[], metavar="NAME",
                   help="a further host name the server answers to (e.g. its DNS name behind a proxy); repeatable")
    s.set_defaults(func=_run)
