"""The collision geometry of a URDF robot (`urdf_collision_geometry`): every link's
``<collision>`` elements (meshes and primitives) and how the links hang together, for
`ratectl.collision`. Mesh files are located, not read (the geometry library reads them).

Meshes are located as the viewer locates them (`ratectl.io.urdf.find_mesh`):
``package://PKG/path`` URIs against ``package_dirs`` (each tried as ``dir/PKG/path`` and
``dir/path``), then the URDF's directory and its ancestors (one named ``PKG``, or a ``PKG``
folder inside one) and ``ROS_PACKAGE_PATH``; ``file://`` URIs and relative paths against the
URDF's directory (the working directory for a URDF given as text).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..arrays import read_only
from ..errors import ImportModelError
from .urdf import _read_geometry, _read_tree, _urdf_origin, find_mesh, mesh_candidates
from .xml import parse_xml_safely, read_source

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

    Each element is read by the URDF reader's one reader of link geometry (the viewer's
    `VisualDescription` comes from the same one); meshes are located by `find_mesh`.

    Raises:
        ImportModelError: malformed XML or geometry, or a mesh file that cannot be found
            (the message lists where it was looked for).
    """
    data, label, directory = read_source(source, "URDF")
    root = parse_xml_safely(data, label=label)
    tree = _read_tree(root, label)
    dirs = [Path(d) for d in (package_dirs or ())]
    base = directory if directory is not None else Path.cwd()
    elements: list[CollisionElement] = []
    for el in root.findall("link"):
        lname = str(el.get("name"))
        for k, col in enumerate(el.findall("collision")):
            what = f"link {lname!r} <collision> {k}"
            g = _read_geometry(col, what, label)
            if g.shape != "mesh":
                elements.append(CollisionElement(link=lname, origin=g.origin, kind=g.shape, size=g.size))
                continue
            if not g.filename:
                raise ImportModelError(f"{label}: {what} <mesh> has no filename", element=what)
            found = find_mesh(g.filename, base, package_dirs=dirs)
            if found is None:
                tried = mesh_candidates(g.filename, base, package_dirs=dirs)
                raise ImportModelError(f"{label}: {what}: mesh {g.filename!r} not found; looked in "
                                       f"{[str(p) for p in tried] or 'no place'} (pass package_dirs=)",
                                       element=what)
            elements.append(CollisionElement(link=lname, origin=g.origin, kind="mesh",
                                             filename=str(found), scale=g.scale))
    parents = {}
    for child, jname in tree.parent_joint.items():
        j = tree.joints[jname]
        parents[child] = (str(j.find("parent").get("link")), jname,  # type: ignore[union-attr]
                          str(j.get("type")), _urdf_origin(j.find("origin"), f"joint {jname!r}"))
    return UrdfGeometry(elements=tuple(elements), parents=parents)
