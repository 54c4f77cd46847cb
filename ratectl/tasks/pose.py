"""`Pose`: a link's full pose (6 rows)."""

from __future__ import annotations

from numpy.typing import ArrayLike

from .base import FrameTask, check_pose, check_vector

__all__ = ["Pose"]


class Pose(FrameTask):
    """Track a 4×4 pose with a link's frame (default the tool): 6 rows [linear; angular].

    ``b = ξ_ff + K e`` with ``e = [p_d − p ; log(R_d Rᵀ)]`` (base axes) and ``A = J``
    (the link's geometric Jacobian, base axes, at the link origin).

    Args:
        link: a name of ``chain.link_names``, or None for the tool.
        priority, weight, gain: see `Task`.
        target: the initial target pose (4×4), or None until `set_target`.
    """

    size = 6
    _rows = slice(0, 6)

    def __init__(self, *, link: str | None = None, priority: int = 0, weight: float = 1.0,
                 gain: float = 10.0, target: ArrayLike | None = None) -> None:
        super().__init__(link=link, priority=priority, weight=weight, gain=gain)
        if target is not None:
            self.set_target(target)

    def set_target(self, T: ArrayLike, *, twist: ArrayLike | None = None) -> None:
        """Track the pose ``T`` (4×4, base frame), with an optional feed-forward twist
        ``[v; ω]`` (6,) [m/s; rad/s] in base axes."""
        self._set(check_pose(T), check_vector(twist, 6, "twist", "[m/s; rad/s]"))
