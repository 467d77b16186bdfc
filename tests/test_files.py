"""Writers and readers of the user's files: nothing lost, nothing surprising. Every writer goes
through dualpuma.files.atomic_write (a random temporary name in the target's directory, os.replace,
the temporary removed on failure, the target's permission bits kept); a directory, a missing
directory or a device as target is an error before any work; readers refuse devices, FIFOs and
oversized files at once."""

from __future__ import annotations

import os
import stat
import time

import numpy as np
import pytest

import dualpuma.cli.plan as cli_plan
from dualpuma import Cell, Plan, files, load_cell, save_cell
from dualpuma.cli import main
from dualpuma.errors import CellError, DualpumaError, FileError
from dualpuma.files import atomic_write, check_writable, read_limited


@pytest.fixture(scope="module")
def small_plan() -> Plan:
    return Plan.failed("frozen", "a plan to write")


def _writers(small_plan):
    """Every writer of the package, as (name, write(path, overwrite))."""
    return [
        ("atomic_write", lambda p, o: atomic_write(p, b"new contents", overwrite=o)),
        ("save_cell", lambda p, o: save_cell(Cell.default(), p, overwrite=o)),
        ("save_npz", lambda p, o: small_plan.save_npz(p, overwrite=o)),
        ("plan --out", lambda p, o: _cli_plan_out(p, o)),
    ]


def _cli_plan_out(path, overwrite):
    rc = main(["plan", "--by", "0", "0", "0", "--out", str(path)] + (["--force"] if overwrite else []))
    if rc == 2:
        raise FileError("the CLI refused")
    return path


WRITERS = ["atomic_write", "save_cell", "save_npz", "plan --out"]


def _writer(name, small_plan):
    return dict(_writers(small_plan))[name]


@pytest.mark.parametrize("name", WRITERS)
def test_a_file_named_like_a_temporary_is_not_touched(tmp_path, small_plan, name):
    target = tmp_path / "p.json"
    bystanders = {tmp_path / "p.json.tmp": b"someone's work", tmp_path / ".p.json.tmp": b"more work",
                  tmp_path / "p.json~": b"a backup"}
    for p, data in bystanders.items():
        p.write_bytes(data)
    _writer(name, small_plan)(target, False)
    assert target.exists()
    for p, data in bystanders.items():
        assert p.read_bytes() == data
    assert sorted(os.listdir(tmp_path)) == sorted(["p.json", *(p.name for p in bystanders)])  # no temporary left


@pytest.mark.parametrize("name", WRITERS)
def test_a_link_planted_at_a_temporary_name_does_not_redirect_the_write(tmp_path, small_plan, name):
    victim = tmp_path / "victim"
    victim.write_bytes(b"must stay")
    d = tmp_path / "out"
    d.mkdir()
    for link in ("p.json.tmp", ".p.json.tmp", "p.json.part", ".p.json.part"):
        (d / link).symlink_to(victim)
    _writer(name, small_plan)(d / "p.json", False)
    assert victim.read_bytes() == b"must stay"
    assert (d / "p.json").is_file() and not (d / "p.json").is_symlink()


@pytest.mark.parametrize("name", WRITERS)
@pytest.mark.parametrize("mode", [0o644, 0o640, 0o600, 0o664])
def test_overwriting_keeps_the_permission_bits(tmp_path, small_plan, name, mode):
    target = tmp_path / "p.json"
    target.write_bytes(b"old")
    os.chmod(target, mode)
    _writer(name, small_plan)(target, True)
    assert stat.S_IMODE(os.stat(target).st_mode) == mode and target.read_bytes() != b"old"


def test_a_new_file_gets_the_usual_permissions(tmp_path):
    umask = os.umask(0o022)
    try:
        atomic_write(tmp_path / "new", b"x")
    finally:
        os.umask(umask)
    assert stat.S_IMODE(os.stat(tmp_path / "new").st_mode) == 0o644  # not mkstemp's 0600


@pytest.mark.parametrize("name", WRITERS)
def test_existing_files_are_kept_unless_asked(tmp_path, small_plan, name):
    target = tmp_path / "p.json"
    target.write_bytes(b"old")
    with pytest.raises(DualpumaError):
        _writer(name, small_plan)(target, False)
    assert target.read_bytes() == b"old"


@pytest.mark.parametrize("name", WRITERS)
@pytest.mark.parametrize("where", ["a directory", "a missing directory", "a device", "a NUL in the name"])
def test_impossible_targets_are_errors(tmp_path, small_plan, name, where):
    target = {"a directory": tmp_path, "a missing directory": tmp_path / "missing" / "p.json",
              "a device": "/dev/null", "a NUL in the name": str(tmp_path / "p\0.json")}[where]
    with pytest.raises(DualpumaError):
        _writer(name, small_plan)(target, True)
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("target", ["dir", "missing/p.json", "/dev/null", "exists.json"])
def test_plan_refuses_its_output_before_planning(tmp_path, monkeypatch, capsys, target):
    (tmp_path / "dir").mkdir()
    (tmp_path / "exists.json").write_text("{}")

    def no_planning(*a, **k):
        raise AssertionError("planned before checking --out")

    monkeypatch.setattr(cli_plan, "plan", no_planning)
    out = target if target.startswith("/") else str(tmp_path / target)
    assert main(["plan", "--by", "0", "0", "10", "--out", out]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "error" in err and out in err


def test_the_temporary_is_removed_when_the_write_fails(tmp_path, monkeypatch):
    def broken_replace(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(files.os, "replace", broken_replace)
    monkeypatch.setattr(files.os, "link", broken_replace)  # a new file is linked into place
    with pytest.raises(FileError, match="No space left"):
        atomic_write(tmp_path / "p.json", b"data")
    assert os.listdir(tmp_path) == []
    (tmp_path / "p.json").write_bytes(b"old")
    with pytest.raises(FileError, match="No space left"):
        atomic_write(tmp_path / "p.json", b"data", overwrite=True)
    assert os.listdir(tmp_path) == ["p.json"] and (tmp_path / "p.json").read_bytes() == b"old"


def test_a_file_another_process_creates_during_a_write_is_never_replaced(tmp_path, monkeypatch):
    """A new file's name was checked free, then the temporary renamed over it: a file another
    process created in between was replaced. The temporary is now hard-linked to the name, which
    fails if the name exists by then."""
    target = tmp_path / "p.json"
    real_replace, real_link = os.replace, os.link

    def other_process_first(rename):
        def step(src, dst):
            target.write_bytes(b"theirs")  # the other process's file appears now
            return rename(src, dst)
        return step

    monkeypatch.setattr(files.os, "replace", other_process_first(real_replace))
    monkeypatch.setattr(files.os, "link", other_process_first(real_link))
    with pytest.raises(FileError, match="exists"):
        atomic_write(target, b"ours")
    assert target.read_bytes() == b"theirs" and os.listdir(tmp_path) == ["p.json"]


def test_check_writable_names_the_problem(tmp_path):
    (tmp_path / "f").write_text("x")
    for path, words in ((tmp_path, "not a regular file"), (tmp_path / "nope" / "f", "does not exist"),
                        (tmp_path / "f", "exists"), ("", "not a file name"), (5, "file name"),
                        (tmp_path / ("x" * 5000), "characters")):
        with pytest.raises(FileError, match=words):
            check_writable(path)
    assert check_writable(tmp_path / "f", overwrite=True) == tmp_path / "f"


# ----------------------------------------------------------------------------- readers
@pytest.mark.parametrize("reader", [read_limited, load_cell, Plan.load_npz])
def test_readers_refuse_devices_fifos_and_directories_at_once(tmp_path, reader):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)  # opening it would block until a writer comes
    for path in ("/dev/zero", "/dev/urandom", fifo, tmp_path, tmp_path / "missing", "a\0b"):
        t0 = time.perf_counter()
        with pytest.raises(DualpumaError):
            reader(path)
        assert time.perf_counter() - t0 < 1.0


def test_read_limited_refuses_large_files(tmp_path):
    big = tmp_path / "big"
    with open(big, "wb") as f:
        f.truncate(2_000_001)  # sparse: costs no disk
    with pytest.raises(FileError, match="more than"):
        read_limited(big, limit=2_000_000)
    with pytest.raises(CellError, match="more than"):
        load_cell(big)  # cells: at most 1 MB
    assert read_limited(big, limit=3_000_000) == bytes(2_000_001)
    assert np.frombuffer(read_limited(big, limit=2_000_001), np.uint8).sum() == 0
