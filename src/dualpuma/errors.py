"""Exception hierarchy: every error dualpuma raises on bad input derives from DualpumaError."""

from __future__ import annotations

__all__ = [
    "CellError",
    "CellFileError",
    "DualpumaError",
    "FileError",
    "JointError",
    "ParameterError",
    "PoseError",
    "RobotError",
]


class DualpumaError(Exception):
    """Base class of all dualpuma errors."""


class PoseError(DualpumaError, ValueError):
    """A pose is malformed: wrong shape, NaN/inf, or a non-orthonormal rotation."""


class JointError(DualpumaError, ValueError):
    """A joint vector is malformed: wrong shape or NaN/inf."""


class RobotError(DualpumaError, ValueError):
    """An unknown robot name, or a model that is not a 6-DOF serial arm."""


class CellError(DualpumaError, ValueError):
    """A work-cell description (file or Python) is invalid; the message names file, key and problem."""


class FileError(DualpumaError, OSError):
    """A file cannot be read or written: missing, not a regular file, too large, exists (and
    overwriting was not asked for), or outside the allowed directory."""


class CellFileError(CellError, FileError):
    """A cell file that cannot be read or written (``load_cell``, ``save_cell``): missing, exists
    (and overwriting was not asked for), its directory missing, not a regular file, too large.
    Both a :class:`CellError`, as every cell-file problem, and a :class:`FileError`, as every other
    file dualpuma cannot read or write."""


class ParameterError(DualpumaError, ValueError):
    """An impossible parameter value (negative step, zero resolution, ...)."""
