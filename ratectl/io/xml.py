"""Reading model files safely: sources, size caps and an XML parser without entities.

Both model formats (URDF, MJCF) come through here. `read_source` accepts a path,
XML text (``str`` starting with ``<``) or bytes and refuses files over the size cap;
`parse_xml_safely` refuses any document type or entity declaration, so no
entity is expanded and no external reference is followed.
"""

from __future__ import annotations

import math
import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..errors import ImportModelError

__all__ = ["read_source", "parse_xml_safely", "floats", "float_attr", "MAX_BYTES"]

_FORBIDDEN = re.compile(rb"<!\s*(DOCTYPE|ENTITY)", re.IGNORECASE)
MAX_BYTES = 50_000_000


def read_source(source, kind: str) -> tuple[bytes, str, Path | None]:
    """(bytes, a label for messages, directory of the file or None) of a path or XML text."""
    if isinstance(source, bytes):
        return source, f"<{kind} bytes>", None
    if isinstance(source, str) and source.lstrip().startswith("<"):
        return source.encode("utf-8"), f"<{kind} string>", None
    if not isinstance(source, str | os.PathLike):
        raise ImportModelError(
            f"expected a path to a {kind} file or its XML text, got {type(source).__name__}",
            element="file")
    path = Path(source)
    if not path.is_file():
        raise ImportModelError(f"{kind} file not found: {str(path)!r}", element=f"file {str(path)!r}")
    size = path.stat().st_size
    if size > MAX_BYTES:
        raise ImportModelError(f"{kind} file {str(path)!r} is {size} bytes; refusing files over "
                               f"{MAX_BYTES} bytes", element=f"file {str(path)!r}")
    return path.read_bytes(), str(path), path.parent


def parse_xml_safely(data: bytes, *, label: str = "<xml>") -> ET.Element:
    """Parse XML without entity expansion or external references.

    Any ``<!DOCTYPE`` or ``<!ENTITY`` declaration is refused (that is where entity
    bombs and external entities live); without one, ElementTree only knows the five
    predefined entities and character references, so nothing expands.

    Raises:
        ImportModelError: for a declaration (``element="<!DOCTYPE>"``/``"<!ENTITY>"``) or
            malformed XML (``element`` gives the line and column).
    """
    m = _FORBIDDEN.search(data)
    if m:
        decl = m.group(1).decode().upper()
        line = data.count(b"\n", 0, m.start()) + 1
        raise ImportModelError(
            f"{label}: line {line}: <!{decl}> declarations are not allowed (ratectl does not "
            "expand entities or follow external references); remove the declaration",
            element=f"<!{decl}>")
    parser = ET.XMLParser()
    try:
        parser.feed(data)
        return parser.close()
    except ET.ParseError as exc:
        line, col = exc.position
        raise ImportModelError(f"{label}: malformed XML at line {line}, column {col}: {exc}",
                               element=f"XML line {line} column {col}") from None


def floats(text: str | None, count: int, *, default, what: str) -> np.ndarray:
    if text is None:
        return np.array(default, dtype=float)
    parts = text.split()
    try:
        vals = np.array([float(p) for p in parts], dtype=float)
    except ValueError:
        raise ImportModelError(f"{what}: expected {count} numbers, got {text!r}", element=what) from None
    if vals.shape != (count,) or not np.all(np.isfinite(vals)):
        raise ImportModelError(f"{what}: expected {count} finite numbers, got {text!r}", element=what)
    return vals


def float_attr(el: ET.Element, name: str, *, what: str) -> float | None:
    text = el.get(name)
    if text is None:
        return None
    try:
        v = float(text)
    except ValueError:
        raise ImportModelError(f"{what}: attribute {name}={text!r} is not a number",
                               element=what) from None
    if math.isnan(v):
        raise ImportModelError(f"{what}: attribute {name} is NaN", element=what)
    return v
