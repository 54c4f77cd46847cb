"""Obstacles placed in the base frame: `Sphere`, `Box`, `Mesh` (for `Obstacles`), and the
conversion of a shape to the geometry library's object (`coal_geometry`)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..checks import positive_number
from ..errors import InputError
from ..spatial import rigid_transform_defect

__all__ = ["Sphere", "Box", "Mesh", "coal_geometry", "import_coal"]


def import_coal() -> Any:
    """The ``coal`` module, or InputError saying how to install it (the ``collision`` extra)."""
    try:
        import coal
    except ImportError:
        raise InputError("collision avoidance needs the coal package: pip install 'ratectl[collision]'",
                         argument="collision", value=None) from None
    return coal


def _pose(T: ArrayLike | None, name: str) -> np.ndarray:
    if T is None:
        return np.eye(4)
    a = np.array(T, dtype=float)
    if a.shape == (3,):
        out = np.eye(4)
        out[:3, 3] = a
        return out
    defect = rigid_transform_defect(a) if a.shape == (4, 4) else "must be a 4x4 pose or a 3-vector"
    if defect is not None:
        raise InputError(f"{name} {defect}", argument=name, value=T)
    return a


class _Obstacle:
    """An obstacle: a shape and its pose in the base frame (settable: a moving obstacle)."""

    kind = ""
    size: tuple[float, ...] = ()
    filename: str | None = None
    scale: np.ndarray | None = None

    def __init__(self, pose: ArrayLike | None, name: str | None) -> None:
        self.pose = _pose(pose, "pose")
        self.name = name or type(self).__name__.lower()

    def set_pose(self, pose: ArrayLike) -> None:
        """Move the obstacle: a 4×4 pose, or a position (3,) [m], in the base frame."""
        self.pose = _pose(pose, "pose")

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r}, at {self.pose[:3, 3].round(4).tolist()})"


class Sphere(_Obstacle):
    """A sphere of ``radius`` [m] centred at ``center`` (3,) [m] in the base frame."""

    kind = "sphere"

    def __init__(self, center: ArrayLike, radius: float, *, name: str | None = None) -> None:
        super().__init__(center, name)
        self.size = (positive_number("radius", radius, unit="[m]"),)


class Box(_Obstacle):
    """A box of full side lengths ``size`` (x, y, z) [m] at ``pose`` (4×4 or a centre (3,))."""

    kind = "box"

    def __init__(self, pose: ArrayLike, size: ArrayLike, *, name: str | None = None) -> None:
        super().__init__(pose, name)
        s = np.asarray(size, dtype=float)
        if s.shape != (3,) or not np.all(s > 0) or not np.all(np.isfinite(s)):
            raise InputError(f"size must be three positive side lengths [m], got {size!r}", argument="size",
                             value=size)
        self.size = tuple(float(v) for v in s)


class Mesh(_Obstacle):
    """A mesh file (STL, OBJ, DAE, … as the geometry library reads them) at ``pose``; its
    convex hull is used."""

    kind = "mesh"

    def __init__(self, filename: str, pose: ArrayLike | None = None, *, scale: ArrayLike = (1.0, 1.0, 1.0),
                 name: str | None = None) -> None:
        super().__init__(pose, name)
        self.filename = str(filename)
        self.scale = np.broadcast_to(np.asarray(scale, dtype=float), (3,)).copy()


def coal_geometry(kind: str, size: tuple[float, ...], filename: str | None,
                  scale: Any) -> tuple[Any, np.ndarray, float]:
    """(coal collision geometry, centre (3,) and radius [m] of a sphere that bounds it, in its
    own frame). Meshes become their convex hull (signed distances, penetration included,
    by GJK/EPA)."""
    coal = import_coal()
    zero = np.zeros(3)
    if kind == "sphere":
        return coal.Sphere(size[0]), zero, size[0]
    if kind == "box":
        return coal.Box(*size), zero, 0.5 * float(np.linalg.norm(size))
    if kind == "cylinder":
        return coal.Cylinder(size[0], size[1]), zero, float(np.hypot(size[0], 0.5 * size[1]))
    if kind == "capsule":
        return coal.Capsule(size[0], size[1]), zero, size[0] + 0.5 * size[1]
    if kind == "mesh":
        try:
            m = coal.MeshLoader().load(str(filename), np.asarray(scale, dtype=float))
            m.buildConvexHull(True, "Qt")
        except Exception as exc:  # the loader's own errors: a file it cannot read
            raise InputError(f"cannot read mesh {filename!r}: {exc}", argument="filename",
                             value=filename) from None
        pts = np.asarray(m.vertices(), dtype=float).reshape(-1, 3)
        if not pts.size:
            raise InputError(f"mesh {filename!r} has no vertices", argument="filename", value=filename)
        c = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
        return m.convex, c, float(np.max(np.linalg.norm(pts - c, axis=1)))
    raise InputError(f"unknown shape kind {kind!r}", argument="kind", value=kind)
