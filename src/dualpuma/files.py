"""Writing and reading the user's files safely: the one place that touches the file system.

* :func:`check_writable` — is a path a place a new file may go (before any work is done)?
* :func:`atomic_write` — write bytes through a temporary file in the target's directory and
  ``os.replace`` it over the target: a reader never sees half a file, an existing file is replaced
  only with ``overwrite=True`` and keeps its permission bits (a new file is hard-linked into place,
  which fails if another process created it meanwhile), and the temporary file is removed on any
  failure (a fixed ``name.tmp`` is never used: it could be someone's file or a planted link).
* :func:`read_limited` — read a file of at most ``limit`` bytes (a cell file, a plan), refusing
  devices, directories and anything larger, so that ``/dev/zero`` is an error, not a hang; what is
  checked is the file opened, not its name.
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import tempfile
from pathlib import Path

from .errors import FileError

__all__ = ["MAX_PATH_CHARS", "MAX_READ_BYTES", "atomic_write", "check_writable", "read_limited", "user_path"]

MAX_READ_BYTES = 64 * 1024 * 1024  #: default size limit of :func:`read_limited` [bytes]
MAX_PATH_CHARS = 4096  #: longest file name accepted (Linux's PATH_MAX)


def user_path(path: object) -> Path:
    """A file name the user gave (str, bytes or path-like) as a :class:`~pathlib.Path`, a leading
    ``~`` expanded as a shell would (``--cell=~/c.toml`` reaches us unexpanded).

    Raises:
        FileError: not a file name, a NUL character in it, or longer than :data:`MAX_PATH_CHARS`.
    """
    try:
        p = os.fspath(path)  # type: ignore[arg-type]
    except TypeError:
        raise FileError(f"path: expected a file name, got {type(path).__name__}") from None
    if isinstance(p, bytes):
        try:
            p = os.fsdecode(p)
        except UnicodeDecodeError:
            raise FileError("path: not a valid file name") from None
    if "\0" in p:
        raise FileError("path: a file name cannot contain a NUL character")
    if len(p) > MAX_PATH_CHARS:
        raise FileError(f"path: {len(p)} characters, more than the {MAX_PATH_CHARS} accepted")
    try:
        return Path(p).expanduser()
    except RuntimeError:  # ~someone who has no home here
        return Path(p)


def check_writable(path: str | os.PathLike, *, overwrite: bool = False) -> Path:
    """The path as a :class:`~pathlib.Path` if a file may be written there, else FileError.

    Raises:
        FileError: the directory does not exist or is not writable; the path is a directory, a
            device or another non-regular file; it exists and ``overwrite`` is False.
    """
    p = user_path(path)
    if str(p) == "" or p.name in ("", ".", ".."):
        raise FileError(f"{p}: not a file name")
    try:
        return _check_writable(p, overwrite)
    except FileError:
        raise
    except OSError as exc:  # a name too long, a loop of links, a permission denied on the way
        raise FileError(f"{p}: {exc.strerror or exc}") from None


def _check_writable(p: Path, overwrite: bool) -> Path:
    parent = p.parent
    if not parent.is_dir():
        raise FileError(f"{p}: the directory {parent} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise FileError(f"{p}: the directory {parent} is not writable")
    if p.is_symlink() or p.exists():
        try:
            st = os.stat(p)
        except FileNotFoundError:
            raise FileError(f"{p}: a link to {os.readlink(p)}, which does not exist (remove the link, or write "
                            "to another name)") from None
        except OSError as exc:
            raise FileError(f"{p}: {exc.strerror}") from None
        if not stat.S_ISREG(st.st_mode):
            raise FileError(f"{p}: exists and is not a regular file")
        if not overwrite:
            raise FileError(f"{p}: exists; pass overwrite=True to replace it")
    return p


def atomic_write(path: str | os.PathLike, data: bytes, *, overwrite: bool = False) -> Path:
    """Write ``data`` to ``path`` atomically (see the module docstring).

    Raises:
        FileError: as :func:`check_writable`, or the write itself failed (disk full...).
    """
    p = check_writable(path, overwrite=overwrite)
    try:
        mode = stat.S_IMODE(os.stat(p).st_mode) if p.exists() else None
    except OSError as exc:
        raise FileError(f"{p}: {exc.strerror or exc}") from None
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise FileError(f"{p}: expected bytes to write, got {type(data).__name__}")
    try:  # a random name created exclusively (O_EXCL): never someone's file, never a planted link
        fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=f".{p.name[:64]}.", suffix=".part")
    except OSError as exc:
        raise FileError(f"{p}: cannot create a temporary file in {p.parent}: {exc.strerror or exc}") from None
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        if mode is None:  # a new file gets the usual permissions (umask), not mkstemp's 0600
            umask = os.umask(0)
            os.umask(umask)
            mode = 0o666 & ~umask
        os.chmod(tmp, mode)
        if overwrite:
            os.replace(tmp, p)
        else:
            _link_new(tmp, p)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError) and not isinstance(exc, FileError):
            raise FileError(f"{p}: cannot write: {exc.strerror or exc}") from None
        raise
    return p


def _link_new(tmp: str, p: Path) -> None:
    """Give the written temporary file ``tmp`` the name ``p``, which must not exist: a hard link
    fails atomically if another process created ``p`` meanwhile (a check, then a rename, would
    replace it); where the file system has no hard links, that check and rename."""
    try:
        os.link(tmp, p)
    except FileExistsError:
        raise FileError(f"{p}: exists; pass overwrite=True to replace it") from None
    except OSError:  # no hard links here (FAT, some network and FUSE file systems): check, then rename
        if p.exists():  # appeared meanwhile
            raise FileError(f"{p}: exists; pass overwrite=True to replace it") from None
        os.replace(tmp, p)
    else:
        os.unlink(tmp)


def read_limited(path: str | os.PathLike, *, limit: int = MAX_READ_BYTES, follow_links: bool = True) -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes (``follow_links=False``: the file
    itself must not be a symbolic link).

    The name is checked before anything is opened (a device is never opened: opening a serial port
    can reset the board on it), and the file opened is checked again to be that same regular file,
    so one swapped for a link or a FIFO between the check and the read is not read (the data
    directory's reads had checked the name with ``lstat`` and then opened it following links: a
    reviewer's script swapping a file and a link read the link's target, outside).

    Raises:
        FileError: missing, unreadable, a link (``follow_links=False``), not a regular file (device,
            directory, FIFO), too large, or replaced while it was opened.
    """
    p = user_path(path)
    try:
        st = os.stat(p) if follow_links else os.lstat(p)
    except OSError as exc:
        raise FileError(f"{p}: cannot read: {exc.strerror}") from None
    if stat.S_ISLNK(st.st_mode):
        raise FileError(f"{p}: a symbolic link, which is not followed here")
    if not stat.S_ISREG(st.st_mode):
        raise FileError(f"{p}: not a regular file")
    if st.st_size > limit:
        raise FileError(f"{p}: {st.st_size} bytes, more than the {limit} accepted")
    flags = os.O_RDONLY | getattr(os, "O_BINARY", 0) | getattr(os, "O_NONBLOCK", 0)  # a FIFO swapped in: no wait
    if not follow_links:
        flags |= getattr(os, "O_NOFOLLOW", 0)
    try:
        fd = os.open(p, flags)
    except OSError as exc:
        if exc.errno == errno.ELOOP and not follow_links:  # a link swapped in since the check
            raise FileError(f"{p}: a symbolic link, which is not followed here") from None
        raise FileError(f"{p}: cannot read: {exc.strerror}") from None
    try:
        opened = os.fstat(fd)
        if (opened.st_dev, opened.st_ino) != (st.st_dev, st.st_ino) or not stat.S_ISREG(opened.st_mode):
            raise FileError(f"{p}: replaced while it was being opened; not read")
        with os.fdopen(fd, "rb", closefd=False) as f:
            data = f.read(limit + 1)
    except OSError as exc:
        if isinstance(exc, FileError):
            raise
        raise FileError(f"{p}: cannot read: {exc.strerror}") from None
    finally:
        os.close(fd)
    if len(data) > limit:
        raise FileError(f"{p}: more than the {limit} bytes accepted")
    return data
