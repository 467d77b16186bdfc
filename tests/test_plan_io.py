"""Plan files: strict JSON (non-finite numbers as null), and every plan read back is checked —
corrupted, truncated or foreign NPZ files, malformed JSON data, reached plans with NaN joints or
poses that are not rigid give a DualpumaError (never EOFError, BadZipFile, KeyError, ...)."""

from __future__ import annotations

import io
import json
import math
import os
import re
import zipfile

import numpy as np
import pytest

from dualpuma import Cell, Plan, plan
from dualpuma.errors import DualpumaError, FileError, ParameterError


@pytest.fixture(scope="module")
def reached() -> Plan:
    c = Cell.default()
    B = c.T_world_object_start.copy()
    B[:3, 3] += (-0.1, -0.05, 0.05)  # 50 mm in -y: robot 2's wrist stays clear of its own pedestal
    p = plan(c, c.T_world_object_start, B)
    assert p.reached and p.n_steps >= 2
    return p


def _with(p: Plan, **changes) -> dict:
    """The plain-data form of ``p`` with per-step values changed: ``changes[key] = (row, value)``."""
    d = json.loads(p.to_json())
    for key, (row, value) in changes.items():
        d["steps"][row][key] = value
    return d


def _strict_loads(text: str):
    def refuse(token):
        raise AssertionError(f"non-standard JSON token {token}")

    return json.loads(text, parse_constant=refuse)


def test_json_is_strict_and_nan_comes_back_as_nan(reached):
    frozen = Plan("frozen", "blocked", reached.T_world_object, reached.q_left, reached.q_right,
                  np.full(reached.clearance.shape, np.nan), reached.pair, reached.t, path_length=math.inf,
                  meta={"x": float("nan"), "y": [1.0, float("-inf")]})
    text = frozen.to_json()
    d = _strict_loads(text)  # no NaN / Infinity tokens
    assert d["steps"][0]["clearance"] is None and d["path_length"] is None and d["meta"] == {"x": None, "y": [1.0, None]}
    back = Plan.from_json(text)
    assert np.isnan(back.clearance).all() and math.isnan(back.path_length)
    np.testing.assert_array_equal(back.q_left, frozen.q_left)
    assert Plan.from_json(reached.to_json()).equals(reached, ignore_timing=False)  # finite floats: exact


def test_the_npz_meta_is_strict_json_too(tmp_path, reached):
    p = Plan("frozen", "x", reached.T_world_object, reached.q_left, reached.q_right, reached.clearance, reached.pair,
             reached.t, path_length=math.nan)
    path = p.save_npz(tmp_path / "p.npz")
    with np.load(path, allow_pickle=False) as z:
        _strict_loads(str(z["meta"]))
    assert math.isnan(Plan.load_npz(path).path_length)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"q_left": (1, [float("nan")] * 6)}, "q_left"),
        ({"q_right": (0, [0.0, None, 0.0, 0.0, 0.0, 0.0])}, "q_right"),  # null = NaN
        ({"clearance": (1, None)}, "clearance"),
        ({"T_world_object": (1, (2.0 * np.eye(4)).tolist())}, "T_world_object"),  # scaled: not rigid
        ({"T_world_object": (0, [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1, 0], [0, 0, 0, 1]])}, "T_world_object"),  # det -1
        ({"t": (0, None)}, "t"),
        ({"pair": (0, ["bar"])}, "pair"),
        ({"q_left": (0, [0.0] * 5)}, "q_left"),
    ],
)
def test_malformed_plans_are_refused(reached, changes, message):
    d = _with(reached, **changes)
    with pytest.raises(ParameterError, match=message):
        Plan.from_dict(d)
    with pytest.raises(ParameterError, match=message):
        Plan.from_json(json.dumps(d))


def test_a_reached_plan_needs_a_step_and_other_statuses_keep_nan(reached):
    d = json.loads(reached.to_json())
    d["steps"] = []
    with pytest.raises(ParameterError, match="at least one step"):
        Plan.from_dict(d)
    d = _with(reached, q_left=(1, [None] * 6))
    d["status"] = "frozen"  # a frozen plan may hold rows it did not solve
    assert np.isnan(Plan.from_dict(d).q_left[1]).all()


@pytest.mark.parametrize(
    "data",
    [None, "plan", [1, 2], {"format": "dualpuma.plan/1"}, {"format": "dualpuma.plan/1", "steps": "x"},
     {"format": "dualpuma.plan/1", "steps": [1]}, {"format": ["x"]}],
)
def test_from_dict_refuses_non_plans(data):
    with pytest.raises(ParameterError):
        Plan.from_dict(data)


@pytest.mark.parametrize("text", [None, 5, "[" * 100_000, "{\"format\": " + "[" * 5000, b"\xff\xfe", "NaN"])
def test_from_json_refuses_non_json(text):
    with pytest.raises(ParameterError):
        Plan.from_json(text)


@pytest.mark.parametrize("indent", [-1, 17, 10**9, "  ", 2.0, True])
def test_to_json_indent_is_bounded(reached, indent):
    with pytest.raises(ParameterError, match="indent"):
        reached.to_json(indent=indent)


# ----------------------------------------------------------------------------- NPZ
def _npz(**arrays) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


@pytest.fixture(scope="module")
def good_npz(tmp_path_factory, reached) -> bytes:
    return reached.save_npz(tmp_path_factory.mktemp("npz") / "p.npz").read_bytes()


def _variants(good: bytes) -> dict[str, bytes]:
    z = zipfile.ZipFile(io.BytesIO(good))
    members = {n: z.read(n) for n in z.namelist()}
    meta = json.loads(str(np.load(io.BytesIO(good))["meta"]))

    def rebuilt(**over) -> bytes:
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w") as out:
            for n, data in {**members, **over}.items():
                if data is not None:
                    out.writestr(n, data)
        return buf.getvalue()

    def npy(a) -> bytes:
        b = io.BytesIO()
        np.save(b, a, allow_pickle=True)
        return b.getvalue()

    forged = bytearray(members["q_left.npy"])
    header_end = forged.index(b"\n") + 1
    head = forged[:header_end].decode("latin1").replace(str(tuple(np.load(io.BytesIO(members["q_left.npy"])).shape)),
                                                          "(100000000000, 6)")
    out = {
        "empty": b"",
        "truncated": good[: len(good) // 2],
        "one byte short": good[:-1],
        "random": bytes(range(256)) * 8,
        "text": b"hello, not a zip\n",
        "foreign npz": _npz(a=np.zeros(3), b=np.ones(2)),
        "no meta": rebuilt(**{"meta.npy": None}),
        "no q_left": rebuilt(**{"q_left.npy": None}),
        "meta not JSON": rebuilt(**{"meta.npy": npy(np.array("{not json"))}),
        "meta not an object": rebuilt(**{"meta.npy": npy(np.array("[1, 2]"))}),
        "meta other format": rebuilt(**{"meta.npy": npy(np.array(json.dumps({**meta, "format": "other/1"})))}),
        "meta missing keys": rebuilt(**{"meta.npy": npy(np.array(json.dumps({"format": meta["format"]})))}),
        "pickled object array": rebuilt(**{"q_left.npy": npy(np.array([object()] * 6, dtype=object))}),
        "string array": rebuilt(**{"q_left.npy": npy(np.array(["a"] * 6))}),
        "wrong shape": rebuilt(**{"q_left.npy": npy(np.zeros((3, 5)))}),
        "NaN joints in a reached plan": rebuilt(**{"q_right.npy": npy(np.full((len(meta["pair"]), 6), np.nan))}),
        "forged header": rebuilt(**{"q_left.npy": head.encode("latin1") + bytes(forged[header_end:])}),
        "corrupted member": good.replace(members["t.npy"][-16:], b"\x00" * 16) if members["t.npy"][-16:] in good else b"x",
    }
    return out


@pytest.mark.parametrize(
    "name",
    ["empty", "truncated", "one byte short", "random", "text", "foreign npz", "no meta", "no q_left", "meta not JSON",
     "meta not an object", "meta other format", "meta missing keys", "pickled object array", "string array",
     "wrong shape", "NaN joints in a reached plan", "forged header", "corrupted member"],
)
def test_load_npz_refuses_bad_files(tmp_path, good_npz, name):
    path = tmp_path / "bad.npz"
    path.write_bytes(_variants(good_npz)[name])
    with pytest.raises(DualpumaError):  # ParameterError (content) or FileError
        Plan.load_npz(path)


def test_load_npz_refuses_what_is_not_a_file(tmp_path):
    for path in (tmp_path / "missing.npz", tmp_path, "/dev/zero"):
        with pytest.raises(FileError):
            Plan.load_npz(path)
    with pytest.raises(FileError):
        Plan.load_npz(5)


def test_save_npz_round_trip_and_refusals(tmp_path, reached):
    path = tmp_path / "p.npz"
    reached.save_npz(path)
    assert Plan.load_npz(path).equals(reached, ignore_timing=False)
    with pytest.raises(FileError, match="overwrite"):
        reached.save_npz(path)
    with pytest.raises(ParameterError, match="overwrite"):
        reached.save_npz(path, overwrite="yes")  # not a bool
    with pytest.raises(FileError):
        reached.save_npz(tmp_path)  # a directory
    with pytest.raises(FileError):
        reached.save_npz(tmp_path / "missing" / "p.npz")
    assert sorted(os.listdir(tmp_path)) == ["p.npz"]  # no temporary file left behind


@pytest.fixture(scope="module")
def timed(reached) -> Plan:
    from dualpuma import World
    from dualpuma.planning import with_trajectory

    return with_trajectory(reached, World(Cell.default()))


def _edit(d: dict, path: tuple, value) -> dict:
    """A copy of plan dict d with d[path...] set to value (the trajectory's fields, as a file has them)."""
    d = json.loads(json.dumps(d))
    node = d
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return d


def test_a_corrupted_trajectory_in_a_file_is_refused(timed):
    """A plan file's trajectory goes to a controller as it is: a NaN sample, a joint that jumps,
    stated figures the samples contradict, or times that do not fit the plan's rows were loaded,
    certified (a helper streamed NaN and a 250 rad/s jump that way). Each is refused now; the
    file as written loads equal. The jump's speed is computed here from the samples."""
    d = timed.to_dict()
    assert Plan.from_dict(d).equals(timed)
    tr = d["trajectory"]
    k = len(tr["t"]) // 2
    jump_q = tr["q_left"][k][0] + 1.0
    speed = 1.0 / (tr["t"][k + 1] - tr["t"][k])
    assert speed > tr["v_max"][0]  # what the edit below makes the joint do
    cases = [
        (("trajectory", "q_left", k, 2), None, "Trajectory.q_left: contains NaN or inf"),
        (("trajectory", "qd_right", k, 0), None, "Trajectory.qd_right: contains NaN or inf"),
        (("trajectory", "q_left", k, 0), jump_q, "joint 1 of the left arm moves"),
        (("trajectory", "v_max", 0), 0.0, "v_max and a_max must be positive"),
        (("trajectory", "duration"), 99.0, "Trajectory.duration: 99.0 s"),
        (("trajectory", "velocity_ratio"), 5.0, "Trajectory.velocity_ratio: 5.0"),
        (("trajectory", "velocity_ratio"), 0.0, "Trajectory.velocity_ratio: 0.0, but the samples reach"),
        (("trajectory", "closure_error"), 0.01, "certified with a closed-chain error 0.01 m"),
        (("trajectory", "row_times", -1), 99.0, "trajectory: its sample times and row_times do not fit"),
        (("steps", 0, "t"), timed.t[0] + 0.5, "trajectory: its sample times and row_times do not fit"),
    ]
    for path, value, says in cases:
        with pytest.raises(ParameterError, match=re.escape(says)):
            Plan.from_dict(_edit(d, path, value))


def test_equals_compares_meta_as_a_file_holds_it(tmp_path):
    """Plan.equals ignored meta (a margin of 0.02 and one of 123 were equal); meta is compared as
    its JSON text, so a plan equals its own round trip through a file (tuples come back as lists)."""
    import dataclasses

    c = Cell.default()
    goal = c.T_world_object_start.copy()
    goal[2, 3] += 0.05
    p = plan(c, c.T_world_object_start, goal)
    assert p.meta["margin"] == 0.02
    assert not p.equals(dataclasses.replace(p, meta={**p.meta, "margin": 123.0}))
    q = dataclasses.replace(p, meta={**p.meta, "extra": (1, 2)})
    assert Plan.from_json(q.to_json()).equals(q)
    q.save_npz(tmp_path / "p.npz")
    assert Plan.load_npz(tmp_path / "p.npz").equals(q)
    odd = object()  # meta a file cannot hold: the plans still compare (no exception)
    r = dataclasses.replace(p, meta={"x": odd})
    assert r.equals(dataclasses.replace(p, meta={"x": odd})) and not r.equals(p)
