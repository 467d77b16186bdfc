"""The documentation names only what exists: every dotted ``dualpuma.…`` name in README.md and
docs/*.md (in backticks) imports, every module path ``src/dualpuma/….py`` it cites is a file,
and every CLI subcommand and ``--flag`` it shows for ``dualpuma <command>`` is one that command's
parser accepts."""

from __future__ import annotations

import importlib
import re
import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
_NAME = re.compile(r"`[^`\n]*?\b(dualpuma(?:\.[A-Za-z_]\w*)+)")


def _names() -> list[tuple[str, str]]:
    out = set()
    for f in DOCS:
        for m in _NAME.finditer(f.read_text()):
            out.add((f.name, m.group(1)))
    return sorted(out)


def _resolve(dotted: str) -> object:
    """The object a dotted name denotes: the longest importable module prefix, then attributes."""
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            with warnings.catch_warnings():  # the docs also name the deprecated aliases (dualpuma.puma)
                warnings.simplefilter("ignore", DeprecationWarning)
                obj = importlib.import_module(".".join(parts[:i]))
        except ModuleNotFoundError:
            continue
        for a in parts[i:]:
            obj = getattr(obj, a)
        return obj
    raise ModuleNotFoundError(dotted)


def test_the_docs_name_dotted_names():
    assert len(_names()) > 30  # the pattern finds what the docs cite


@pytest.mark.parametrize(("doc", "dotted"), _names())
def test_a_dotted_name_in_the_docs_exists(doc, dotted):
    try:
        _resolve(dotted)
    except (ImportError, AttributeError) as exc:
        pytest.fail(f"{doc} names `{dotted}`, which does not exist: {exc}")


_PATH = re.compile(r"(?<![\w/.])((?:src/dualpuma|benchmarks|tests|web_demo|[a-z_]+)/[\w/]*\w\.py)\b")


def _paths() -> list[tuple[str, str]]:
    return sorted({(f.name, m.group(1)) for f in DOCS for m in _PATH.finditer(f.read_text())})


def test_the_docs_cite_files():
    assert len(_paths()) > 30


@pytest.mark.parametrize(("doc", "path"), _paths())
def test_a_file_the_docs_cite_exists(doc, path):
    """A path from the project root, or a module path inside the package (``model/pairs.py``)."""
    assert (ROOT / path).is_file() or (ROOT / "src" / "dualpuma" / path).is_file(), f"{doc} cites {path}"


_COMMAND = re.compile(r"\bdualpuma (fk|ik|plan|routine|envelope|serve)\b([^`\n]*)")


def _flags() -> list[tuple[str, str, str]]:
    out = set()
    for f in DOCS:
        for m in _COMMAND.finditer(f.read_text()):
            out |= {(f.name, m.group(1), flag) for flag in re.findall(r"(?<![\w-])--[a-z][a-z0-9-]*", m.group(2))}
    return sorted(out)


def test_the_docs_show_command_flags():
    assert len(_flags()) > 15


@pytest.fixture(scope="module")
def helps() -> dict[str, str]:
    """Each command's ``--help`` text, as ``dualpuma <command> --help`` prints it."""
    import contextlib
    import io

    from dualpuma.cli import main

    out = {}
    for cmd in ("fk", "ik", "plan", "routine", "envelope", "serve"):
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            assert main([cmd, "--help"]) == 0
        out[cmd] = buf.getvalue()
    return out


@pytest.mark.parametrize(("doc", "cmd", "flag"), _flags())
def test_a_flag_the_docs_show_is_accepted(doc, cmd, flag, helps):
    assert re.search(rf"(?<![\w-]){re.escape(flag)}(?![\w-])", helps[cmd]), (
        f"{doc}: `dualpuma {cmd} ... {flag}` is not in `dualpuma {cmd} --help`")
