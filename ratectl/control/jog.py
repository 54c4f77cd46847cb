"""Jogging: the tool moves along the commanded twist ξ at a fraction c ∈ [0, 1] of it.

    q̇ = c·J⁺ξ

c changes within the acceleration share of `ProgressLimits` and never exceeds its bounds
(with ξ as the direction, one unit of progress per second is the full twist), so the tool's
velocity is always a non-negative multiple of the command: near a singularity or a joint
limit the arm slows down and stops along ξ, never sideways, and a command that leads away
moves at once.
"""

from __future__ import annotations

import numpy as np

from .progress import ProgressCaps

__all__ = ["Jog"]


class Jog:
    """The fraction c ∈ [0, 1] of the commanded twist the tool moves at (see the module
    docstring). Owns c and the last commanded twist."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.c = 0.0
        self.twist: np.ndarray | None = None
        self.w_prev: np.ndarray | None = None

    def start(self, twist: np.ndarray) -> None:
        """A new commanded twist: c continues from the previous motion projected on it."""
        prev = self.twist
        if prev is not None and self.c > 0.0 and not np.array_equal(prev, twist):
            nn = float(twist @ twist)
            self.c = min(max(self.c * float(prev @ twist) / nn, 0.0), 1.0) if nn > 0.0 else 0.0
            self.w_prev = None
        self.twist = twist.copy()

    def advance(self, caps: ProgressCaps, dt: float) -> float:
        """c for the coming period: toward min(1, the speed bound), changed by at most the
        acceleration bound times dt (an exceeded speed bound is met at once, which the
        braking laws of the bound keep within amax in a fault-free loop)."""
        goal = min(1.0, caps.speed)
        step = caps.accel * dt
        c = self.c
        c = min(c + step, goal) if c < goal else goal
        self.c = max(c, 0.0)
        return self.c
