"""Build: the modules of the servo's control cycle are compiled to C extensions with mypyc.

The project's metadata is in ``pyproject.toml``; this file only adds the compiled modules
(listed in ``ratectl/compiled.py``). The same Python sources are compiled, not a second
implementation; every module stays importable as plain Python. Set
``RATECTL_PURE_PYTHON=1`` when installing to skip the compilation (a machine without a C
compiler).
"""

from __future__ import annotations

import json
import os
import runpy
import sys
import tempfile

from setuptools import setup
from setuptools.command.build_ext import build_ext
from setuptools.errors import CCompilerError, CompileError, ExecError, LinkError, PlatformError

here = os.path.dirname(os.path.abspath(__file__))
compiled = runpy.run_path(os.path.join(here, "ratectl", "compiled.py"))
modules = compiled["COMPILED_MODULES"]


class BuildExtRecordingSources(build_ext):
    """build_ext, then the record of what it compiled, by content (`ratectl.compiled.stale`
    tells an edited source from a touched one in a checkout; not part of the package)."""

    def run(self) -> None:
        try:
            super().run()
        except (CCompilerError, CompileError, ExecError, LinkError, PlatformError) as exc:
            raise SystemExit(
                f"ratectl: compiling the control cycle with mypyc failed ({exc}). It needs a C "
                "compiler and the Python headers (Debian: apt-get install gcc python3-dev). To "
                "install the same code as plain Python instead (slower per cycle), set "
                "RATECTL_PURE_PYTHON=1, e.g. RATECTL_PURE_PYTHON=1 pip install -e .") from exc
        if not (self.extensions and (self.inplace or getattr(self, "editable_mode", False))):
            return  # (only the compiled files beside the sources have their record there)
        with open(os.path.join(here, compiled["SOURCES_RECORD"]), "w", encoding="utf-8") as f:
            json.dump({m: compiled["source_digest"](os.path.join(here, m)) for m in modules}, f, indent=1)


# pip asks for the metadata first (dist_info / egg_info): the extensions are not needed for
# it, and generating their C code takes a quarter of the build
metadata_only = bool({"dist_info", "egg_info"} & set(sys.argv)) and not (
    {"build", "build_ext", "bdist_wheel", "editable_wheel", "install", "develop"} & set(sys.argv))
ext_modules: list = []
if os.environ.get("RATECTL_PURE_PYTHON", "").lower() not in ("1", "true", "yes") and not metadata_only:
    from mypyc.build import mypycify

    # numpy is left untyped for the compiler, whether or not the build environment has it:
    # the compiled code then takes any array-like where the source takes one, as the
    # interpreted code does (no run-time isinstance check on ``np.ndarray`` arguments)
    config = os.path.join(tempfile.mkdtemp(prefix="ratectl-mypyc-"), "mypy.ini")
    # (the modules not compiled are type-checked by the project's own mypy run, with numpy
    # typed; here only the compiled ones must check)
    names = [m[:-3].replace("/", ".") for m in modules]
    with open(config, "w", encoding="utf-8") as f:
        f.write("[mypy]\npython_version = 3.10\nignore_missing_imports = True\n"
                "[mypy-numpy.*]\nfollow_imports = skip\nfollow_imports_for_stubs = True\n"
                "[mypy-ratectl.*]\nignore_errors = True\n"
                + "".join(f"[mypy-{n}]\nignore_errors = False\n" for n in names))
    ext_modules = mypycify(["--config-file", config, *modules], opt_level="3",
                           group_name="ratectl._core")

setup(ext_modules=ext_modules, cmdclass={"build_ext": BuildExtRecordingSources})
