"""The file forms of a :class:`~dualpuma.planning.plan.Plan`: strict JSON and NPZ, and the checks
every plan read back from them passes.

* JSON (``Plan.to_json``/``from_json``) is strict (RFC 8259: no ``NaN``/``Infinity`` tokens): a
  non-finite number (NaN, +-inf) is written as ``null`` and read back as NaN. Finite floats
  round-trip exactly.
* NPZ (``Plan.save_npz``/``load_npz``): one float64 array per per-step field plus ``meta`` (the
  scalars, events and pairs as strict JSON text). Reading never unpickles, checks each member's
  declared shape and dtype before reading it (a forged header cannot make it allocate more than
  the file holds) and refuses files over :data:`MAX_PLAN_BYTES`.
* Every plan read back is checked (:func:`checked_fields`): shapes and row counts, a known status,
  texts, finite times; every pose a rigid transform; a ``reached`` plan has finite joints and
  clearances and at least one row. Anything else is a :class:`~dualpuma.errors.ParameterError`
  (a file that cannot be read at all: :class:`~dualpuma.errors.FileError`).
"""

from __future__ import annotations

import io
import json
import math
import zipfile

import numpy as np
import numpy.typing as npt

from ..checks import validate_pose
from ..errors import DualpumaError, ParameterError
from .trajectory import TRAJECTORY_FIELDS, Trajectory

__all__ = [
    "ARRAYS",
    "FORMAT",
    "MAX_PLAN_BYTES",
    "MAX_PLAN_STEPS",
    "SCALARS",
    "STATUSES",
    "checked_fields",
    "fields_from_dict",
    "fields_from_npz",
    "json_safe",
    "npz_bytes",
]

FloatArray = npt.NDArray[np.float64]

#: every status a plan can have
STATUSES = ("reached", "frozen", "invalid_start", "invalid_goal", "invalid_input", "limit_exceeded", "error")
FORMAT = "dualpuma.plan/1"  #: the ``format`` tag of both file forms
ARRAYS = ("T_world_object", "q_left", "q_right", "clearance", "t")  #: per-step arrays
TAILS = {"T_world_object": (4, 4), "q_left": (6,), "q_right": (6,), "clearance": (), "t": ()}
SCALARS = ("status", "reason", "path_length", "planning_time", "planner")
MAX_PLAN_BYTES = 256 * 1024 * 1024  #: largest plan file or JSON text read [bytes]
MAX_PLAN_STEPS = 1_000_000  #: most rows a plan read back may have
_MAX_TEXT = 100_000  # longest reason, event, planner or pair name [characters]


# ----------------------------------------------------------------------------- writing
def json_safe(value: object) -> object:
    """``value`` with every non-finite float replaced by None (JSON ``null``), numpy scalars and
    arrays as Python numbers and lists, tuples as lists: ready for ``json.dumps(allow_nan=False)``.

    Raises:
        ParameterError: a value JSON cannot hold (an object other than str, number, bool, None,
            list, tuple, dict with string keys, numpy array or scalar).
    """
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, (str, bool, int)):
        return value
    if isinstance(value, np.generic):
        return json_safe(value.item())
    if isinstance(value, np.ndarray):
        return json_safe(value.tolist())
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, dict):
        if not all(isinstance(k, str) for k in value):
            raise ParameterError("plan meta: dictionary keys must be strings")
        return {k: json_safe(v) for k, v in value.items()}
    raise ParameterError(f"plan: a {type(value).__name__} cannot be written as JSON")


def npz_bytes(arrays: dict[str, FloatArray], meta: dict) -> bytes:
    """The NPZ file of a plan's per-step arrays and its ``meta`` (strict JSON)."""
    buf = io.BytesIO()
    np.savez(buf, **arrays, meta=np.array(json.dumps(json_safe(meta), allow_nan=False)))
    return buf.getvalue()


# ----------------------------------------------------------------------------- reading
def _rows(steps: list, key: str, source: str) -> FloatArray:
    try:
        vals = [s[key] for s in steps]
        with np.errstate(all="ignore"):
            arr = np.array(vals, dtype=np.float64)  # null -> NaN
    except KeyError:
        raise ParameterError(f"{source}: a step has no {key!r}") from None
    except (TypeError, ValueError, OverflowError) as e:
        raise ParameterError(f"{source}: steps[].{key}: expected numbers ({type(e).__name__})") from None
    tail = TAILS[key]
    if arr.shape[1:] != tail and not (arr.size == 0 and len(steps) == 0):
        raise ParameterError(f"{source}: steps[].{key}: expected shape {tail} per step, got {arr.shape[1:]}")
    return arr.reshape((len(steps),) + tail)


def fields_from_dict(d: object, source: str = "plan data") -> dict:
    """The :class:`Plan` fields of a plan's plain-data form (``to_dict``), checked.

    Raises:
        ParameterError: not a dualpuma plan, or malformed (see :func:`checked_fields`).
    """
    if not isinstance(d, dict):
        raise ParameterError(f"{source}: expected an object (dict), got {type(d).__name__}")
    if d.get("format") != FORMAT:
        raise ParameterError(f"{source}: not a dualpuma plan (format {str(d.get('format'))[:80]!r}, expected {FORMAT!r})")
    steps = d.get("steps")
    if not isinstance(steps, list) or len(steps) > MAX_PLAN_STEPS:
        raise ParameterError(f"{source}: steps: expected a list of at most {MAX_PLAN_STEPS} steps")
    if not all(isinstance(s, dict) for s in steps):
        raise ParameterError(f"{source}: steps: every step must be an object")
    missing = [k for k in (*SCALARS, "events") if k not in d]
    if missing:
        raise ParameterError(f"{source}: missing {missing}")
    try:
        pair = [s["pair"] for s in steps]
    except KeyError:
        raise ParameterError(f"{source}: a step has no 'pair'") from None
    fields = {k: d[k] for k in SCALARS}
    fields.update({a: _rows(steps, a, source) for a in ARRAYS}, pair=pair, events=d["events"],
                  meta=d.get("meta", {}))
    traj = d.get("trajectory")
    fields["trajectory"] = None if traj is None else Trajectory.from_dict(traj)
    return checked_fields(fields, source)


def _member(zf: zipfile.ZipFile, name: str, kinds: str, source: str) -> np.ndarray:
    """One array of an NPZ, its header checked before any data is read."""
    member = f"{name}.npy"
    try:
        info = zf.getinfo(member)
    except KeyError:
        raise ParameterError(f"{source}: not a dualpuma plan (no {name!r} array)") from None
    with zf.open(info) as f:
        version = np.lib.format.read_magic(f)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(f)
        elif version == (2, 0):
            shape, _, dtype = np.lib.format.read_array_header_2_0(f)
        else:
            raise ParameterError(f"{source}: {name}: unsupported .npy version {version}")
    if dtype.hasobject or dtype.kind not in kinds:
        raise ParameterError(f"{source}: {name}: unexpected dtype {dtype}")
    if math.prod(shape) * dtype.itemsize > info.file_size:
        raise ParameterError(f"{source}: {name}: the header claims more data than the file holds")
    with zf.open(info) as f:
        return np.lib.format.read_array(f, allow_pickle=False)


def fields_from_npz(data: bytes, source: str = "plan") -> dict:
    """The :class:`Plan` fields of an NPZ file's bytes, checked.

    Raises:
        ParameterError: not an NPZ file, not a dualpuma plan, truncated or corrupted, malformed.
    """
    if len(data) > MAX_PLAN_BYTES:
        raise ParameterError(f"{source}: more than the {MAX_PLAN_BYTES} bytes accepted")
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            if sum(i.file_size for i in zf.infolist()) > MAX_PLAN_BYTES:
                raise ParameterError(f"{source}: unpacks to more than the {MAX_PLAN_BYTES} bytes accepted")
            meta_arr = _member(zf, "meta", "U", source)
            arrays = {a: _member(zf, a, "fiu", source) for a in ARRAYS}
            meta = json.loads(str(meta_arr))
            traj_scalars = meta.get("trajectory") if isinstance(meta, dict) else None
            traj = None if traj_scalars is None else Trajectory.from_arrays(
                {f"trajectory_{k}": _member(zf, f"trajectory_{k}", "fiu", source) for k in TRAJECTORY_FIELDS},
                traj_scalars)
    except DualpumaError:
        raise
    except (zipfile.BadZipFile, zipfile.LargeZipFile, EOFError, OSError, ValueError, TypeError, KeyError,
            NotImplementedError, RecursionError, UnicodeDecodeError) as e:  # json errors are ValueErrors
        raise ParameterError(f"{source}: not a readable dualpuma plan file ({type(e).__name__}: {e})"[:400]) from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise ParameterError(f"{source}: not a dualpuma plan")
    missing = [k for k in (*SCALARS, "events", "pair") if k not in meta]
    if missing:
        raise ParameterError(f"{source}: meta: missing {missing}")
    fields = {k: meta[k] for k in SCALARS}
    fields.update({a: np.asarray(arrays[a], dtype=np.float64) for a in ARRAYS}, pair=meta["pair"],
                  events=meta["events"], meta=meta.get("meta", {}), trajectory=traj)
    return checked_fields(fields, source)


# ----------------------------------------------------------------------------- checks
def _text(v: object, what: str, source: str) -> str:
    if not isinstance(v, str) or len(v) > _MAX_TEXT:
        raise ParameterError(f"{source}: {what}: expected a string of at most {_MAX_TEXT} characters")
    return v


def _number(v: object, what: str, source: str) -> float:
    if v is None:  # a non-finite number written as null
        return math.nan
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ParameterError(f"{source}: {what}: expected a number, got {type(v).__name__}")
    try:
        return float(v)
    except OverflowError:
        raise ParameterError(f"{source}: {what}: beyond the float range") from None


def checked_fields(f: dict, source: str = "plan") -> dict:
    """The fields of a plan read back, as the Plan constructor takes them, after every check of the
    module docstring.

    Raises:
        ParameterError: the first problem found, naming the field.
    """
    status = f["status"]
    if not isinstance(status, str) or status not in STATUSES:
        raise ParameterError(f"{source}: status: expected one of {STATUSES}, got {str(status)[:80]!r}")
    out: dict = {"status": status, "reason": _text(f["reason"], "reason", source),
                 "planner": _text(f["planner"], "planner", source)}
    for k in ("path_length", "planning_time"):
        out[k] = _number(f[k], k, source)
    arrays = {a: np.asarray(f[a], dtype=np.float64) for a in ARRAYS}
    n = arrays["T_world_object"].shape[0] if arrays["T_world_object"].ndim else -1
    for a, tail in TAILS.items():
        if arrays[a].shape != (n,) + tail:
            raise ParameterError(f"{source}: {a}: expected shape (N,) + {tail} with one row per step, "
                                 f"got {arrays[a].shape}")
    if n > MAX_PLAN_STEPS:
        raise ParameterError(f"{source}: {n} steps, more than the {MAX_PLAN_STEPS} accepted")
    events, pair = f["events"], f["pair"]
    if not isinstance(events, list) or len(events) > 10 * MAX_PLAN_STEPS:
        raise ParameterError(f"{source}: events: expected a list of strings")
    out["events"] = tuple(_text(e, "events[]", source) for e in events)
    if not isinstance(pair, list) or len(pair) != n or not all(
        isinstance(p, list) and len(p) == 2 and all(isinstance(x, str) and len(x) <= _MAX_TEXT for x in p) for p in pair
    ):
        raise ParameterError(f"{source}: pair: expected one [name, name] per step ({n})")
    out["pair"] = tuple((a, b) for a, b in pair)
    meta = f["meta"]
    if not isinstance(meta, dict):
        raise ParameterError(f"{source}: meta: expected an object, got {type(meta).__name__}")
    out["meta"] = meta
    traj = f.get("trajectory")
    if traj is not None and not isinstance(traj, Trajectory):
        raise ParameterError(f"{source}: trajectory: expected a timed trajectory")
    out["trajectory"] = traj
    if n:
        validate_pose(arrays["T_world_object"], name=f"{source}: T_world_object", error=ParameterError)
    if not np.all(np.isfinite(arrays["t"])):
        raise ParameterError(f"{source}: t: times must be finite")
    if status == "reached":
        if n == 0:
            raise ParameterError(f"{source}: a reached plan needs at least one step")
        for a in ("q_left", "q_right", "clearance"):
            if not np.all(np.isfinite(arrays[a])):
                raise ParameterError(f"{source}: {a}: a reached plan has finite values only (NaN or inf found)")
        if not (math.isfinite(out["path_length"]) and out["path_length"] >= 0):
            raise ParameterError(f"{source}: path_length: expected a finite length >= 0")
    out.update(arrays)
    return out
