"""What the viewer draws, as plain arrays (no viser, no trimesh): the capsule skeleton of
a chain, the lost directions of a singularity report, the points of a path.

Every chain frame ``T_k`` (``Chain.frames(q)``: ``T_0`` the base, ``T_k`` the frame after
joint k) carries one rigid body. Joint i is ``T_i = T_{i−1} · P_i · M_i(q_i) · Q_i``, so
body k (after joint k, before joint k+1) holds, in its own frame k:

* the origin of joint k's moving frame ``T_{k−1} P_k M_k``, at ``a = Q_k⁻¹ · 0``
  (for k = 0, the base origin), and that joint's axis, the z axis of ``Q_k⁻¹``;
* the point of joint k+1's axis ``b = P_{k+1} · 0`` (for the last body, the tool origin).

The capsule polyline of body k runs ``a → c → b`` with the corner ``c = a + ((b − a)·z) z``,
the foot of ``b`` on joint k's axis: for a standard DH row this is ``o_{k−1} + d_k z_{k−1}``,
so the drawing follows the d and a offsets of the table.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import InputError
from ..spatial import inverse_transform

if TYPE_CHECKING:
    from ..model.chain import Chain
    from ..singularity import SingularityReport

__all__ = ["body_polylines", "joint_markers", "lost_directions", "path_points"]


def body_polylines(chain: Chain) -> list[np.ndarray]:
    """For every chain frame k = 0…n, the capsule polyline of its body in frame-k
    coordinates [m]: an (m, 3) array of 1 to 3 distinct points (see the module docstring)."""
    n = chain.dof
    out = []
    for k in range(n + 1):
        if k == 0:
            a, z = np.zeros(3), np.array([0.0, 0.0, 1.0])
        else:
            Qi = inverse_transform(chain.joints[k - 1].post)
            a, z = Qi[:3, 3], Qi[:3, 2]
        b = chain.joints[k].pre[:3, 3] if k < n else chain.tool[:3, 3]
        c = a + float((b - a) @ z) * z
        pts = [a]
        for p in (c, b):
            if np.linalg.norm(p - pts[-1]) > 1e-9:
                pts.append(p)
        out.append(np.array(pts))
    return out


def joint_markers(chain: Chain) -> list[tuple[int, np.ndarray, np.ndarray, str]]:
    """``(frame k, centre (3,), unit axis (3,), kind)`` of every joint, in the coordinates of
    the body it moves (frame k for joint k, 1-based): where the viewer draws the joint."""
    out = []
    for k, j in enumerate(chain.joints, start=1):
        Qi = inverse_transform(j.post)
        out.append((k, Qi[:3, 3].copy(), Qi[:3, 2].copy(), j.kind))
    return out


def lost_directions(report: SingularityReport, *, min_component: float = 0.05
                    ) -> list[tuple[str, np.ndarray]]:
    """The task directions being lost at a configuration, split into what can be drawn
    at the tool: ``[("translation" | "rotation", unit vector (3,)), ...]`` in base axes.

    The directions are ``report.lost_directions_task`` (the columns of a basis of what the
    arm cannot produce, in scaled twist coordinates [v/L; ω]) at a singular configuration,
    and ``report.weakest_direction_task`` (the left singular vector of σ_min(J_L)) when it is
    only near one; none when it is regular. Each column contributes its linear part (a
    direction of translation) and its angular part (an axis of rotation) where that part's
    norm is at least ``min_component`` (the column is a unit vector).
    """
    if report.singular and report.lost_directions_task.shape[1]:
        cols = report.lost_directions_task.T
    elif report.near_singular:
        cols = report.weakest_direction_task[None, :]
    else:
        return []
    out = []
    for u in cols:
        for name, part in (("translation", u[:3]), ("rotation", u[3:])):
            norm = float(np.linalg.norm(part))
            if norm >= min_component:
                out.append((name, part / norm))
    return out


def path_points(path: Any, *, samples: int = 200) -> np.ndarray:
    """Points (m, 3) [m] of a path to draw as a polyline.

    ``path`` is a `ratectl.paths.Path` (sampled at ``samples`` path parameters from 0 to
    its length), an (m, 3) array of points or an (m, 4, 4) array of poses.
    """
    if hasattr(path, "pose_at") and hasattr(path, "length"):
        s = np.linspace(0.0, float(path.length), samples)
        return np.array([path.pose_at(x)[:3, 3] for x in s])
    try:
        a = np.asarray(path, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"path must be a ratectl path, (m, 3) points or (m, 4, 4) poses, got "
                         f"{type(path).__name__}", argument="path", value=path) from None
    if a.ndim == 3 and a.shape[1:] == (4, 4):
        a = a[:, :3, 3]
    if a.ndim != 2 or a.shape[1] != 3 or len(a) < 2 or not np.all(np.isfinite(a)):
        raise InputError(f"path must be a ratectl path, (m, 3) points or (m, 4, 4) poses with m >= 2 "
                         f"finite entries, got shape {a.shape}", argument="path", value=path)
    return a
