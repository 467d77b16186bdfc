"""The validation layer at the public boundary: every argument check that raises a typed error.

Each function takes the user's value and the argument's name, and returns the value in the form the
code inside relies on (float64 arrays, Python floats and ints). Anything else raises a
:class:`~dualpuma.errors.DualpumaError` subclass naming the argument, what was expected and what
came: never a bare ``ValueError``/``TypeError`` from numpy, Pinocchio or coal further in.

Poses are homogeneous transforms (4, 4) (or stacks (..., 4, 4)) [m]; joint vectors are (6,) (or
stacks (..., 6)) [rad].
"""

from __future__ import annotations

import math
import numbers
import warnings
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from .errors import JointError, ParameterError, PoseError

__all__ = [
    "MAX_ELEMENTS",
    "ORTHO_TOL",
    "as_array",
    "choice",
    "flag",
    "frozen_array",
    "generator",
    "has_attributes",
    "instance",
    "integer",
    "joint_pair",
    "points",
    "probability",
    "real",
    "rotations",
    "text",
    "times",
    "validate_joints",
    "validate_pose",
    "vector",
]

FloatArray = npt.NDArray[np.float64]

ORTHO_TOL = 1e-9  #: largest |R^T R - I| accepted for a rotation matrix
MAX_ELEMENTS = 100_000_000  #: largest array (number of entries) taken at the boundary (800 MB of float64)


#: entries of an object array that are not numbers, though numpy would convert them ("0.3", True)
_NOT_NUMBERS = (str, bytes, bool, np.bool_)


def as_array(value: object, name: str, error: type[Exception] = ParameterError) -> FloatArray:
    """``value`` as a float64 array, or ``error`` naming ``name`` (strings, dicts, ragged lists, None;
    booleans, and numbers written as text, such as ``["0.3", ...]``, which numpy would read).

    Raises:
        error: the value is not an array of real numbers.
    """
    if isinstance(value, (str, bytes, dict, set, frozenset)) or value is None:
        raise error(f"{name}: expected numbers, got {type(value).__name__}")
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "iuf":
            raise error(f"{name}: expected real numbers, got an array of dtype {value.dtype}")
        if value.size > MAX_ELEMENTS:
            raise error(f"{name}: {value.size} entries, more than the {MAX_ELEMENTS} accepted")
    elif (isinstance(value, numbers.Complex) and not isinstance(value, numbers.Real)) or not (
        isinstance(value, (numbers.Real, Sequence)) or hasattr(value, "__array__")
    ):
        raise error(f"{name}: expected an array of real numbers, got {type(value).__name__}")
    try:
        raw = value if isinstance(value, np.ndarray) else np.asarray(value)
        # objects, and numbers numpy made of a list ([0.1, True] gave 1.0): each entry as it was given
        given = raw.dtype.kind == "O" or (raw.dtype.kind in "iuf" and isinstance(value, Sequence))
        text = raw.dtype.kind in "US" or (given and any(isinstance(x, _NOT_NUMBERS)
                                                        for x in np.asarray(value, dtype=object).flat))
        if not text and raw.dtype.kind != "b":
            with warnings.catch_warnings():
                warnings.simplefilter("error", np.exceptions.ComplexWarning)
                arr = raw.astype(np.float64, copy=False)
    except (TypeError, ValueError, OverflowError, MemoryError, RecursionError, np.exceptions.ComplexWarning) as exc:
        raise error(f"{name}: expected an array of real numbers ({type(exc).__name__}: {exc})"[:300]) from None
    if text or raw.dtype.kind == "b":
        what = "text or booleans (write the numbers themselves)" if text else "booleans"
        raise error(f"{name}: expected real numbers, got {what}")
    if arr.size > MAX_ELEMENTS:
        raise error(f"{name}: {arr.size} entries, more than the {MAX_ELEMENTS} accepted")
    return arr


def frozen_array(value: object, shape: tuple[int, ...], name: str, error: type[Exception] = ParameterError) -> FloatArray:
    """A read-only float64 copy of ``value`` with exactly ``shape`` and finite entries.

    Raises:
        error: not numbers, another shape, NaN or inf.
    """
    arr = np.array(as_array(value, name, error))
    if arr.shape != shape:
        raise error(f"{name}: expected shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise error(f"{name}: contains NaN or inf")
    arr.setflags(write=False)
    return arr


def real(
    value: object,
    name: str,
    *,
    lo: float = -math.inf,
    hi: float = math.inf,
    lo_open: bool = False,
    hi_open: bool = False,
    unit: str = "",
    nan_ok: bool = False,
    error: type[Exception] = ParameterError,
) -> float:
    """A finite real number within [lo, hi] (or open ends), as a Python float (NaN too with ``nan_ok``).

    Raises:
        ParameterError (or ``error``): not a real number (bools, strings, arrays are not), not
            finite, or out of range.
    """
    if type(value) is float or (isinstance(value, numbers.Real) and not isinstance(value, bool)):
        try:
            v = float(value)
        except OverflowError:  # an int beyond the float range
            v = math.nan
            nan_ok = False
        if math.isfinite(v) and lo <= v <= hi and not (lo_open and v == lo) and not (hi_open and v == hi):
            return v
        if nan_ok and math.isnan(v):
            return v
    u = f" [{unit}]" if unit else ""
    span = "" if lo == -math.inf and hi == math.inf else \
        f" in {'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
    raise error(f"{name}: expected a finite number{span}{u}, got {_short(value)}")


def _short(value: object, limit: int = 80) -> str:
    """``repr`` of a user's value, cut to ``limit`` characters (a 50 MB string is not echoed)."""
    if isinstance(value, (str, bytes)) and len(value) > limit:
        return f"{type(value).__name__} of length {len(value)}"
    try:
        r = repr(value)
    except Exception:  # noqa: BLE001 - a broken __repr__ of the user's object
        r = f"<{type(value).__name__}>"
    return r if len(r) <= limit else r[: limit - 3] + "..."


def flag(value: object, name: str) -> bool:
    """True or False (also numpy's bool), as a Python bool.

    Raises:
        ParameterError: anything else (0/1, strings, arrays are not flags).
    """
    if not isinstance(value, (bool, np.bool_)):
        raise ParameterError(f"{name}: expected True or False, got {_short(value)}")
    return bool(value)


def choice(value: object, options: tuple[str, ...], name: str, error: type[Exception] = ParameterError) -> str:
    """One of the strings ``options``.

    Raises:
        ParameterError (or ``error``): not a string, or not one of ``options``.
    """
    if not isinstance(value, str) or value not in options:
        raise error(f"{name}: expected one of {', '.join(map(repr, options))}, got {_short(value)}")
    return value


#: characters a name may not hold: what a terminal acts on rather than shows (newlines, escapes),
#: and the bidirectional overrides that show text in another order than it is read
_HIDDEN = frozenset(chr(c) for c in (*range(0x20), *range(0x7F, 0xA0), *range(0x202A, 0x202F),
                                     *range(0x2066, 0x206A)))


def text(value: object, name: str, *, max_len: int = 1000, printable: bool = False,
         error: type[Exception] = ParameterError) -> str:
    """A string of at most ``max_len`` characters; with ``printable``, none of them a control
    character (a name printed on a terminal cannot start a new line or send an escape sequence).

    Raises:
        ParameterError (or ``error``): not a string, too long, or not printable.
    """
    if not isinstance(value, str):
        raise error(f"{name}: expected a string, got {type(value).__name__}")
    if len(value) > max_len:
        raise error(f"{name}: {len(value)} characters, more than the {max_len} accepted")
    if printable:
        bad = next((i for i, c in enumerate(value) if c in _HIDDEN), None)
        if bad is not None:
            raise error(f"{name}: character {bad + 1} is a control character (U+{ord(value[bad]):04X}); "
                        f"a name holds printable characters only")
    return value


def instance(value: object, cls: type | tuple[type, ...], name: str, error: type[Exception] = ParameterError) -> object:
    """``value`` if it is an instance of ``cls``.

    Raises:
        ParameterError (or ``error``): otherwise, naming the expected and the given type.
    """
    if not isinstance(value, cls):
        want = " or ".join(c.__name__ for c in (cls if isinstance(cls, tuple) else (cls,)))
        raise error(f"{name}: expected a {want}, got {type(value).__name__}")
    return value


def has_attributes(value: object, attrs: tuple[str, ...], what: str, name: str,
                   error: type[Exception] = ParameterError) -> object:
    """``value`` if it has every attribute in ``attrs`` (for modules that may not import the class:
    a World or a Cell checked from :mod:`dualpuma.kinematics`).

    Raises:
        ParameterError (or ``error``): an attribute is missing.
    """
    if not all(hasattr(value, a) for a in attrs):
        raise error(f"{name}: expected a dualpuma {what}, got {type(value).__name__}")
    return value


def generator(value: object, name: str = "rng") -> np.random.Generator:
    """A numpy Generator from ``value``: a Generator (used as is), a seed (int >= 0) or None (seed 0).

    Raises:
        ParameterError: anything else.
    """
    if isinstance(value, np.random.Generator):
        return value
    if value is None:
        return np.random.default_rng(0)
    try:
        seed = integer(value, name, lo=0, hi=2**63 - 1)
    except ParameterError:
        raise ParameterError(f"{name}: expected a numpy Generator, a seed (an integer >= 0) or None, "
                             f"got {_short(value)}") from None
    return np.random.default_rng(seed)


def vector(value: object, name: str, n: int, *, unit: str = "") -> FloatArray:
    """``n`` finite numbers as a float64 array (n,).

    Raises:
        ParameterError: anything else.
    """
    a = as_array(value, name)
    if a.shape != (n,) or not np.all(np.isfinite(a)):
        u = f" [{unit}]" if unit else ""
        raise ParameterError(f"{name}: expected {n} finite numbers{u}, got shape {a.shape}")
    return a


def points(value: object, name: str, n: int = 3, *, error: type[Exception] = ParameterError, unit: str = "m") -> FloatArray:
    """Finite points of shape (..., n) as float64.

    Raises:
        ParameterError (or ``error``): not numbers, another last dimension, NaN or inf.
    """
    a = as_array(value, name, error)
    if a.ndim < 1 or a.shape[-1] != n or not np.all(np.isfinite(a)):
        raise error(f"{name}: expected finite values of shape (..., {n}) [{unit}], got shape {a.shape}")
    return a


def times(value: object, n: int, name: str = "t") -> FloatArray:
    """One time or ``n`` times [s] as a float64 array (n,) (None: zeros).

    Raises:
        ParameterError: not numbers, not broadcastable to (n,), NaN or inf.
    """
    if value is None:
        return np.zeros(n)
    a = as_array(value, name)
    try:
        out = np.broadcast_to(a, (n,))
    except ValueError:
        raise ParameterError(f"{name}: expected one time or {n} times [s], got shape {a.shape}") from None
    if not np.all(np.isfinite(out)):
        raise ParameterError(f"{name}: times must be finite [s]")
    return out


def rotations(value: object, name: str, error: type[Exception] = PoseError) -> FloatArray:
    """Rotation matrices (3, 3) or (..., 3, 3): finite, orthonormal, det +1, as float64.

    Raises:
        PoseError (or ``error``): anything else.
    """
    R = as_array(value, name, error)
    if R.ndim < 2 or R.shape[-2:] != (3, 3):
        raise error(f"{name}: expected shape (3, 3) or (..., 3, 3), got {R.shape}")
    T = np.zeros(R.shape[:-2] + (4, 4))
    T[..., :3, :3] = R
    T[..., 3, 3] = 1.0
    validate_pose(T, name=name, error=error)
    return R


def integer(value: object, name: str, *, lo: int = -(2**62), hi: int = 2**62) -> int:
    """An integer (not a bool) within [lo, hi], as a Python int.

    Raises:
        ParameterError: not an integer or out of range.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not lo <= int(value) <= hi:
        raise ParameterError(f"{name}: expected an integer in [{lo}, {hi}], got {_short(value)}")
    return int(value)


def probability(value: object, name: str) -> float:
    """A number in [0, 1].

    Raises:
        ParameterError: otherwise.
    """
    return real(value, name, lo=0.0, hi=1.0)


def validate_pose(T: npt.ArrayLike, *, name: str = "T", error: type[Exception] = PoseError) -> FloatArray:
    """Check a homogeneous transform (or a stack of them) and return it as float64.

    Args:
        T: pose(s), shape (4, 4) or (..., 4, 4) [m].
        name: argument name used in error messages.
        error: the exception class raised (a cell file's pose raises CellError).

    Raises:
        PoseError: not numbers, wrong shape, NaN/inf, bottom row not (0, 0, 0, 1), or a rotation
            that is not orthonormal with determinant +1 (tolerance :data:`ORTHO_TOL`).
    """
    arr = T if type(T) is np.ndarray and T.dtype == np.float64 else as_array(T, name, error)
    if arr.shape == (4, 4):
        _check_one_pose(arr.tolist(), name, error)
        return arr
    if arr.ndim < 2 or arr.shape[-2:] != (4, 4):
        raise error(f"{name}: expected shape (4, 4) or (..., 4, 4), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise error(f"{name}: contains NaN or inf")
    if np.any(np.abs(arr[..., 3, :] - (0.0, 0.0, 0.0, 1.0)) > 1e-12):
        raise error(f"{name}: bottom row must be (0, 0, 0, 1)")
    c0, c1, c2 = arr[..., :3, 0], arr[..., :3, 1], arr[..., :3, 2]
    err = np.maximum.reduce(
        [
            np.abs(np.einsum("...i,...i->...", c0, c0) - 1.0),
            np.abs(np.einsum("...i,...i->...", c1, c1) - 1.0),
            np.abs(np.einsum("...i,...i->...", c2, c2) - 1.0),
            np.abs(np.einsum("...i,...i->...", c0, c1)),
            np.abs(np.einsum("...i,...i->...", c0, c2)),
            np.abs(np.einsum("...i,...i->...", c1, c2)),
        ]
    )
    det = np.einsum("...i,...i->...", np.cross(c0, c1), c2)
    bad = (err > ORTHO_TOL) | (det < 0.0)
    if np.any(bad):
        idx = tuple(int(i) for i in np.argwhere(bad)[0])
        raise error(
            f"{name}: rotation at index {idx} is not orthonormal with det +1 "
            f"(|R^T R - I| = {float(err[idx]):.2e}, det = {float(det[idx]):.6f})"
        )
    return arr


def _check_one_pose(m: list[list[float]], name: str, error: type[Exception]) -> None:
    """:func:`validate_pose` for one pose in plain floats (no numpy temporaries)."""
    (a, b, c, x), (d, e, f, y), (g, h, i, z), bottom = m
    if not all(map(math.isfinite, (a, b, c, x, d, e, f, y, g, h, i, z, *bottom))):
        raise error(f"{name}: contains NaN or inf")
    if bottom != [0.0, 0.0, 0.0, 1.0]:
        raise error(f"{name}: bottom row must be (0, 0, 0, 1), got {bottom}")
    err = max(
        abs(a * a + d * d + g * g - 1.0),
        abs(b * b + e * e + h * h - 1.0),
        abs(c * c + f * f + i * i - 1.0),
        abs(a * b + d * e + g * h),
        abs(a * c + d * f + g * i),
        abs(b * c + e * f + h * i),
    )
    det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    if err > ORTHO_TOL or det < 0.0:
        raise error(
            f"{name}: rotation is not orthonormal with det +1 (|R^T R - I| = {err:.2e}, det = {det:.6f})"
        )


def validate_joints(q: npt.ArrayLike, *, name: str = "q", n: int = 6) -> FloatArray:
    """Check a joint vector (or a stack of them) of shape (..., n) [rad] and return it as float64.

    Raises:
        JointError: not numbers, wrong shape or NaN/inf.
    """
    arr = q if type(q) is np.ndarray and q.dtype == np.float64 else as_array(q, name, JointError)
    if arr.shape == (n,):  # fast path: one vector in plain floats
        if not all(map(math.isfinite, arr.tolist())):
            raise JointError(f"{name}: contains NaN or inf")
        return arr
    if arr.ndim < 1 or arr.shape[-1] != n:
        raise JointError(f"{name}: expected shape ({n},) or (..., {n}), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise JointError(f"{name}: contains NaN or inf")
    return arr


def joint_pair(q: object, name: str = "q") -> tuple[FloatArray, FloatArray]:
    """Both arms' joints ``(q_left, q_right)``, each one finite vector (6,) [rad].

    Raises:
        JointError: not a pair, or either vector malformed.
    """
    if isinstance(q, (str, bytes)) or not isinstance(q, (Sequence, np.ndarray)) \
            or (isinstance(q, np.ndarray) and q.ndim == 0) or len(q) != 2:
        raise JointError(f"{name}: expected (q_left, q_right), two joint vectors of shape (6,)")
    out = tuple(validate_joints(qi, name=f"{name}[{i}]") for i, qi in enumerate(q))  # type: ignore[union-attr]
    if any(qi.shape != (6,) for qi in out):
        raise JointError(f"{name}: expected two joint vectors of shape (6,), got {[qi.shape for qi in out]}")
    return out  # type: ignore[return-value]
