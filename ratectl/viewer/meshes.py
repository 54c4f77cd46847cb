"""Meshes for the viewer, built or read with trimesh (which comes with viser).

* `capsule_mesh`: a polyline of capsules (cylinders with spheres at the joints);
* `joint_mesh`: a short thick cylinder along a revolute axis, a box along a prismatic one;
* `visual_glb`: the binary glTF of one piece of link geometry from a model file
  (`ratectl.io.description.VisualDescription`): its mesh file where trimesh can read it
  (STL, OBJ, PLY, glTF/GLB, and COLLADA ``.dae`` when pycollada is installed), boxes,
  cylinders and spheres; None where it cannot be read.
"""

from __future__ import annotations

import io
import logging
import os
import threading
from typing import TYPE_CHECKING, Any

import numpy as np
import trimesh

if TYPE_CHECKING:
    from ..io.description import VisualDescription

__all__ = ["capsule_mesh", "joint_mesh", "visual_glb", "MESH_SUFFIXES", "MAX_MESH_BYTES"]

#: Mesh file types the viewer tries to read.
MESH_SUFFIXES = (".stl", ".obj", ".ply", ".glb", ".gltf", ".dae", ".off")
#: Largest mesh file read [bytes].
MAX_MESH_BYTES = 100_000_000

_cache: dict[tuple, bytes | None] = {}
_cache_lock = threading.Lock()


def capsule_mesh(points: np.ndarray, radius: float) -> trimesh.Trimesh:
    """Capsules of ``radius`` [m] along the polyline ``points`` (m, 3) [m] (a sphere for a
    single point)."""
    parts: list[Any] = [trimesh.creation.icosphere(subdivisions=2, radius=radius).apply_translation(p)
                        for p in points]
    for a, b in zip(points[:-1], points[1:], strict=True):
        parts.append(trimesh.creation.cylinder(radius=radius, segment=np.array([a, b]), sections=24))
    mesh: Any = trimesh.util.concatenate(parts)
    return mesh


def joint_mesh(centre: np.ndarray, axis: np.ndarray, kind: str, radius: float) -> trimesh.Trimesh:
    """A joint drawn at ``centre`` along ``axis``: a cylinder of radius 1.35·``radius`` and
    length 3·``radius`` (revolute) or a box of side 2.2·``radius`` (prismatic)."""
    if kind == "prismatic":
        return trimesh.creation.box(extents=[2.2 * radius] * 3).apply_translation(centre)
    h = 1.5 * radius
    return trimesh.creation.cylinder(radius=1.35 * radius, segment=np.array([centre - h * axis,
                                                                           centre + h * axis]),
                                     sections=32)


def _primitive(v: VisualDescription) -> trimesh.Trimesh | None:
    if v.shape == "box" and len(v.size) == 3 and min(v.size) > 0:
        return trimesh.creation.box(extents=list(v.size))
    if v.shape == "cylinder" and len(v.size) == 2 and min(v.size) > 0:
        return trimesh.creation.cylinder(radius=v.size[0], height=v.size[1], sections=32)
    if v.shape == "sphere" and len(v.size) == 1 and v.size[0] > 0:
        return trimesh.creation.icosphere(subdivisions=2, radius=v.size[0])
    return None


def visual_glb(v: VisualDescription, *, default_rgba: tuple[float, float, float, float]
               ) -> bytes | None:
    """Binary glTF of one piece of link geometry in its own frame (the ``origin`` is not
    applied), or None when it cannot be read. Mesh files are read once and cached; a mesh
    keeps its own materials, a primitive gets ``rgba`` or ``default_rgba``."""
    key = (v.shape, v.path, v.size, v.rgba, default_rgba)
    with _cache_lock:
        if key in _cache:
            return _cache[key]
    data = _build(v, default_rgba)
    with _cache_lock:
        _cache[key] = data
    return data


def _build(v: VisualDescription, default_rgba) -> bytes | None:
    rgba = np.array(v.rgba if v.rgba is not None else default_rgba) * 255
    obj: Any
    if v.shape == "mesh":
        if v.path is None or not v.path.lower().endswith(MESH_SUFFIXES):
            return None
        try:
            if os.path.getsize(v.path) > MAX_MESH_BYTES:
                return None
            logging.getLogger("trimesh").disabled = True  # unreadable files are expected here
            try:
                obj = trimesh.load(v.path)
            finally:
                logging.getLogger("trimesh").disabled = False
        except Exception:  # any failure of a third-party reader means "not readable"
            return None
        if isinstance(obj, trimesh.Scene):
            if not obj.geometry:
                return None
        elif not isinstance(obj, trimesh.Trimesh) or not len(obj.faces):
            return None
        if np.any(np.asarray(v.size) != 1.0):
            obj.apply_transform(np.diag([*v.size, 1.0]))
        if isinstance(obj, trimesh.Trimesh) and v.rgba is not None:
            obj.visual = trimesh.visual.ColorVisuals(obj, face_colors=rgba.astype(np.uint8))
    else:
        obj = _primitive(v)
        if obj is None:
            return None
        obj.visual = trimesh.visual.ColorVisuals(obj, face_colors=rgba.astype(np.uint8))
    try:
        with io.BytesIO() as buf:
            obj.export(buf, file_type="glb")
            return buf.getvalue()
    except Exception:  # an exporter failure: draw the link without this piece
        return None
