"""`Orientation`: a link's orientation (3 rows)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from .base import FrameTask, check_pose, check_vector

__all__ = ["Orientation"]


class Orientation(FrameTask):
    """Turn a link's frame (default the tool's) to an orientation: 3 rows.

    ``b = ω_ff + K log(R_d Rᵀ)`` [rad/s] (base axes), ``A = J_ω``. The position is left free.

    Args:
        link: a name of ``chain.link_names``, or None for the tool.
        priority, weight, gain: see `Task`.
        target: the initial target rotation (3×3) or pose (4×4), or None.
    """

    size = 3
    _rows = slice(3, 6)

    def __init__(self, *, link: str | None = None, priority: int = 0, weight: float = 1.0,
                 gain: float = 10.0, target: ArrayLike | None = None) -> None:
        super().__init__(link=link, priority=priority, weight=weight, gain=gain)
        if target is not None:
            self.set_target(target)

    def set_target(self, R: ArrayLike, *, angular_velocity: ArrayLike | None = None) -> None:
        """Track the rotation ``R`` (3×3, or the rotation of a 4×4 pose) in the base frame,
        with an optional feed-forward angular velocity (3,) [rad/s]."""
        try:
            a = np.array(R, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"target must be a 3x3 rotation or 4x4 pose, got {R!r}"[:300],
                             argument="target", value=R) from None
        if a.shape == (3, 3):
            T = np.eye(4)
            T[:3, :3] = a
            a = T
        T = check_pose(a)
        T[:3, 3] = 0.0
        self._set(T, check_vector(angular_velocity, 3, "angular_velocity", "[rad/s]"))
