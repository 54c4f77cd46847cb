"""A circular arc (centre, axis, angle), or through three points.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..checks import positive_number
from ..errors import InputError
from ..spatial import so3_log
from .base import Path, _Geodesic
from .checks import _pose, _vec3

__all__ = ['Arc']


class Arc(Path):
    """Circular arc of the tool origin about an axis through ``centre``.

    ``p(φ) = c + Rot(k, φ)(p₀ − c)`` for φ ∈ [0, angle] (right-handed about the unit
    axis k; the start point is the position of ``T_start``). Orientation:
    ``"fixed"`` keeps R₀; ``"rotate"`` turns the tool with the arc, R(φ) = Rot(k, φ)R₀.
    Use `through` for an arc given by three points.

    Args:
        T_start: start pose (4×4).
        centre: a point on the axis [m] (3,).
        axis: axis direction (3,), normalised here.
        angle: swept angle [rad] (may be negative, |angle| ≤ 2π).
        orientation: ``"fixed"`` or ``"rotate"``.
        speed: maximum ṡ [m/s], as for `Line`.
        acceleration: maximum |s̈| [m/s²], as for `Line`.
        jerk: optional jerk limit [m/s³], as for `Line`.
        law: time law, as for `Line`.
        rotation_length: ρ [m/rad], as for `Line`.
    """

    def __init__(self, T_start: ArrayLike, *, centre: ArrayLike, axis: ArrayLike, angle: float,
                 orientation: str = "fixed", speed: float, acceleration: float, jerk: float | None = None,
                 law: str | None = None, rotation_length: float = 0.1, _R_end: Any = None) -> None:
        self.T_start = _pose(T_start, "T_start")
        c = _vec3(centre, "centre")
        k = _vec3(axis, "axis")
        nk = float(np.linalg.norm(k))
        if nk < 1e-12:
            raise InputError("axis must be a non-zero vector", argument="axis", value=axis)
        k = k / nk
        angle = float(angle)
        if not (math.isfinite(angle) and 0 < abs(angle) <= 2 * math.pi + 1e-12):
            raise InputError(f"angle must be non-zero with |angle| ≤ 2π [rad], got {angle!r}",
                             argument="angle", value=angle)
        p0 = self.T_start[:3, 3]
        with np.errstate(over="ignore", invalid="ignore"):  # far out: refused by _setup (length)
            r0 = p0 - c
            r0 = r0 - (r0 @ k) * k  # radial part
            self.centre = c + ((p0 - c) @ k) * k
            self.radius = math.hypot(*r0.tolist())
        self.axis, self.angle, self.radial = k, angle, r0
        if self.radius < 1e-9:
            raise InputError("the start position lies on the arc axis (radius 0); give a centre "
                             "away from the start point", argument="centre", value=centre)
        R0 = self.T_start[:3, :3]
        if _R_end is not None:
            w = so3_log(R0.T @ _R_end)
        elif orientation == "fixed":
            w = np.zeros(3)
        elif orientation == "rotate":
            w = R0.T @ k * angle
        else:
            raise InputError(f"orientation must be 'fixed' or 'rotate', got {orientation!r}",
                             argument="orientation", value=orientation)
        self.orientation = orientation if _R_end is None else "interpolated"
        self.rot = _Geodesic(R0, w)
        rho = positive_number("rotation_length", rotation_length)
        L = math.hypot(self.radius * abs(angle), rho * self.rot.angle)
        if not math.isfinite(L):
            L = math.inf  # NaN from an overflowed centre: refused by _setup
        self._setup(L, speed=speed, acceleration=acceleration, jerk=jerk, law=law,
                    rotation_length=rotation_length)

    @classmethod
    def through(cls, T_start: ArrayLike, via: ArrayLike, T_end: ArrayLike, *, speed: float,
                acceleration: float, jerk: float | None = None, law: str | None = None,
                rotation_length: float = 0.1) -> Arc:
        """The arc from the position of ``T_start`` through the point ``via`` (3,) to the position
        of ``T_end``; the orientation goes from R(T_start) to R(T_end) on the SO(3) geodesic."""
        T0, T1 = _pose(T_start, "T_start"), _pose(T_end, "T_end")
        a, b, c = T0[:3, 3], _vec3(via, "via"), T1[:3, 3]
        u, v = b - a, c - a
        n = np.cross(u, v)
        n2 = float(n @ n)
        if n2 < 1e-18 * max(float(u @ u) * float(v @ v), 1e-30):
            raise InputError("the three points are collinear (or coincide): no circle passes "
                             "through them; use Line", argument="via", value=via)
        centre = a + (np.cross(n, u) * float(v @ v) + np.cross(v, n) * float(u @ u)) / (2.0 * n2)
        k = n / math.sqrt(n2)
        ra, rc_ = a - centre, c - centre
        ang = math.atan2(float(np.cross(ra, rc_) @ k), float(ra @ rc_))
        if ang <= 0.0:
            ang += 2 * math.pi
        return cls(T0, centre=centre, axis=k, angle=ang, speed=speed, acceleration=acceleration,
                   jerk=jerk, law=law, rotation_length=rotation_length, _R_end=T1[:3, :3])

    def _geometry(self, s):
        lam = s / self.length
        phi = lam * self.angle
        c, sn = math.cos(phi), math.sin(phi)
        k, r = self.axis, self.radial
        kxr = np.cross(k, r)
        p = self.centre + c * r + sn * kxr
        dp = (-sn * r + c * kxr) * (self.angle / self.length)
        return p, self.rot.at(lam), dp, self.rot.w_base / self.length
