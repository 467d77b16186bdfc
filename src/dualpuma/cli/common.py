"""What the subcommands share: the parser class, vector flags, help texts, output files.

The UI edge: millimetres and degrees come in here and are converted to SI at once.

* Every error is one line on stderr and exit code 2 (:class:`Parser` for argparse's own errors,
  :func:`dualpuma.cli.main` for every :class:`~dualpuma.errors.DualpumaError`).
* Every vector flag takes its numbers the same way (:func:`add_vector`): as separate arguments
  (``--q 10 20 30 0 45 0``) or as one quoted string with spaces or commas (``--q "10,20,30,0,45,0"``).
* Every subcommand's ``--help`` has a description and an example (:func:`add_command`).
"""

from __future__ import annotations

import argparse
import math
import os
import re
from typing import Any, NoReturn

import numpy as np

from ..errors import FileError, ParameterError
from ..files import check_writable

__all__ = ["Parser", "add_command", "add_vector", "check_output", "floats", "one_line", "vector"]

_MAX_TEXT = 200  # longest piece of the user's input echoed in a message [characters]


def one_line(text: str, limit: int = 2000) -> str:
    """``text`` on one line (newlines and tabs as spaces), cut to ``limit`` characters."""
    flat = " ".join(str(text).split())
    return flat if len(flat) <= limit else flat[: limit - 3] + "..."


class Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line (``dualpuma fk: error: ... (see --help)``) and
    exit code 2, without the usage block; a word starting with a minus and a digit is a value, not
    an option (``--by -200,0,100``, ``--rpy -1e-3 0 0``: argparse's own rule takes only plain
    ``-200`` and ``-0.5``)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("allow_abbrev", False)  # --j is not --json: a prefix is an unknown flag, said so
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-\.?\d")  # the stdlib's own attribute, widened

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {one_line(message)} (see '{self.prog} --help')\n")


def add_command(sub: Any, name: str, summary: str, description: str, examples: tuple[str, ...]) -> Parser:
    """A subcommand parser with a description and examples in its ``--help``."""
    epilog = "examples:\n" + "\n".join(f"  {e}" for e in examples)
    return sub.add_parser(name, help=summary, description=description, epilog=epilog,
                          formatter_class=argparse.RawDescriptionHelpFormatter)


def add_vector(p: argparse.ArgumentParser, flag: str, n: int, unit: str, what: str, *,
               default: tuple[float, ...] | None = None, required: bool = False, group: Any = None) -> None:
    """A flag taking ``n`` numbers [unit]: separate arguments or one quoted string."""
    d = "" if default is None else f" (default {' '.join(f'{v:g}' for v in default)})"
    (group or p).add_argument(
        flag, nargs="+", required=required, default=None if default is None else [str(v) for v in default],
        metavar=unit.upper(),
        help=f"{what}: {n} numbers [{unit}], as separate arguments or one quoted string{d}",
    )


def vector(values: object, n: int, what: str) -> np.ndarray:
    """``n`` finite numbers from a flag's values: a list of strings, each holding one or more numbers
    separated by spaces or commas (``["10", "20"]``, ``["10 20"]``, ``["10,20"]``).

    Raises:
        ParameterError: not ``n`` finite numbers (the message names the flag).
    """
    parts = [values] if isinstance(values, str) else list(values)  # type: ignore[call-overload]
    words = " ".join(str(v) for v in parts).replace(",", " ").split()
    try:
        vals = [float(w) for w in words]
    except ValueError:
        raise ParameterError(f"{what}: expected {n} numbers, got {one_line(' '.join(words), _MAX_TEXT)!r}") from None
    if len(vals) != n:
        raise ParameterError(f"{what}: expected {n} numbers, got {len(vals)}")
    if not all(math.isfinite(v) for v in vals):
        raise ParameterError(f"{what}: the numbers must be finite, got {vals}")
    return np.array(vals)


def floats(text: str, n: int, what: str) -> np.ndarray:
    """``n`` numbers from a string such as ``"10 20 30"`` or ``"10,20,30"`` (:func:`vector`).

    Raises:
        ParameterError: not ``n`` finite numbers.
    """
    return vector([text], n, what)


#: largest |angle| an angle flag takes (--q, --rpy) [deg] (100 turns): sin and cos of larger ones
#: are meaningless (--rpy 1e20 planned 'reached'), and fk printed 300 digits for them
MAX_ANGLE_DEG = 36_000.0


def angles(values: object, n: int, flag: str) -> np.ndarray:
    """``n`` angles [deg] from an angle flag's values (:func:`vector`), each within :data:`MAX_ANGLE_DEG`.

    Raises:
        ParameterError: not ``n`` finite numbers, or beyond a hundred turns (the message names the flag).
    """
    v = vector(values, n, f"{flag} [deg]")
    if np.abs(v).max() > MAX_ANGLE_DEG:
        raise ParameterError(f"{flag}: expected angles within ±{MAX_ANGLE_DEG:g} deg (100 turns), got {v.tolist()}"[:300])
    return v


def check_output(path: str | None, force: bool) -> None:
    """Refuse an output file before any work: it exists (without ``force``), its directory is
    missing or not writable, it is a directory or a device.

    Raises:
        FileError: as above.
    """
    if path is None:
        return
    if path == "-":  # not a file name: many tools read it as stdout, which --json is here
        raise FileError("-: not a file name (--json prints to stdout)")
    check_writable(path, overwrite=True)  # first what --force cannot help: a directory, a device, no directory
    if os.path.lexists(path) and not force:
        raise FileError(f"{path}: exists; pass --force to overwrite it")
