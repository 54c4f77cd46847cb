"""`Position`: a link's origin (3 rows)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .base import FrameTask, check_vector

__all__ = ["Position"]


class Position(FrameTask):
    """Bring a link's origin (default the tool's) to a point: 3 rows.

    ``b = v_ff + K (p_d − p)`` [m/s], ``A = J_v`` (the linear rows of the link's Jacobian,
    base axes). The orientation is left free.

    Args:
        link: a name of ``chain.link_names``, or None for the tool.
        priority, weight, gain: see `Task`.
        target: the initial target point (3,) [m] in the base frame, or None.
    """

    size = 3
    _rows = slice(0, 3)

    def __init__(self, *, link: str | None = None, priority: int = 0, weight: float = 1.0,
                 gain: float = 10.0, target: ArrayLike | None = None) -> None:
        super().__init__(link=link, priority=priority, weight=weight, gain=gain)
        if target is not None:
            self.set_target(target)

    def set_target(self, p: ArrayLike, *, velocity: ArrayLike | None = None) -> None:
        """Track the point ``p`` (3,) [m] (or the position of a 4×4 pose), base frame, with an
        optional feed-forward velocity (3,) [m/s]."""
        a = np.asarray(p, dtype=float) if not isinstance(p, str | bytes) else p
        if isinstance(a, np.ndarray) and a.shape == (4, 4):
            a = a[:3, 3]
        point = check_vector(a, 3, "target", "[m]")
        T = np.eye(4)
        T[:3, 3] = point
        self._set(T, check_vector(velocity, 3, "velocity", "[m/s]"))

    @property
    def point(self) -> np.ndarray | None:
        """The target point (3,) [m] or None."""
        return None if self._target is None else self._target[:3, 3].copy()
