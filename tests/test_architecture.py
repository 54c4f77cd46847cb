"""The architecture contract: subpackages import only downward, never each other's private names.

The package is layered along the data flow of a control cycle. A module may import from its own
subpackage and from any layer below; an import that goes up (or sideways between two layers of
the same rank) would make a cycle possible and is refused here. Imports inside functions count
too: a lazy import is still a dependency. Imports under ``if TYPE_CHECKING:`` are not run and
serve annotations only (a chain type in the kinematics layer); they are exempt. Names
starting with ``_`` stay inside their subpackage.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "ratectl"

# lowest first; layers on one line have the same rank and must not import each other
LAYERS: list[tuple[str, ...]] = [
    ("errors", "arrays"),
    ("checks",),
    ("spatial",),
    ("kinematics",),
    ("io",),
    ("model",),
    ("singularity",),
    ("solvers",),
    ("tasks", "collision"),
    ("control", "paths"),
    ("planning",),
    ("drivers",),
    ("execution",),
    ("interop",),
    ("viewer",),
    ("cli", "compiled"),
]
RANK = {name: rank for rank, names in enumerate(LAYERS) for name in names}
TOP = "__init__"  # the package's own __init__ re-exports everything (lazily)


def _layer_of(module: str) -> str:
    """'ratectl.solvers.qp.bounds' -> 'solvers'."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else TOP


def _module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _imports(source: str, module: str, *, is_pkg: bool = False):
    """(line, imported module, imported names) of every ratectl import in a module's source."""
    tree = ast.parse(source)
    type_only = set()
    for node in ast.walk(tree):  # "if TYPE_CHECKING:" imports exist for annotations only
        if isinstance(node, ast.If) and getattr(node.test, "id", getattr(node.test, "attr", "")) \
                == "TYPE_CHECKING":
            type_only.update(id(n) for b in node.body for n in ast.walk(b))
    for node in ast.walk(tree):
        if id(node) in type_only:
            continue
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".")
                if not is_pkg:
                    base = base[:-1]
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            names = [a.name for a in node.names]
            if target.startswith("ratectl"):
                if node.module is None or target.count(".") == 0:
                    # "from . import solvers" / "from ratectl import x": each name is a module
                    for name in names:
                        yield node.lineno, f"{target}.{name}", []
                else:
                    yield node.lineno, target, names
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("ratectl"):
                    yield node.lineno, a.name, []


SOURCES = sorted(PACKAGE.rglob("*.py"))


def test_the_layers_cover_every_subpackage():
    found = {p.name for p in PACKAGE.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    found |= {p.stem for p in PACKAGE.glob("*.py") if p.stem != "__init__"}
    assert found <= set(RANK), f"subpackages without a layer: {sorted(found - set(RANK))}"


def _problems(source: str, module: str, *, is_pkg: bool = False) -> list[str]:
    here = _layer_of(module)
    if here == TOP:
        return []
    problems = []
    for line, target, names in _imports(source, module, is_pkg=is_pkg):
        there = _layer_of(target)
        if there == TOP:
            problems.append(f"line {line}: imports the top-level package ({target})")
            continue
        if there != here and RANK[there] >= RANK[here]:
            problems.append(f"line {line}: {here} (layer {RANK[here]}) imports {target} "
                            f"(layer {RANK[there]}): imports must go down")
        if there != here:
            private = [n for n in names if n.startswith("_")] + \
                [p for p in target.split(".")[1:] if p.startswith("_")]
            if private:
                problems.append(f"line {line}: imports private name(s) {private} from {target}")
    return problems


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_imports_go_down_the_layers_and_keep_private_names_private(path):
    problems = _problems(path.read_text(encoding="utf-8"), _module_name(path),
                         is_pkg=path.name == "__init__.py")
    assert not problems, f"{path.relative_to(PACKAGE)}:\n" + "\n".join(problems)


@pytest.mark.parametrize(("source", "expected"), [
    ("from ..control import ResolvedRateController\n", "imports must go down"),
    ("def f():\n    from ..control.controller import default_solver\n", "imports must go down"),
    ("from .. import paths\n", "imports must go down"),  # control and paths share a rank
    ("from ..model.limits import _private\n", "private name"),
    ("import ratectl\n", "top-level package"),
    ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    pass\nfrom ..control import x\n",
     "imports must go down"),
])
def test_the_checker_catches_what_it_must(source, expected):
    module = "ratectl.solvers.base" if "paths" not in source else "ratectl.control.controller"
    assert any(expected in p for p in _problems(source, module)), _problems(source, module)


def test_the_checker_accepts_downward_and_internal_imports():
    source = ("from ..model.limits import Limits\nfrom .damped import DLS\n"
              "from .qp.bounds import _BoundCache\nfrom ..errors import InputError\n")
    assert _problems(source, "ratectl.solvers.base") == []
    type_only = "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..model import Chain\n"
    assert _problems(type_only, "ratectl.kinematics.forward") == []


def test_import_ratectl_needs_no_optional_extra():
    """mujoco, mink, matplotlib and franky are extras: importing the package (and a chain from
    URDF text) must not import them — an annotation's import belongs under TYPE_CHECKING."""
    import subprocess
    import sys

    code = ("import sys, ratectl as rc\n"
            "rc.Chain.from_urdf('<robot name=\"r\"><link name=\"a\"/><link name=\"b\"/>"
            "<joint name=\"j\" type=\"continuous\"><parent link=\"a\"/><child link=\"b\"/></joint>"
            "</robot>')\n"
            "rc.solvers, rc.control, rc.paths, rc.planning, rc.execution, rc.singularity\n"
            "print(sorted(m for m in ('mujoco', 'mink', 'matplotlib', 'franky') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]", out.stdout


MAX_FUNCTION_LINES = 100


def test_no_function_is_longer_than_a_reader_can_hold():
    """Every function and method has at most 100 lines of code (its docstring excluded)."""
    long = []
    for path in SOURCES:
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                length = node.end_lineno - node.lineno + 1
                first = node.body[0]
                if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) \
                        and isinstance(first.value.value, str):
                    length -= first.end_lineno - first.lineno + 1
                if length > MAX_FUNCTION_LINES:
                    long.append(f"{path.relative_to(PACKAGE)}:{node.lineno} {node.name}: {length} lines")
    assert not long, "\n".join(long)
