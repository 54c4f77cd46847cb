"""The collision geometry of a URDF robot (`urdf_collision_geometry`): every link's
``<collision>`` elements (meshes and primitives) and how the links hang together, for
`ratectl.collision`. Mesh files are located, not read (the geometry library reads them).

``package://PKG/path`` URIs are resolved against ``package_dirs`` (each tried as
``dir/PKG/path`` and ``dir/path``) and against the ancestors of the URDF's directory named
``PKG``; ``file://`` URIs and relative paths against the URDF's directory.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..arrays import read_only
from ..errors import ImportModelError
from .urdf import _read_tree, _urdf_origin
from .xml import floats, parse_xml_safely, read_source

__all__ = ["CollisionElement", "UrdfGeometry", "urdf_collision_geometry"]


@dataclass(frozen=True, kw_only=True)
class CollisionElement:
    """One ``<collision>`` of a link.

    Attributes:
        link: the link's name.
        origin: (4, 4) placement in the link frame.
        kind: ``"mesh"``, ``"box"``, ``"sphere"``, ``"cylinder"`` or ``"capsule"``.
        size: box full sides (x, y, z) [m]; sphere (radius,); cylinder/capsule (radius, length).
        filename: the mesh file's path (mesh only).
        scale: the mesh's scale (3,).
    """

    link: str
    origin: np.ndarray
    kind: str
    size: tuple[float, ...] = ()
    filename: str | None = None
    scale: np.ndarray | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "origin", read_only(self.origin))
        if self.scale is not None:
            object.__setattr__(self, "scale", read_only(self.scale))


@dataclass(frozen=True, kw_only=True)
class UrdfGeometry:
    """What `urdf_collision_geometry` returns.

    Attributes:
        elements: every collision element, link by link in file order.
        parents: child link -> (parent link, joint name, joint type, (4, 4) joint origin).
    """

    elements: tuple[CollisionElement, ...]
    parents: dict[str, tuple[str, str, str, np.ndarray]]


def urdf_collision_geometry(source: Any, *, package_dirs: Any = None) -> UrdfGeometry:
    """The collision elements and link tree of a URDF file (see the module docstring).

    Raises:
        ImportModelError: malformed XML or geometry, or a mesh file that cannot be found
            (the message lists where it was looked for).
    """
    data, label, directory = read_source(source, "URDF")
    root = parse_xml_safely(data, label=label)
    tree = _read_tree(root, label)
    dirs = [Path(d) for d in (package_dirs or ())]
    elements: list[CollisionElement] = []
    for el in root.findall("link"):
        lname = str(el.get("name"))
        for k, col in enumerate(el.findall("collision")):
            what = f"link {lname!r} <collision> {k}"
            origin = _urdf_origin(col.find("origin"), what)
            geo = col.find("geometry")
            shape = None if geo is None or len(geo) == 0 else geo[0]
            if shape is None:
                raise ImportModelError(f"{label}: {what} has no <geometry>", element=what)
            elements.append(_element(shape, lname, origin, what, label, directory, dirs))
    parents = {}
    for child, jname in tree.parent_joint.items():
        j = tree.joints[jname]
        parents[child] = (str(j.find("parent").get("link")), jname,  # type: ignore[union-attr]
                          str(j.get("type")), _urdf_origin(j.find("origin"), f"joint {jname!r}"))
    return UrdfGeometry(elements=tuple(elements), parents=parents)


def _element(shape, link, origin, what, label, directory, dirs) -> CollisionElement:
    tag = shape.tag
    if tag == "mesh":
        fn = shape.get("filename")
        if not fn:
            raise ImportModelError(f"{label}: {what} <mesh> has no filename", element=what)
        scale = floats(shape.get("scale"), 3, default=[1.0, 1.0, 1.0], what=f"{what} <mesh scale>")
        return CollisionElement(link=link, origin=origin, kind="mesh",
                                filename=str(_resolve(fn, directory, dirs, label, what)), scale=scale)
    if tag == "box":
        size = floats(shape.get("size"), 3, default=None, what=f"{what} <box size>")
        return CollisionElement(link=link, origin=origin, kind="box", size=tuple(map(float, size)))
    if tag == "sphere":
        r = floats(shape.get("radius"), 1, default=None, what=f"{what} <sphere radius>")
        return CollisionElement(link=link, origin=origin, kind="sphere", size=(float(r[0]),))
    if tag in ("cylinder", "capsule"):
        r = floats(shape.get("radius"), 1, default=None, what=f"{what} <{tag} radius>")
        h = floats(shape.get("length"), 1, default=None, what=f"{what} <{tag} length>")
        return CollisionElement(link=link, origin=origin, kind=tag, size=(float(r[0]), float(h[0])))
    raise ImportModelError(f"{label}: {what} has geometry <{tag}>; allowed: mesh, box, sphere, cylinder, "
                           "capsule", element=what)


def _resolve(fn: str, directory: Path | None, dirs: list[Path], label: str, what: str) -> Path:
    tried: list[Path] = []
    base = directory if directory is not None else Path.cwd()
    if fn.startswith("package://"):
        pkg, _, rest = fn[len("package://"):].partition("/")
        for d in dirs:
            tried += [d / pkg / rest, d / rest]
        for anc in [base, *base.parents]:
            if anc.name == pkg:
                tried.append(anc / rest)
    elif fn.startswith("file://"):
        p = Path(fn[len("file://"):])
        tried.append(p if p.is_absolute() else base / p)
    else:
        p = Path(fn)
        tried.append(p if p.is_absolute() else base / p)
    for p in tried:
        if p.is_file():
            return p
    raise ImportModelError(f"{label}: {what}: mesh {fn!r} not found; looked in "
                           f"{[str(p) for p in tried] or 'no place'} (pass package_dirs=)", element=what)
