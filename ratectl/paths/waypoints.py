"""A polyline of poses with smooth blends at the corners.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from ..spatial import so3_exp, so3_log
from .base import Path
from .checks import _pose
from .line import Line

__all__ = ['Waypoints']


def _smoothstep(x: float) -> tuple[float, float]:
    """Quintic smooth step α = 10x³ − 15x⁴ + 6x⁵ and dα/dx (α', α'' vanish at 0 and 1)."""
    return x**3 * (10 - 15 * x + 6 * x * x), 30 * x * x * (1 - x) ** 2


class Waypoints(Path):
    """A sequence of poses joined by straight segments with smooth blends at the corners.

    Each segment is a `Line`. Around every inner waypoint i the path blends the
    incoming and outgoing segments over ``s ∈ [S_i − d, S_i + d]`` with
    d = min(blend, half of each adjacent segment):
    ``p = (1 − α)p_in(s) + α p_out(s)`` and ``R = R_in(s) exp(α log(R_in(s)ᵀ R_out(s)))``,
    where p_in/R_in and p_out/R_out extend the two segments and α is the quintic smooth
    step of (s − S_i + d)/(2d). The blended path passes through the waypoint and is
    twice continuously differentiable at the blend ends. ``blend=0`` gives sharp corners
    (the tool stops at each corner only if the time law or governor makes it).

    Args:
        poses: N ≥ 2 poses (N, 4, 4).
        blend: blend half-length d [m].
        speed: maximum ṡ [m/s], as for `Line`.
        acceleration: maximum |s̈| [m/s²], as for `Line`.
        jerk: optional jerk limit [m/s³], as for `Line`.
        law: time law, as for `Line`.
        rotation_length: ρ [m/rad], as for `Line`.
    """

    def __init__(self, poses: ArrayLike, *, blend: float = 0.02, speed: float, acceleration: float,
                 jerk: float | None = None, law: str | None = None, rotation_length: float = 0.1) -> None:
        P = np.asarray(poses, dtype=float)
        if P.ndim != 3 or P.shape[1:] != (4, 4) or P.shape[0] < 2:
            raise InputError(f"poses must be an (N, 4, 4) array with N ≥ 2, got shape {P.shape}",
                             argument="poses", value=poses)
        blend = float(blend)
        if not (blend >= 0.0 and math.isfinite(blend)):
            raise InputError(f"blend must be a non-negative length [m], got {blend!r}",
                             argument="blend", value=blend)
        self.poses = np.array([_pose(T, f"poses[{i}]") for i, T in enumerate(P)])
        self.segments = []
        for i in range(len(P) - 1):
            seg = Line(self.poses[i], self.poses[i + 1], speed=speed, acceleration=acceleration,
                       rotation_length=rotation_length)
            if seg.length <= 1e-12:
                raise InputError(f"poses[{i}] and poses[{i + 1}] coincide; remove the duplicate",
                                 argument="poses", value=poses)
            self.segments.append(seg)
        lengths = np.array([g.length for g in self.segments])
        self.knots = np.concatenate([[0.0], np.cumsum(lengths)])
        self.blends = np.zeros(len(P))
        for i in range(1, len(P) - 1):
            self.blends[i] = min(blend, 0.5 * lengths[i - 1], 0.5 * lengths[i])
        self._setup(float(self.knots[-1]), speed=speed, acceleration=acceleration, jerk=jerk, law=law,
                    rotation_length=rotation_length)

    def _line(self, i: int, s: float):
        """Segment i extended beyond its ends: (p, R, dp/ds, ω/ṡ) at global s."""
        g = self.segments[i]
        u = s - self.knots[i]
        lam = u / g.length
        return g.p0 + lam * g.dp, g.rot.at(lam), g.dp / g.length, g.rot.w_base / g.length

    def _geometry(self, s):
        i = int(np.searchsorted(self.knots, s, side="right")) - 1
        i = min(max(i, 0), len(self.segments) - 1)
        # nearest inner knot, if inside its blend zone
        for k in (i, i + 1):
            if 1 <= k <= len(self.segments) - 1:
                d = self.blends[k]
                if d > 0.0 and abs(s - self.knots[k]) < d:
                    return self._blend(k, s)
        return self._line(i, s)

    def _rot_blend(self, k: int, s: float):
        d = self.blends[k]
        a, _ = _smoothstep((s - self.knots[k] + d) / (2 * d))
        _, Ri, _, _ = self._line(k - 1, s)
        _, Ro, _, _ = self._line(k, s)
        return Ri @ so3_exp(a * so3_log(Ri.T @ Ro))

    def _blend(self, k: int, s: float):
        d = self.blends[k]
        a, da = _smoothstep((s - self.knots[k] + d) / (2 * d))
        da /= 2 * d
        pi, _, vi, _ = self._line(k - 1, s)
        po, _, vo, _ = self._line(k, s)
        p = (1 - a) * pi + a * po
        dp = (1 - a) * vi + a * vo + da * (po - pi)
        R = self._rot_blend(k, s)
        h = 1e-6 * d
        Rp, Rm = self._rot_blend(k, s + h), self._rot_blend(k, s - h)
        w = so3_log(Rp @ Rm.T) / (2 * h)
        return p, R, dp, w
