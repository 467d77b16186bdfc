"""The pinned versions (constraints.txt) that `make serve`, `make test` and `make bench` install:
every declared dependency is pinned inside its declared range, the Makefile installs with them, and
this test run uses them."""

from __future__ import annotations

import re
import tomllib
from importlib import metadata
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]


def _pins() -> dict[str, Version]:
    pins: dict[str, Version] = {}
    for line in (ROOT / "constraints.txt").read_text().splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        m = re.fullmatch(r"([A-Za-z0-9][A-Za-z0-9._-]*)==([^\s;]+)", line)
        assert m, f"constraints.txt: not an exact pin: {line!r}"
        name = canonicalize_name(m.group(1))
        assert name not in pins, f"constraints.txt: {name} pinned twice"
        pins[name] = Version(m.group(2))
    return pins


def _declared() -> dict[str, list[Requirement]]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    groups = {"": [Requirement(r) for r in project["dependencies"]]}
    groups.update({k: [Requirement(r) for r in v] for k, v in project["optional-dependencies"].items()})
    return groups


def test_every_declared_dependency_is_pinned_inside_its_range():
    pins = _pins()
    for extra, reqs in _declared().items():
        for req in reqs:
            name = canonicalize_name(req.name)
            assert name in pins, f"{req.name} ({extra or 'base'} dependency) is not pinned in constraints.txt"
            assert req.specifier.contains(pins[name], prereleases=True), (
                f"constraints.txt pins {req.name}=={pins[name]}, outside pyproject.toml's {req.specifier}"
            )


def test_the_makefile_installs_with_the_constraints():
    lines = [ln.strip() for ln in (ROOT / "Makefile").read_text().splitlines() if "pip install" in ln]
    installs = [ln for ln in lines if "--upgrade pip" not in ln]
    assert len(installs) >= 2, lines  # make test / serve, make bench
    for ln in installs:
        assert "-c constraints.txt" in ln, f"Makefile installs without the pins: {ln}"
    assert re.search(r"^\$\(STAMP\):.*\bconstraints\.txt\b", (ROOT / "Makefile").read_text(), re.MULTILINE), (
        "the install stamp must depend on constraints.txt (a changed pin reinstalls)"
    )


def test_this_run_uses_the_pinned_versions():
    pins = _pins()
    wrong = []
    for req in _declared()[""] + _declared()["test"]:
        name = canonicalize_name(req.name)
        installed = Version(metadata.version(req.name))
        if installed != pins[name]:
            wrong.append(f"{req.name} {installed} (pinned {pins[name]})")
    assert not wrong, "installed versions differ from constraints.txt (run `make test`): " + ", ".join(wrong)
