"""Which of ratectl's modules run compiled, and whether a compiled module is stale.

An installation compiles the modules of the servo's control cycle, listed in
``COMPILED_MODULES``, to C extensions with mypyc (see ``setup.py``); every one of them is
also plain Python, which runs where the compilation was skipped (``RATECTL_PURE_PYTHON=1``
at install time). Both give the same commands; the compiled cycle is faster.

``modules()`` says, for each listed module, whether the imported one is compiled. In a
source checkout (an editable install), a compiled module built from other bytes than its
``.py`` file now holds runs the old code: ``import ratectl`` warns then (`stale`), and
``pip install -e .`` rebuilds.

This file is read by ``setup.py`` without importing ratectl: it imports nothing but the
standard library at module level (and `hashlib`, `json` only where a source is newer than
its compiled file: ``import ratectl`` runs `stale` every time).
"""

import importlib as _importlib
import os as _os

__all__ = ["COMPILED_MODULES", "SOURCES_RECORD", "modules", "source_digest", "stale"]

#: The modules compiled with mypyc, as paths from the project's root: the stage objects of
#: the control cycle and what they call every period. What a user subclasses, passes
#: duck-typed objects to or calls with arbitrary arguments (the controller, the solvers, the
#: chain, the command) stays interpreted: compiled code checks the declared types of its
#: arguments, and these take more than their annotations say.
COMPILED_MODULES: tuple[str, ...] = (
    "ratectl/spatial.py",
    "ratectl/model/limits.py",
    "ratectl/control/approach.py",
    "ratectl/control/cycle.py",
    "ratectl/control/gate.py",
    "ratectl/control/halt.py",
    "ratectl/control/jog.py",
    "ratectl/control/limiter.py",
    "ratectl/control/progress.py",
    "ratectl/control/progress_stage.py",
    "ratectl/control/servo.py",
    "ratectl/control/smooth_stage.py",
    "ratectl/control/smoothing.py",
    "ratectl/control/solve_stage.py",
    "ratectl/solvers/qp/active_set.py",
    "ratectl/solvers/qp/bounds.py",
)


def _name(path: str) -> str:
    return path[:-3].replace("/", ".")


def modules() -> dict[str, bool]:
    """``{module name: compiled?}`` for every module of `COMPILED_MODULES`, as imported."""
    out = {}
    for path in COMPILED_MODULES:
        m = _importlib.import_module(_name(path))
        out[_name(path)] = not (m.__file__ or "").endswith(".py")
    return out


#: Written by the build beside the sources it compiled (a source checkout): ``{path: the
#: SHA-256 of the source compiled}``, so that a file only touched (a branch switched back
#: and forth) is not taken for an edit.
SOURCES_RECORD = "ratectl/_compiled_sources.json"


def source_digest(path: str) -> str:
    """The SHA-256 of a file's bytes (hex), as `SOURCES_RECORD` holds it."""
    import hashlib

    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def stale(root: str | None = None) -> list[str]:
    """The compiled modules of a source checkout whose ``.py`` file was changed after they
    were built (they run the old code); empty for an installed wheel. A source newer than
    its compiled file is compared with the digest the build recorded (`SOURCES_RECORD`):
    the same bytes are not stale. ``root`` is the directory that holds the ``ratectl``
    package (default: this one's parent)."""
    root = root or _os.path.dirname(_os.path.dirname(_os.path.abspath(__file__)))
    if not _os.path.isdir(_os.path.join(root, ".git")):
        return []
    recorded: dict[str, str] | None = None
    listed: dict[str, list[str]] = {}  # each folder's compiled files, listed once
    out = []
    for path in COMPILED_MODULES:
        src = _os.path.join(root, path)
        folder, base = _os.path.split(src)
        stem = base[:-3] + "."
        try:
            if folder not in listed:
                listed[folder] = [f for f in _os.listdir(folder) if f.endswith((".so", ".pyd"))]
            built = [f for f in listed[folder] if f.startswith(stem)]
            if not built or _os.path.getmtime(src) <= max(_os.path.getmtime(_os.path.join(folder, f))
                                                          for f in built):
                continue
            if recorded is None:
                import json

                try:
                    with open(_os.path.join(root, SOURCES_RECORD), encoding="utf-8") as f:
                        recorded = dict(json.load(f))
                except (OSError, ValueError, TypeError):
                    recorded = {}
            if recorded.get(path) != source_digest(src):
                out.append(_name(path))
        except OSError:
            continue
    return out
