"""The one directory the viewer reads and writes, and the files in it.

A browser client names a file by a short name only (:func:`file_name`): letters, digits, ``-`` and
``_``, at most :data:`MAX_NAME` characters, with the kind's fixed suffix (``.json`` for waypoints,
``.toml`` for cells) added when missing. No separator, no ``..``, no absolute path, no other
suffix: whatever a client types, the file is a direct child of :attr:`DataDir.root`. The directory
is created on the first write (not at start). Writes go through :func:`dualpuma.files.atomic_write`
(never over an existing file unless asked), reads through :func:`dualpuma.files.read_limited`.

Waypoint files (:func:`save_waypoints`, :func:`load_waypoints`) are JSON:
``{"format": "dualpuma.waypoints/1", "units": "m", "T_world_object": [4x4, ...]}``.
"""

from __future__ import annotations

import json
import os
import re
import stat
from pathlib import Path

import numpy as np

from ..checks import validate_pose
from ..errors import DualpumaError, FileError, ParameterError
from ..files import atomic_write, read_limited, user_path

__all__ = [
    "DEFAULT_DATA_DIR",
    "MAX_NAME",
    "MAX_WAYPOINTS",
    "DataDir",
    "file_name",
    "load_waypoints",
    "save_waypoints",
    "waypoints_from_bytes",
    "waypoints_to_bytes",
]

DEFAULT_DATA_DIR = "dualpuma-data"  #: default data directory, relative to where the server starts
MAX_NAME = 60  #: longest file name stem [characters]
MAX_WAYPOINTS = 1000  #: most waypoints in one file
_WAYPOINT_BYTES = 1 << 20
_STEM = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]*")
_FORMAT = "dualpuma.waypoints/1"


def file_name(name: object, suffix: str) -> str:
    """``name`` as a file name with ``suffix`` (".json" or ".toml"), or ParameterError saying why.

    >>> file_name("pick-1", ".json")
    'pick-1.json'
    """
    if not isinstance(name, str):
        raise ParameterError(f"file name: expected text, got {type(name).__name__}")
    stem = name.removesuffix(suffix)
    if len(stem) > MAX_NAME:
        raise ParameterError(f"file name: at most {MAX_NAME} characters, got {len(stem)}")
    if not _STEM.fullmatch(stem):
        shown = stem if len(stem) <= 40 else stem[:37] + "..."
        raise ParameterError(f"file name {shown!r}: use letters, digits, '-' and '_' only, starting with a letter or digit (no folders, no dots), "
                             f"e.g. 'waypoints'; the file is saved as NAME{suffix} in the data directory")
    return stem + suffix


class DataDir:
    """The viewer's data directory (see the module docstring).

    Args:
        root: the directory (created on the first write; its parent must exist then).
    """

    def __init__(self, root: str | os.PathLike) -> None:
        self.root = Path(os.path.abspath(user_path(root)))  # a leading ~ expanded

    def __repr__(self) -> str:
        return f"DataDir({str(self.root)!r})"

    def path(self, name: object, suffix: str) -> Path:
        """The path of the file ``name`` (validated by :func:`file_name`) in the directory."""
        return self.root / file_name(name, suffix)

    def names(self, suffix: str) -> list[str]:
        """Sorted names of the regular files with ``suffix`` that :func:`file_name` accepts."""
        return self._scan(suffix)[0]

    def unlisted(self, suffix: str) -> list[str]:
        """Sorted names ending in ``suffix`` (any case) that :meth:`names` leaves out: a name
        :func:`file_name` refuses, a link, not a regular file."""
        return self._scan(suffix)[1]

    def _scan(self, suffix: str) -> tuple[list[str], list[str]]:
        try:
            entries = list(os.scandir(self.root))
        except OSError:
            return [], []
        listed, left_out = [], []
        for e in entries:
            if not e.name.lower().endswith(suffix.lower()):
                continue
            try:
                ok = e.is_file(follow_symlinks=False) and e.name.endswith(suffix) and file_name(e.name, suffix) == e.name
            except (OSError, ParameterError):
                ok = False
            (listed if ok else left_out).append(e.name)
        return sorted(listed), sorted(left_out)

    def write(self, name: object, suffix: str, data: bytes, *, overwrite: bool = False) -> Path:
        """Write ``data`` to the file ``name`` atomically; creates the directory if needed.

        Raises:
            ParameterError: bad name. FileError: exists (without ``overwrite``), cannot write.
        """
        p = self.path(name, suffix)
        try:
            self.root.mkdir(mode=0o755, parents=False, exist_ok=True)
        except OSError as exc:
            raise FileError(f"data directory {self.root}: cannot create it: {exc.strerror}") from None
        if p.is_symlink():
            raise FileError(f"{p.name}: is a symbolic link in the data directory; not replaced")
        if p.exists() and not overwrite:  # said in the pendant's words (atomic_write checks again)
            raise FileError(f"{p.name}: exists in the data directory; tick 'overwrite' to replace it")
        return atomic_write(p, data, overwrite=overwrite)

    def read(self, name: object, suffix: str, limit: int) -> bytes:
        """The bytes of the file ``name`` (a regular file, not a link, at most ``limit`` bytes).

        Raises:
            ParameterError: bad name. FileError: missing, a link, not a regular file, too large.
        """
        p = self.path(name, suffix)
        try:
            st = os.lstat(p)
        except OSError:
            raise FileError(f"{p.name}: no such file in the data directory {self.root}") from None
        if not stat.S_ISREG(st.st_mode):
            raise FileError(f"{p.name}: not a regular file")
        return read_limited(p, limit=limit, follow_links=False)  # a link swapped in meanwhile is not read either


def waypoints_to_bytes(poses: list[np.ndarray]) -> bytes:
    """The JSON bytes of a waypoint file (for :meth:`DataDir.write`).

    Raises:
        ParameterError: more than :data:`MAX_WAYPOINTS` poses.
    """
    if len(poses) > MAX_WAYPOINTS:
        raise ParameterError(f"waypoints: at most {MAX_WAYPOINTS}, got {len(poses)}")
    data = {"format": _FORMAT, "units": "m", "T_world_object": [np.asarray(T, float).tolist() for T in poses]}
    return json.dumps(data, allow_nan=False).encode()


def waypoints_from_bytes(data: bytes, where: str) -> list[np.ndarray]:
    """Poses from the bytes of a waypoint file; ``where`` names it in errors.

    Raises:
        ParameterError: not a waypoint file, or a bad pose.
    """
    try:
        doc = json.loads(data.decode("utf-8"))
        if not isinstance(doc, dict) or doc.get("format") != _FORMAT:
            raise ParameterError(f"{where}: not a dualpuma waypoint file")
        poses = doc["T_world_object"]
        if not isinstance(poses, list) or len(poses) > MAX_WAYPOINTS:
            raise ParameterError(f"{where}: T_world_object: expected a list of at most {MAX_WAYPOINTS} poses")
        return [validate_pose(T, name=f"{where}: waypoint {i}") for i, T in enumerate(poses)]
    except DualpumaError as exc:
        raise ParameterError(str(exc)) from None
    except (ValueError, KeyError, TypeError, RecursionError) as exc:
        raise ParameterError(f"{where}: cannot read waypoints: {type(exc).__name__}: {exc}"[:300]) from None


def save_waypoints(path: str | os.PathLike, poses: list[np.ndarray], overwrite: bool = False) -> Path:
    """Write taught object poses (4x4 each, metres) as JSON; never replaces a file unless asked.

    Raises:
        ParameterError: too many poses. FileError: exists (without ``overwrite``), cannot write.
    """
    return atomic_write(path, waypoints_to_bytes(poses), overwrite=overwrite)


def load_waypoints(path: str | os.PathLike) -> list[np.ndarray]:
    """Read a waypoint file written by :func:`save_waypoints` (every pose validated).

    Raises:
        FileError: unreadable or too large. ParameterError: not a waypoint file, bad poses.
    """
    return waypoints_from_bytes(read_limited(path, limit=_WAYPOINT_BYTES), str(path))


