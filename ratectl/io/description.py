"""What a model file says about a serial chain, before it becomes a `Chain`.

The URDF and MJCF readers produce a `ModelDescription`: the moving joints on
the path from the base to the tip, each in the general form ``pre · M(q) · post``
(see `ratectl.model.joints.Joint`), and the constant tool transform after the
last one. `ratectl.Chain.from_urdf` and `ratectl.Chain.from_mjcf` turn it
into a chain. Keeping the readers free of the chain class keeps the layers one-way:
``model`` uses ``io``, never the reverse.

A joint with origin transform ``O`` (relative to its parent link/body frame) and unit
axis ``a`` gets ``pre = A · O · R_a`` and ``post = R_aᵀ``, where ``R_a`` takes the z axis
onto ``a`` and ``A`` collects the constant transforms (fixed joints, joint-less
bodies) met since the previous moving joint. ``R_a Rz(q) R_aᵀ`` is the rotation by q
about ``a``, so the chain frame after each joint is exactly the child link or body frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..arrays import read_only
from ..errors import ImportModelError
from ..spatial import transform

__all__ = ["JointDescription", "ModelDescription", "VisualDescription", "SHAPES", "axis_rotation",
           "unit_axis", "movable_joint", "MAX_LENGTH"]


@dataclass(frozen=True, kw_only=True)
class JointDescription:
    """One moving joint read from a file: kind, constant transforms, name and limits.

    ``element`` names the file element for error messages (``"joint 'shoulder'"``).
    Limits are ``None`` where the file gives none.
    """

    kind: str
    pre: np.ndarray
    post: np.ndarray
    name: str
    element: str
    qlim: tuple[float, float] | None = None
    vmax: float | None = None

    def __post_init__(self) -> None:
        for name in ("pre", "post"):
            object.__setattr__(self, name, read_only(getattr(self, name)))


#: Shapes of link geometry (`VisualDescription.shape`).
SHAPES = ("mesh", "box", "cylinder", "sphere")


@dataclass(frozen=True, kw_only=True)
class VisualDescription:
    """One piece of a link's geometry as a model file gives it, placed on the chain.

    Attributes:
        link: the link it belongs to.
        role: ``"visual"`` or ``"collision"`` (the element it came from).
        frame: the chain frame it moves with: 0 for the base, k for the frame after
            joint k (``Chain.frames(q)[..., k, :, :]``).
        origin: its pose in that frame (4×4; fixed joints and the element's ``<origin>``
            folded in).
        shape: one of `SHAPES`.
        size: ``mesh``: the scale (sx, sy, sz); ``box``: edge lengths (x, y, z) [m];
            ``cylinder``: (radius, length) [m] along its z axis; ``sphere``: (radius,) [m].
        filename: the mesh file name as written in the model (``package://...``,
            relative or absolute); None for other shapes.
        path: the mesh file found on disk for ``filename``, or None when it was not
            found. Readers only look the file up; they never open it.
        rgba: the material colour (red, green, blue, alpha in 0…1), or None.
    """

    link: str
    role: str
    frame: int
    origin: np.ndarray
    shape: str
    size: tuple[float, ...]
    filename: str | None = None
    path: str | None = None
    rgba: tuple[float, float, float, float] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "origin", read_only(self.origin))
        object.__setattr__(self, "size", tuple(float(x) for x in self.size))


@dataclass(frozen=True, kw_only=True)
class ModelDescription:
    """The serial chain a model file describes: its joints, tool transform, name and
    the geometry of its links (``visuals``, empty when the reader keeps none).

    ``label`` names the source in messages (a file path, ``"<URDF string>"``, ...).
    ``links`` lists the named frames rigidly attached to the chain, each as
    ``(name, k, T)``: the frame is ``T`` (4×4, constant) after the chain frame of joint ``k``
    (the frame after the k-th moving joint; ``k = 0`` is the base).
    """

    joints: tuple[JointDescription, ...]
    tool: np.ndarray
    name: str
    label: str
    links: tuple[tuple[str, int, np.ndarray], ...] = ()
    visuals: tuple[VisualDescription, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "tool", read_only(self.tool))
        object.__setattr__(self, "joints", tuple(self.joints))
        object.__setattr__(self, "links", tuple((str(nm), int(k), read_only(T))
                                                for nm, k, T in self.links))
        object.__setattr__(self, "visuals", tuple(self.visuals))


def axis_rotation(axis: ArrayLike) -> np.ndarray:
    """A rotation ``R_a`` (3×3) with ``R_a · ẑ = a`` for a unit vector ``a``.

    Exact for ±z (identity, Rx(π)); otherwise the rotation about ``ẑ × a`` by the
    angle between them (Rodrigues' formula, written without trigonometric calls:
    ``R = c I + [k]× + (1 − c)/s² k kᵀ`` with ``k = ẑ × a``, ``c = a_z``, ``s = ‖k‖``).
    """
    a = np.asarray(axis, dtype=float)
    c = float(a[2])
    k = np.array([-a[1], a[0], 0.0])
    s2 = float(k @ k)
    if s2 < 1e-30:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return c * np.eye(3) + K + ((1.0 - c) / s2) * np.outer(k, k)


#: Largest constant offset [m] a model file may give (far beyond any robot; sums over
#: thousands of links stay finite).
MAX_LENGTH = 1e9


def unit_axis(v: ArrayLike, what: str, *, label: str | None = None, noun: str = "joint axis",
              ) -> np.ndarray:
    """``v / ‖v‖``, scaled by max |v_i| first so that the norm cannot overflow or underflow
    (an axis ``1e300 1e300 0`` is the unit vector (1, 1, 0)/√2).

    The one normalisation of a direction read from a model file (URDF and MJCF joint axes,
    MJCF orientation vectors and quaternions). ``what`` names the element (``joint 'j1'``),
    ``label`` the file, ``noun`` the value in the message.

    Raises:
        ImportModelError: ``v`` is zero, shorter than 1e-12 or not finite.
    """
    v = np.asarray(v, dtype=float)
    big = float(np.max(np.abs(v))) if v.size else 0.0
    where = what if label is None else f"{label}: {what}"
    if not (math.isfinite(big) and big > 0.0):
        raise ImportModelError(f"{where}: the {noun} {v.tolist()} has zero length"
                               if big == 0.0 else f"{where}: the {noun} {v.tolist()} is not finite",
                               element=what)
    u = v / big
    n = float(np.linalg.norm(u))
    if big * n < 1e-12:
        raise ImportModelError(f"{where}: the {noun} {v.tolist()} has (near) zero length "
                               f"({big * n:.3g} < 1e-12)", element=what)
    return u / n


def movable_joint(kind: str, O: np.ndarray, axis: np.ndarray, *, name: str,
                  qlim: tuple[float, float] | None, vmax: float | None,
                   what: str, post_extra: np.ndarray | None = None,
                   offset: float = 0.0) -> JointDescription:
    """Joint with ``pre = O · R_a · M(−offset)``, ``post = R_aᵀ · post_extra``."""
    Ra = transform(axis_rotation(axis))
    pre = O @ Ra
    if offset:
        M = np.eye(4)
        if kind == "revolute":
            c, s = math.cos(-offset), math.sin(-offset)
            M[:2, :2] = [[c, -s], [s, c]]
        else:
            M[2, 3] = -offset
        pre = pre @ M
    post = Ra.T.copy()
    if post_extra is not None:
        post = post @ post_extra
    return JointDescription(kind=kind, pre=pre, post=post, name=name, element=what, qlim=qlim,
                            vmax=vmax)
