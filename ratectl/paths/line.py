"""A straight line between two poses, orientation on the SO(3) geodesic.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from ..checks import positive_number
from ..spatial import so3_log
from .base import Path, _Geodesic
from .checks import _pose

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
        with np.errstate(over="ignore", invalid="ignore"):  # too far apart: refused by _setup
            self.dp = self.T_end[:3, 3] - self.p0
            dist = math.hypot(*self.dp.tolist())
        self.rot = _Geodesic(self.T_start[:3, :3], so3_log(self.T_start[:3, :3].T @ self.T_end[:3, :3]))
        rho = positive_number("rotation_length", rotation_length)
        L = math.hypot(dist, rho * self.rot.angle)
        self._setup(L, speed=speed, acceleration=acceleration, jerk=jerk, law=law,
                    rotation_length=rotation_length)

    def _geometry(self, s):
        L = self.length
        if L == 0.0:
            return self.p0.copy(), self.rot.R0, np.zeros(3), np.zeros(3)
        lam = s / L
        return self.p0 + lam * self.dp, self.rot.at(lam), self.dp / L, self.rot.w_base / L

    def _start_estimate(self, x, Rx):
        """The exact nearest point of the segment for a position; for a pose, the minimiser of
        ‖p(λ) − x‖² + ρ²‖λw − φ‖² (φ = log(R₀ᵀR_x)), exact when R_x lies on the geodesic."""
        L = self.length
        num, den = float((x - self.p0) @ self.dp), float(self.dp @ self.dp)
        if Rx is not None:
            r2 = self.rotation_length ** 2
            num += r2 * float(self.rot.w @ so3_log(self.rot.R0.T @ Rx))
            den += r2 * self.rot.angle ** 2
        if L == 0.0 or den == 0.0:
            return 0.0, max(L, 1e-9)
        return min(max(num / den, 0.0), 1.0) * L, max(0.1 * L, 1e-9)
