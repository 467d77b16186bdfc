"""Fuzz of the command line: every subcommand with generated arguments (bad numbers, wrong counts,
unknown flags, missing values, unreadable and malformed files, impossible outputs) run in-process
through ``dualpuma.cli.main``, plus a few real subprocesses. Bad input exits 2 with one line on
stderr and nothing on stdout; nothing ever prints a traceback or an internal error (exit 70)."""

from __future__ import annotations

import os
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest
from fuzz_targets import FUZZ_RANDOM
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import dualpuma
from dualpuma import Cell, save_cell
from dualpuma.cli import COMMANDS, main

TRIED: Counter = Counter()
FIXED = settings(max_examples=int(os.environ.get("DUALPUMA_FUZZ_EXAMPLES", "60")), deadline=None, database=None,
                 derandomize=not FUZZ_RANDOM,
                 suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
                                        HealthCheck.data_too_large])


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, str]:
    d = tmp_path_factory.mktemp("cli_files")
    (d / "bad.toml").write_text("[left]\nrobot = 5\n")
    (d / "binary.toml").write_bytes(bytes(range(256)) * 4)
    (d / "exists.json").write_text("{}")
    good = save_cell(Cell.default(), d / "good.toml")
    return {"dir": str(d), "missing": str(d / "missing" / "x.toml"), "bad": str(d / "bad.toml"),
            "binary": str(d / "binary.toml"), "exists": str(d / "exists.json"), "good": str(good),
            "new": str(d / "new.json"), "zero": "/dev/zero", "null": "/dev/null"}


NUMBERS = ["0", "1", "-1", "10", "-200", "45", "500", "1000", "2500", "1e3", "0.5", "1,2,3", "1 2 3", "10 20 30 0 45 0"]
BAD_NUMBERS = ["nan", "inf", "-inf", "1e400", "abc", "", " ", "--", "1..2", "0x10", "١٢٣", "9" * 400, "1e-400", "½",
               "\x00", "é", "-1e-3", "+-1"]
PATHS = ["dir", "missing", "bad", "binary", "exists", "good", "new", "zero", "null"]

# per subcommand: its flags and how many values each takes (None: any number of numbers)
FLAGS: dict[str, dict[str, int | None]] = {
    "fk": {"--robot": 1, "--q": None, "--frame": 1, "--json": 0},
    "ik": {"--robot": 1, "--xyz": None, "--rpy": None, "--json": 0},
    "plan": {"--cell": 1, "--to": None, "--by": None, "--rpy": None, "--step-mm": 1, "--step-time": 1, "--out": 1,
             "--force": 0,
             "--json": 0, "--trajectory": 0, "--v-max": None, "--a-max": None, "--max-wait": 1, "--max-slowdown": 1,
             "--period": 1, "--fallback": 0, "--time-limit": 1},
    "routine": {"--json": 0},
    "envelope": {"--ideal": 0, "--reach-mm": 1, "--reach": 1, "--base-distance-mm": 1, "--base-distance": 1,
                 "--bar-length-mm": 1, "--bar-length": 1, "--cell": 1, "--resolution-mm": 1, "--resolution": 1,
                 "--clearance": 0,
                 "--json": 0},
}
# values that keep a valid run fast (no fine envelope grids, no long plans)
SAFE_VALUES = {"--resolution-mm": ["abc", "nan", "-1", "0", "1", "2", "501", "1e9", "40", "100"],
               "--resolution": ["abc", "nan", "-1", "0", "0.025", "1", "40", "100"],
               "--step-mm": ["abc", "nan", "0", "-5", "1e9", "50", "100"],
               "--step-time": ["abc", "nan", "0", "-1", "1e9", "0.1", "0.5"],
               "--period": ["abc", "nan", "0", "-1", "1e-5", "2", "0.004", "0.05", "1"],
               "--time-limit": ["abc", "nan", "inf", "0", "-1", "1e9", "0.05", "0.5"],
               "--robot": ["puma560", "ur5", "z1", "kuka", "", "PUMA560"],
               "--frame": ["wrist", "nope", "", "link3", "gripper"]}


def _value(draw, flag: str, files: dict[str, str]) -> str:
    if flag in SAFE_VALUES:
        return draw(st.sampled_from(SAFE_VALUES[flag]))
    if flag in ("--cell", "--out"):
        return draw(st.sampled_from([files[p] for p in PATHS] + ["default", "agv", "nope", ""]))
    return draw(st.one_of(st.sampled_from(NUMBERS + BAD_NUMBERS), st.text(max_size=6)))


@st.composite
def argvs(draw, cmd: str, files: dict[str, str]) -> list[str]:
    argv = [cmd]
    if cmd == "routine":
        argv.append(draw(st.sampled_from(["0", "9", "-1", "abc", "1.5", "", "8", "2", "100000000000000000000"])))
    flags = FLAGS[cmd]
    for _ in range(draw(st.integers(0, 5))):
        kind = draw(st.integers(0, 9))
        if kind == 0:  # an unknown flag or a stray word
            argv.append(draw(st.sampled_from(["--bogus", "-x", "--q=1", "--", "-", "extra", "--JSON", "-h"])))
            continue
        flag = draw(st.sampled_from(sorted(flags)))
        argv.append(flag)
        n = flags[flag]
        count = draw(st.integers(0, 7)) if n is None else (n if draw(st.integers(0, 5)) else draw(st.integers(0, 2)))
        argv += [_value(draw, flag, files) for _ in range(count)]
    return argv


def _check(argv: list[str], capsys) -> int:
    capsys.readouterr()
    rc = main(argv)
    out, err = capsys.readouterr()
    TRIED[argv[0] if argv else ""] += 1
    assert "Traceback" not in err and "internal error" not in err, (argv, err)
    assert rc in (0, 1, 2), (argv, rc, err)
    if rc == 2:
        assert err.endswith("\n") and err.count("\n") == 1 and "error" in err, (argv, err)
        assert out == "", (argv, out[:200])
    return rc


@pytest.mark.parametrize("cmd", ["fk", "ik", "plan", "routine", "envelope"])
@FIXED
@given(data=st.data())
def test_generated_arguments(cmd, files, capsys, data):
    _check(data.draw(argvs(cmd, files)), capsys)


@FIXED
@given(data=st.data())
def test_serve_with_bad_arguments_never_starts(files, capsys, data):
    """Only arguments that must fail (the server would otherwise start and block)."""
    head = data.draw(st.lists(st.sampled_from(["--host", "127.0.0.1", "--cell", files["good"]]), max_size=3))
    bad = data.draw(st.sampled_from([["--port", "abc"], ["--port"], ["--bogus"], ["--cell", files["missing"]],
                                     ["--cell", files["bad"]], ["--cell", files["zero"]], ["--cell", files["dir"]],
                                     ["--cell", files["binary"]], ["--port", "1.5"]]))
    assert _check(["serve", *head, *bad], capsys) == 2


BAD = {
    "fk": [["--q", "1", "2"], ["--q", "a b c d e f"], ["--q", "nan", "0", "0", "0", "0", "0"], ["--robot", "kuka"],
           ["--frame", "nope"], ["--q"], ["--bogus"], ["--q", "1", "2", "3", "4", "5", "6", "7"], ["--robot", "ur5", "--frame", ""]],
    "ik": [[], ["--xyz"], ["--xyz", "1", "2"], ["--rpy", "1", "2", "3"], ["--xyz", "1", "2", "inf"],
           ["--xyz", "1", "2", "3", "--rpy", "x", "y", "z"], ["--xyz", "1e400", "0", "0"]],
    "plan": [[], ["--by", "1", "2"], ["--to", "1", "2", "3", "--by", "1", "2", "3"], ["--by", "0", "0", "0", "--cell", "zero"],
             ["--by", "0", "0", "0", "--cell", "bad"], ["--by", "0", "0", "0", "--cell", "binary"],
             ["--by", "0", "0", "0", "--cell", "dir"], ["--by", "0", "0", "0", "--cell", "missing"],
             ["--by", "0", "0", "0", "--out", "dir"], ["--by", "0", "0", "0", "--out", "missing"],
             ["--by", "0", "0", "0", "--out", "null"], ["--by", "0", "0", "0", "--out", "exists"],
             ["--by", "0", "0", "0", "--step-mm", "0"], ["--by", "0", "0", "0", "--step-mm", "nan"],
             ["--by", "0", "0", "0", "--rpy", "1"], ["--to", "nan", "0", "0"], ["--by", "1e400", "0", "0"]],
    "routine": [[], ["9"], ["0"], ["abc"], ["1", "2"], ["1.5"]],
    "envelope": [["--ideal", "--reach", "1"], ["--reach-mm", "1000"], ["--resolution-mm", "1"], ["--cell", "missing"],
                 ["--ideal", "--reach-mm", "1000", "--reach", "1000"], ["--resolution", "0.025"],
                 ["--ideal", "--resolution-mm", "40"], ["--ideal", "--reach-mm", "-1"], ["--cell", "zero"],
                 ["--ideal", "--bar-length-mm", "nan"]],
    "serve": [["--port", "abc"], ["--cell", "missing"], ["--bogus"]],
    "": [[], ["nope"], ["--bogus"]],
}


@pytest.mark.parametrize(("cmd", "args"), [(c, a) for c, cases in BAD.items() for a in cases])
def test_known_bad_arguments_exit_2(cmd, args, files, capsys):
    argv = ([cmd] if cmd else []) + [files.get(a, a) if a in PATHS else a for a in args]
    assert _check(argv, capsys) == 2


def test_every_subcommand_is_fuzzed():
    names = {m.__name__.rsplit(".", 1)[-1] for m in COMMANDS}
    assert names == set(FLAGS) | {"serve"}


@pytest.mark.parametrize(
    "argv",
    [["fk", "--q", "1", "2"], ["ik", "--xyz", "abc", "0", "0"], ["plan", "--by", "0", "0", "0", "--cell", "/dev/zero"],
     ["routine", "9"], ["envelope", "--ideal", "--reach", "1"], ["serve", "--cell", "/nonexistent/cell.toml"],
     ["nope"]],
)
def test_real_processes_exit_2_with_one_line(argv):
    src = str(Path(dualpuma.__file__).parents[1])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([src, os.environ.get("PYTHONPATH", "")])}
    r = subprocess.run([sys.executable, "-m", "dualpuma.cli", *argv], capture_output=True, text=True, timeout=120,
                       env=env, check=False)
    assert r.returncode == 2 and r.stdout == "", (r.returncode, r.stdout)
    assert r.stderr.count("\n") == 1 and "error" in r.stderr and "Traceback" not in r.stderr, r.stderr


def test_zz_report(capsys):
    total = sum(TRIED.values())
    with capsys.disabled():
        print(f"\nfuzz (CLI): {total} command lines over {len(TRIED)} subcommands, none with a traceback")


def test_every_flag_of_the_fuzzed_commands_is_fuzzed():
    """A flag added to a command is added to FLAGS too (the two new timing flags were missed once)."""
    import argparse

    from dualpuma.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    for cmd, flags in FLAGS.items():
        have = {o for a in sub.choices[cmd]._actions for o in a.option_strings if o.startswith("--") and o != "--help"}
        assert have == set(flags), (cmd, sorted(have ^ set(flags)))
