"""Reading model files safely: sources, size caps and an XML parser without entities.

Both model formats (URDF, MJCF) come through here. `read_source` accepts a path,
XML text (``str`` starting with ``<``, optionally after a byte-order mark) or bytes and
refuses sources over the size cap; `parse_xml_safely` decodes the bytes the way an
XML parser would (byte-order mark, else the XML declaration's ``encoding``, else UTF-8),
refuses any document type or entity declaration in the **decoded** text (so no encoding
can hide one), feeds the parser exactly that text, and refuses documents nested deeper
than `MAX_DEPTH` elements. No entity is expanded and no external reference is
followed. See ``docs/security.md`` for the threat model.
"""

from __future__ import annotations

import codecs
import math
import os
import re
import stat
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ImportModelError

__all__ = ["read_source", "read_file_capped", "parse_xml_safely", "decode_xml", "floats",
           "float_attr", "MAX_BYTES", "MAX_DEPTH"]

_FORBIDDEN = re.compile(r"<!\s*(DOCTYPE|ENTITY)", re.IGNORECASE)
_DECL = re.compile(r"^<\?xml[^>]*?\?>")
_DECL_ENC = re.compile(rb"^<\?xml[^>]*?encoding\s*=\s*[\"']([A-Za-z0-9._-]{1,40})[\"']")
#: Largest model source [bytes] (for MJCF: the model and all its includes together).
MAX_BYTES = 50_000_000
#: Deepest element nesting accepted (a serial arm of n bodies nests about n + 3 deep).
MAX_DEPTH = 400

# byte-order marks, longest first (the UTF-32 LE mark starts with the UTF-16 LE one)
_BOMS = ((codecs.BOM_UTF32_LE, "utf-32-le"), (codecs.BOM_UTF32_BE, "utf-32-be"),
         (codecs.BOM_UTF8, "utf-8"), (codecs.BOM_UTF16_LE, "utf-16-le"),
         (codecs.BOM_UTF16_BE, "utf-16-be"))
# without a mark: the encoding of "<" (or "<?") as the first character
_SNIFF = ((b"<\0\0\0", "utf-32-le"), (b"\0\0\0<", "utf-32-be"), (b"<\0", "utf-16-le"),
          (b"\0<", "utf-16-be"))


def read_source(source: Any, kind: str) -> tuple[bytes | str, str, Path | None]:
    """(bytes or text, a label for messages, directory of the file or None) of a path, XML
    text or bytes; sources over `MAX_BYTES` are refused."""
    if isinstance(source, bytes | bytearray | memoryview):
        data = bytes(source)
        if len(data) > MAX_BYTES:
            raise ImportModelError(f"<{kind} bytes> are {len(data)} bytes; refusing sources over "
                                   f"{MAX_BYTES} bytes", element="file")
        return data, f"<{kind} bytes>", None
    if isinstance(source, str) and source.lstrip("\ufeff \t\r\n").startswith("<"):
        if len(source) > MAX_BYTES:
            raise ImportModelError(f"<{kind} string> has {len(source)} characters; refusing sources "
                                   f"over {MAX_BYTES}", element="file")
        return source, f"<{kind} string>", None
    if not isinstance(source, str | os.PathLike):
        raise ImportModelError(
            f"expected a path to a {kind} file or its XML text, got {type(source).__name__}",
            element="file")
    if not os.fspath(source).strip():
        raise ImportModelError(f"the {kind} file name is empty: give a path to a {kind} file or its "
                               "XML text", element="file")
    try:
        path = Path(source)
        exists = path.is_file()
    except (OSError, ValueError) as exc:  # NUL bytes, names too long, ...
        raise ImportModelError(f"{kind} file name {str(source)[:200]!r} is not usable: {exc}",
                               element="file") from None
    if not exists:
        hint = ""
        if isinstance(source, str) and "<" in source[:200]:
            hint = " (XML text must start with '<')"
        elif path.is_dir():
            hint = " (that is a directory; give the file inside it)"
        raise ImportModelError(f"{kind} file not found: {str(path)[:200]!r}{hint}",
                               element=f"file {str(path)[:200]!r}")
    return read_file_capped(path, kind, MAX_BYTES), str(path), path.parent


def read_file_capped(path: Path, kind: str, cap: int) -> bytes:
    """The bytes of the regular file ``path``, refusing more than ``cap`` bytes (counted
    while reading, so files whose size the system misreports — /proc, pipes — are caught)
    and anything that is not a regular file (devices, FIFOs)."""
    try:
        with open(path, "rb") as fh:
            st = os.fstat(fh.fileno())
            if not stat.S_ISREG(st.st_mode):
                raise ImportModelError(f"{kind} {str(path)!r} is not a regular file",
                                       element=f"file {str(path)!r}")
            if st.st_size > cap:
                raise ImportModelError(f"{kind} file {str(path)!r} is {st.st_size} bytes; refusing "
                                       f"more than {cap} bytes", element=f"file {str(path)!r}")
            data = fh.read(cap + 1)
    except OSError as exc:
        raise ImportModelError(f"{kind} file {str(path)!r} cannot be read: {exc.strerror or exc}",
                               element=f"file {str(path)!r}") from None
    if len(data) > cap:
        raise ImportModelError(f"{kind} file {str(path)!r} has more than {cap} bytes; refused",
                               element=f"file {str(path)!r}")
    return data


def decode_xml(data: bytes, *, label: str = "<xml>") -> str:
    """The text of an XML document as a parser would decode it: a byte-order mark wins,
    then the encoding of the first character ``<`` (UTF-16/32 without a mark), then the
    XML declaration's ``encoding``, else UTF-8. Undecodable bytes are an error."""
    enc = None
    for bom, name in _BOMS:
        if data.startswith(bom):
            enc, data = name, data[len(bom):]
            break
    if enc is None:
        for head, name in _SNIFF:
            if data.startswith(head):
                enc = name
                break
    if enc is None:
        m = _DECL_ENC.match(data.lstrip())
        enc = m.group(1).decode("ascii") if m else "utf-8"
        try:
            info = codecs.lookup(enc)
        except LookupError:
            raise ImportModelError(f"{label}: unknown encoding {enc!r} in the XML declaration",
                                   element="<?xml?>") from None
        enc = info.name
    try:
        return data.decode(enc)
    except (UnicodeDecodeError, LookupError) as exc:
        raise ImportModelError(f"{label}: the document is not valid {enc} text: {exc}",
                               element="<?xml?>") from None


def parse_xml_safely(data: bytes | str, *, label: str = "<xml>",
                     max_depth: int = MAX_DEPTH) -> ET.Element:
    """Parse XML without entity expansion or external references.

    The bytes are decoded first (`decode_xml`); any ``<!DOCTYPE`` or ``<!ENTITY``
    declaration in the decoded text is refused (that is where entity bombs and external
    entities live); without one, the parser only knows the five predefined entities and
    character references, so nothing expands. The parser is fed the checked text itself
    (as UTF-8, without the XML declaration), so what was checked is what is parsed.
    Documents nested deeper than ``max_depth`` elements are refused.

    Raises:
        ImportModelError: for a declaration (``element="<!DOCTYPE>"``/``"<!ENTITY>"``),
            undecodable bytes, too deep nesting or malformed XML (``element`` gives the
            line and column).
    """
    text = data.lstrip("\ufeff") if isinstance(data, str) else decode_xml(data, label=label)
    m = _FORBIDDEN.search(text)
    if m:
        decl = m.group(1).upper()
        line = text.count("\n", 0, m.start()) + 1
        raise ImportModelError(
            f"{label}: line {line}: <!{decl}> declarations are not allowed (ratectl does not "
            "expand entities or follow external references); remove the declaration",
            element=f"<!{decl}>")
    body = text.lstrip()
    lead = text[:len(text) - len(body)]
    dm = _DECL.match(body)
    if dm:  # the declaration may name the original encoding; keep its lines for positions
        body = "\n" * dm.group(0).count("\n") + body[dm.end():]
    body = "\n" * lead.count("\n") + body
    parser = ET.XMLParser()
    try:
        parser.feed(body.encode("utf-8", "surrogatepass"))
        root = parser.close()
    except ET.ParseError as exc:
        line, col = exc.position
        raise ImportModelError(f"{label}: malformed XML at line {line}, column {col}: {exc}",
                               element=f"XML line {line} column {col}") from None
    except UnicodeEncodeError as exc:
        raise ImportModelError(f"{label}: the document contains characters XML does not allow: "
                               f"{exc}", element="XML") from None
    _check_depth(root, label, max_depth)
    return root


def _check_depth(root: ET.Element, label: str, max_depth: int) -> None:
    """Refuse trees nested deeper than ``max_depth`` (iteratively: no recursion)."""
    stack = [(root, 1)]
    while stack:
        el, d = stack.pop()
        if d > max_depth:
            raise ImportModelError(f"{label}: elements are nested more than {max_depth} levels deep "
                                   f"(at <{el.tag}>); refused", element=f"<{el.tag}>")
        stack.extend((c, d + 1) for c in el)


def floats(text: str | None, count: int, *, default: Any, what: str) -> np.ndarray:
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
