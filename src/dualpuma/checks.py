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

import numpy as np
import numpy.typing as npt

from .errors import JointError, ParameterError, PoseError

__all__ = [
    "ORTHO_TOL",
    "as_array",
    "frozen_array",
    "integer",
    "joint_pair",
    "probability",
    "real",
    "validate_joints",
    "validate_pose",
    "vector",
]

FloatArray = npt.NDArray[np.float64]

ORTHO_TOL = 1e-9  #: largest |R^T R - I| accepted for a rotation matrix


def as_array(value: object, name: str, error: type[Exception] = ParameterError) -> FloatArray:
    """``value`` as a float64 array, or ``error`` naming ``name`` (strings, dicts, ragged lists, None).

    Raises:
        error: the value is not an array of real numbers.
    """
    if isinstance(value, (str, bytes, dict)) or value is None:
        raise error(f"{name}: expected numbers, got {type(value).__name__}")
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError) as exc:
        raise error(f"{name}: expected an array of real numbers ({exc})") from None
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
) -> float:
    """A finite real number within [lo, hi] (or open ends), as a Python float.

    Raises:
        ParameterError: not a real number (bools and strings are not), not finite, or out of range.
    """
    if type(value) is float or (isinstance(value, numbers.Real) and not isinstance(value, bool)):
        v = float(value)
        if math.isfinite(v) and lo <= v <= hi and not (lo_open and v == lo) and not (hi_open and v == hi):
            return v
    u = f" [{unit}]" if unit else ""
    span = f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
    raise ParameterError(f"{name}: expected a finite number in {span}{u}, got {value!r}")


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


def integer(value: object, name: str, *, lo: int = -(2**62), hi: int = 2**62) -> int:
    """An integer (not a bool) within [lo, hi], as a Python int.

    Raises:
        ParameterError: not an integer or out of range.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not lo <= int(value) <= hi:
        raise ParameterError(f"{name}: expected an integer in [{lo}, {hi}], got {value!r}")
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
    if isinstance(q, (str, bytes, dict)) or not hasattr(q, "__len__") or len(q) != 2:  # type: ignore[arg-type]
        raise JointError(f"{name}: expected (q_left, q_right), two joint vectors of shape (6,)")
    out = tuple(validate_joints(qi, name=f"{name}[{i}]") for i, qi in enumerate(q))  # type: ignore[union-attr]
    if any(qi.shape != (6,) for qi in out):
        raise JointError(f"{name}: expected two joint vectors of shape (6,), got {[qi.shape for qi in out]}")
    return out  # type: ignore[return-value]
