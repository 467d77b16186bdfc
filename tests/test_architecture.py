"""The package's shape keeps the rules of docs/architecture.md: no private names across modules,
the import direction between subpackages, curated ``__all__`` lists that import, no state stored
on other objects, no oversized modules, and the deprecated deep imports still working."""

import ast
import importlib
import pkgutil
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

import dualpuma

SRC = Path(dualpuma.__file__).parent
MODULES = sorted(p for p in SRC.rglob("*.py"))
SUBPACKAGES = ("kinematics", "model", "collision", "planning", "envelope", "scenarios", "viewer", "cli")
#: which subpackages each may import (docs/architecture.md); top-level modules are below all of them
ALLOWED = {
    "kinematics": set(),
    "model": {"kinematics"},
    "collision": {"model", "kinematics"},
    "planning": {"collision", "model", "kinematics"},
    "envelope": {"collision", "model", "kinematics"},
    "scenarios": {"planning", "collision", "model", "kinematics"},
    "viewer": {"scenarios", "envelope", "planning", "collision", "model", "kinematics"},
    "cli": {"viewer", "scenarios", "envelope", "planning", "collision", "model", "kinematics"},
}
FOUNDATION = {"errors", "checks", "lie", "files", "units", "values"}  # top-level modules every subpackage may use
DEPRECATED = ("puma", "planner", "cell", "world", "coordination", "routines")


def module_name(path: Path) -> str:
    rel = path.relative_to(SRC.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def resolve(mod: str, node: ast.ImportFrom, is_pkg: bool) -> str:
    if node.level == 0:
        return node.module or ""
    base = mod.split(".") if is_pkg else mod.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def imports(path: Path):
    """(imported module, imported name or None) for every import of a source file."""
    tree = ast.parse(path.read_text())
    mod = module_name(path)
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            target = resolve(mod, node, path.name == "__init__.py")
            for alias in node.names:
                yield target, alias.name
        elif isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, None


def test_no_module_imports_a_private_name_from_another_module():
    bad = []
    for path in MODULES:
        for target, name in imports(path):
            if target.startswith("dualpuma") and name and name.startswith("_") and not name.startswith("__"):
                bad.append(f"{module_name(path)}: from {target} import {name}")
            if target.startswith("dualpuma") and any(p.startswith("_") and p != "__init__" for p in target.split(".")):
                bad.append(f"{module_name(path)}: import of private module {target}")
    assert not bad, bad


def test_no_private_attribute_of_another_module_is_used():
    """``module._name`` or ``obj._name`` where the object is not ``self``/``cls``: reaching into
    another module's or object's privates."""
    bad = []
    for path in MODULES:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__"):
                owner = node.value
                if isinstance(owner, ast.Name) and owner.id in ("self", "cls"):
                    continue
                bad.append(f"{module_name(path)}:{node.lineno}: .{node.attr}")
    assert not bad, bad


def test_subpackages_import_only_below_themselves():
    bad = []
    for path in MODULES:
        parts = module_name(path).split(".")
        if len(parts) < 2 or parts[1] not in SUBPACKAGES:
            if len(parts) == 2 and parts[1] in FOUNDATION:  # the foundation imports only itself
                for target, _ in imports(path):
                    if target.startswith("dualpuma.") and target.split(".")[1] not in FOUNDATION:
                        bad.append(f"{module_name(path)} imports {target}")
            continue
        own = parts[1]
        for target, _ in imports(path):
            if not target.startswith("dualpuma."):
                continue
            other = target.split(".")[1]
            if other in (own, *FOUNDATION):
                continue
            if other not in ALLOWED[own]:
                bad.append(f"{module_name(path)} imports {target}")
    assert not bad, bad


def test_no_state_is_stored_on_another_object():
    """No ``x.__dict__`` writes and no ``setattr`` on foreign objects (caches live in WorldCache)."""
    bad = []
    for path in MODULES:
        src = path.read_text()
        if "__dict__" in src:
            bad.append(f"{module_name(path)} uses __dict__")
        for node in ast.walk(ast.parse(src)):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "setattr":
                target = node.args[0]
                if not (isinstance(target, ast.Name) and target.id == "self"):
                    bad.append(f"{module_name(path)}:{node.lineno}: setattr on {ast.unparse(target)}")
    assert not bad, bad


def test_no_module_is_over_450_lines():
    long = {module_name(p): n for p in MODULES if (n := len(p.read_text().splitlines())) > 450}
    assert not long, long


def test_no_mixins_split_a_class():
    """A class built from mixins that exist only to hold its methods (the old kernel) is one class."""
    bad = []
    for path in MODULES:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ClassDef):
                for base in node.bases:
                    if isinstance(base, ast.Name) and base.id.startswith("_"):
                        bad.append(f"{module_name(path)}.{node.name}({base.id})")
    assert not bad, bad


@pytest.mark.parametrize("package", ["dualpuma", *(f"dualpuma.{p}" for p in SUBPACKAGES)])
def test_every_name_in_all_imports(package):
    mod = importlib.import_module(package)
    assert isinstance(mod.__all__, list) and mod.__all__ == sorted(set(mod.__all__), key=mod.__all__.index)
    for name in mod.__all__:
        assert getattr(mod, name) is not None, f"{package}.{name}"


def test_every_module_has_all_and_a_docstring():
    missing = []
    for info in pkgutil.walk_packages(dualpuma.__path__, "dualpuma."):
        if info.name.split(".")[-1] in DEPRECATED or info.name.endswith("__main__"):
            continue
        mod = importlib.import_module(info.name)
        if not mod.__doc__ or not hasattr(mod, "__all__"):
            missing.append(info.name)
        for name in getattr(mod, "__all__", ()):
            assert hasattr(mod, name), f"{info.name}.{name} listed in __all__ but missing"
    assert not missing, missing


@pytest.mark.parametrize("name", DEPRECATED)
def test_deprecated_deep_imports_still_work_and_warn(name):
    """dualpuma.puma, .planner, .cell, .world, .coordination, .routines re-export their old names
    for one release, with a DeprecationWarning (a fresh interpreter, so the import really runs)."""
    code = (f"import warnings; warnings.simplefilter('error', DeprecationWarning)\n"
            f"try:\n    import dualpuma.{name}\nexcept DeprecationWarning as w:\n    print('warned:', w)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)
    assert r.returncode == 0 and f"warned: dualpuma.{name} is deprecated" in r.stdout, r.stderr
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        mod = importlib.import_module(f"dualpuma.{name}")
    for attr in mod.__all__:
        assert getattr(mod, attr) is not None


def test_stable_names_work_as_before(cell):
    """The names users already use (the issue's list) behave as before."""
    import numpy as np

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        import dualpuma.puma
        import dualpuma.routines

    T = dualpuma.Arm.puma560().fk(np.zeros(6))
    sols, valid = dualpuma.puma.ik_all(T)
    assert valid.any() and np.allclose(dualpuma.puma.fk(sols[valid][0]), T, atol=1e-12)
    assert dualpuma.Cell.default().name == "seed-default"
    c = dualpuma.World(cell).clearance(cell.left.q_home, cell.right.q_home)
    assert np.isfinite(c.distance) and len(c.pair) == 2
    assert dualpuma.plan(cell, cell.T_world_object_start, cell.T_world_object_start).reached
    assert dualpuma.routines.run_routine(2).reached
    assert callable(dualpuma.load_cell) and callable(dualpuma.plan_many) and dualpuma.StrivingParams().step == 0.05
    assert isinstance(dualpuma.Plan.failed("error", "x"), dualpuma.Plan)
