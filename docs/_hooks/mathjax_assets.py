"""MkDocs hook: serve MathJax from the installed ``django-static-mathjax`` package.

The site typesets its formulas with MathJax 3 (TeX input, CommonHTML output). So that a
built site renders offline, the script and its web fonts are copied into the site from
the Python package that the ``docs`` extra installs (MathJax's own files, Apache-2.0),
instead of being loaded from a network or committed to this repository.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File, Files

#: Where the files go inside the site; ``mkdocs.yml`` loads ``assets/mathjax/tex-chtml.js``.
TARGET = "assets/mathjax"


def _mathjax_root() -> Path:
    spec = importlib.util.find_spec("mathjax")
    if spec is None or not spec.submodule_search_locations:
        raise PluginError("the docs need MathJax: pip install -e '.[docs]' "
                          "(it installs django-static-mathjax)")
    root = Path(next(iter(spec.submodule_search_locations))) / "static" / "mathjax" / "es5"
    if not (root / "tex-chtml.js").is_file():
        raise PluginError(f"MathJax's tex-chtml.js not found under {root}; reinstall django-static-mathjax")
    return root


def on_files(files: Files, config) -> Files:
    root = _mathjax_root()
    fonts = root / "output" / "chtml" / "fonts" / "woff-v2"
    wanted = [root / "tex-chtml.js", *sorted(fonts.glob("*.woff"))]
    for src in wanted:
        rel = src.relative_to(root).as_posix()
        files.append(File.generated(config, f"{TARGET}/{rel}", abs_src_path=str(src)))
    return files
