"""``dualpuma serve``: the browser viewer (viser) on a cell."""

from __future__ import annotations

import argparse
from typing import Any

from ..model.cell_file import cell_from_spec

__all__ = ["register"]


def _run(args: argparse.Namespace) -> int:
    from ..viewer.app import serve  # the viewer's dependencies load only for this command

    serve(cell_from_spec(args.cell), host=args.host, port=args.port)
    return 0


def register(sub: Any) -> None:
    """Add the ``serve`` command."""
    s = sub.add_parser("serve", help="start the browser viewer (viser)")
    s.add_argument("--cell", default=None, help="cell TOML file (default: the embedded default cell)")
    s.add_argument("--host", default="127.0.0.1")
    s.add_argument("--port", type=int, default=8080)
    s.set_defaults(func=_run)
