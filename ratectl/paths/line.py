"""A straight line between two poses, orientation on the SO(3) geodesic.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..spatial import so3_log
from .base import Path, _Geodesic
from .checks import _pose, _positive

__all__ = ['Line']


class Line(Path):
    """Straight line from ``T_start`` to ``T_end`` (4×4 poses); orientation on the SO(3) geodesic.

    ``p(s) = p₀ + (s/L)(p₁ − p₀)``, ``R(s) = R₀ exp((s/L) log(R₀ᵀR₁))``,
    ``L = √(‖p₁ − p₀‖² + (ρθ)²)``.

    Args:
        T_start: start pose (4×4).
        T_end: end pose (4×4).
        speed: maximum ṡ [m/s].
        acceleration: maximum |s̈| [m/s²].
        jerk: optional jerk limit [m/s³].
        law: time law (default trapezoidal, jerk-limited if ``jerk`` is given).
        rotation_length: ρ [m/rad] (see the module docstring).
    """

    def __init__(self, T_start: ArrayLike, T_end: ArrayLike, *, speed: float, acceleration: float,
                 jerk: float | None = None, law: str | None = None, rotation_length: float = 0.1) -> None:
        self.T_start = _pose(T_start, "T_start")
        self.T_end = _pose(T_end, "T_end")
        self.p0 = self.T_start[:3, 3]
        self.dp = self.T_end[:3, 3] - self.p0
        self.rot = _Geodesic(self.T_start[:3, :3], so3_log(self.T_start[:3, :3].T @ self.T_end[:3, :3]))
        rho = _positive(rotation_length, "rotation_length")
        L = math.hypot(float(np.linalg.norm(self.dp)), rho * self.rot.angle)
        self._setup(L, speed=speed, acceleration=acceleration, jerk=jerk, law=law,
                    rotation_length=rotation_length)

    def _geometry(self, s):
        L = self.length
        if L == 0.0:
            return self.p0.copy(), self.rot.R0, np.zeros(3), np.zeros(3)
        lam = s / L
        return self.p0 + lam * self.dp, self.rot.at(lam), self.dp / L, self.rot.w_base / L

    def closest(self, point: ArrayLike, *, s_hint: Any = None, window: Any = None) -> float:
        """Exact projection onto the segment (the orientation does not enter)."""
        L = self.length
        d2 = float(self.dp @ self.dp)
        if L == 0.0 or d2 == 0.0:
            return super().closest(point, s_hint=s_hint, window=window)
        lam = float((np.asarray(point, dtype=float) - self.p0) @ self.dp) / d2
        return min(max(lam, 0.0), 1.0) * L
