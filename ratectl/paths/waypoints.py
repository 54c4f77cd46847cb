"""A polyline of poses with continuous-curvature blends at the corners.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from ..checks import positive_number
from ..errors import InputError
from ..spatial import so3_exp, so3_left_jacobian
from .base import Path
from .checks import _pose
from .line import Line

__all__ = ['Waypoints']


def _smoothstep(x: float) -> tuple[float, float]:
    """Blend weight β = 10x³ − 15x⁴ + 6x⁵ on x ∈ [0, 1] and its integral B = ∫₀ˣ β = 5x⁴/2 − 3x⁵ + x⁶
    (β′ and β″ vanish at both ends; B(1) = 1/2)."""
    x2 = x * x
    return x2 * x * (10.0 - 15.0 * x + 6.0 * x2), x2 * x2 * (2.5 - 3.0 * x + x2)


class Waypoints(Path):
    """A sequence of poses joined by straight segments with continuous-curvature corner blends.

    Each segment is a `Line`. Around every inner waypoint i (at path parameter S_i) the
    path leaves the segments on ``s ∈ [S_i − d, S_i + d]``, d = min(blend, half of each
    adjacent segment), and blends their *rates* instead of their positions. In coordinates
    of the waypoint, y = [p − p_i; log(R_iᵀR)], each segment is the straight line
    y = (s − S_i)c with the constant unit rate c = [Δp; w]/L of the segment; the blend is

        dy/ds = (1 − β(x)) c_in + β(x) c_out,   x = (s − S_i + d)/(2d),
        y(s)  = (s − S_i) c_in + 2d B(x) (c_out − c_in),

    with β the quintic smooth step and B = ∫β (`_smoothstep`); p = p_i + y_p and
    R = R_i exp(y_R). Because β′ = β″ = 0 at x = 0 and 1, p, R and their first three
    derivatives in s meet the segments' at both blend ends: the curvature is continuous
    (zero at the ends, no jump to a circular arc) and so is its rate, so a joint path
    through a blend has a bounded, continuous q‴ and a jerk-limited motion can follow it.
    The derivatives are exact: dp/ds = dy_p/ds, ω/ṡ = R_i J_l(y_R) dy_R/ds
    (`ratectl.spatial.so3_left_jacobian`).

    The blend cuts the corner instead of turning on the spot: at s = S_i the tool passes
    (5/32)·d·‖Δp_out/L_out − Δp_in/L_in‖ from waypoint i (``corner_distances[i]``; 0.22·d
    at a right angle without rotation), and its rotation vector from R_i is
    (5/32)·d·(w_out/L_out − w_in/L_in). A blend through the waypoint itself, such as
    (1 − α)p_in(s) + α p_out(s), turns on the spot there: over the same d it has twice the
    peak d²p/ds² and 5.2 times the peak d³p/ds³ (the joint jerk needed at a given
    speed scales with the latter).

    The parameter s is the combined length of the polyline (``length`` = the sum of the
    segment lengths). On a segment ‖[dp/ds; ρ ω/ṡ]‖ = 1; inside a blend it is below 1 (a
    convex combination of two unit rates, and ‖J_l v‖ ≤ ‖v‖), so the tool never moves
    faster than ṡ in the metric of ``rotation_length`` ρ. ``blend=0`` gives sharp corners
    through the waypoints, listed in `corners`: the tangent jumps there, so a motion that
    stays on the path must stop at each (the governor plans ṡ = 0 there; the path's own
    time law does not stop there).

    Args:
        poses: N ≥ 2 poses (N, 4, 4).
        blend: blend half-length d [m].
        speed: maximum ṡ [m/s], as for `Line`.
        acceleration: maximum |s̈| [m/s²], as for `Line`.
        jerk: optional jerk limit [m/s³], as for `Line`.
        law: time law, as for `Line`.
        rotation_length: ρ [m/rad], as for `Line`.

    Attributes:
        segments: the `Line` segments.
        knots: (N,) path parameter S_i of each waypoint [m].
        blends: (N,) blend half-length d_i [m] (0 at the ends).
        corner_distances: (N,) distance of p(S_i) from waypoint i [m] (0 at the ends and
            without blends).
    """

    def __init__(self, poses: ArrayLike, *, blend: float = 0.02, speed: float, acceleration: float,
                 jerk: float | None = None, law: str | None = None, rotation_length: float = 0.1) -> None:
        try:
            if isinstance(poses, str | bytes) or np.iscomplexobj(poses):
                raise TypeError("poses")
            P = np.asarray(poses, dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise InputError(f"poses must be an (N, 4, 4) array of rigid transforms with N ≥ 2, got "
                             f"{poses!r}"[:300], argument="poses", value=poses) from None
        if P.ndim != 3 or P.shape[1:] != (4, 4) or P.shape[0] < 2:
            raise InputError(f"poses must be an (N, 4, 4) array with N ≥ 2, got shape {P.shape}",
                             argument="poses", value=poses)
        blend = positive_number("blend", blend, allow_zero=True, unit="[m]")
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
        self.corner_distances = np.zeros(len(P))
        for i in range(1, len(P) - 1):
            dv = self._rate(i)[:3] - self._rate(i - 1)[:3]
            self.corner_distances[i] = 5.0 / 32.0 * self.blends[i] * float(np.linalg.norm(dv))
        self._setup(float(self.knots[-1]), speed=speed, acceleration=acceleration, jerk=jerk, law=law,
                    rotation_length=rotation_length)

    @property
    def corners(self) -> np.ndarray:
        """Path parameters [m] of the sharp corners: the inner waypoints without a blend
        (``blend=0``) where the direction [Δp; w]/L of the path changes (see `Path.corners`)."""
        out = [self.knots[i] for i in range(1, len(self.segments))
               if self.blends[i] == 0.0 and np.linalg.norm(self._rate(i) - self._rate(i - 1)) > 1e-12]
        return np.array(out, dtype=float)

    def _search_grid(self) -> np.ndarray:
        """101 samples over the path, and 9 on every segment (its knots included)."""
        per = [np.linspace(a, b, 9) for a, b in zip(self.knots[:-1], self.knots[1:], strict=True)]
        return np.unique(np.concatenate([super()._search_grid(), *per]))

    def _global_nearest(self, x: np.ndarray, Rx: np.ndarray | None) -> tuple[float, float, float]:
        """The global nearest point piece by piece: on each straight part of a segment (between
        its blends) the segment's closed-form estimate refined within that part, on each
        blend a descent from its middle and both ends within the blend; the best of them
        (the first one on a tie). Each piece is smooth, so no descent crosses a corner."""
        best: tuple[float, float, float] | None = None
        fbest = math.inf
        r2 = self.rotation_length ** 2
        nseg = len(self.segments)
        for i, g in enumerate(self.segments):
            a = float(self.knots[i] + self.blends[i])
            b = float(self.knots[i + 1] - self.blends[i + 1])
            if b >= a:
                s0, _ = g._start_estimate(x, Rx)
                s0 = min(max(float(self.knots[i]) + s0, a), b)
                cands = [self._descend(s0, x, Rx, a, b, max(0.1 * (b - a), 1e-9))]
                if i + 1 < nseg and self.blends[i + 1] == 0.0:  # a sharp corner: its incoming side
                    cands.append(self._descend(b, x, Rx, a, b, max(0.1 * (b - a), 1e-9)))
            else:  # pragma: no cover - blends are at most half of each segment
                cands = []
            k = i + 1
            if 1 <= k < nseg and self.blends[k] > 0.0:
                lo, hi = float(self.knots[k] - self.blends[k]), float(self.knots[k] + self.blends[k])
                step = max(0.5 * (hi - lo), 1e-9)
                cands += [self._descend(s, x, Rx, lo, hi, step) for s in (lo, 0.5 * (lo + hi), hi)]
            for c in cands:
                f = c[1] + r2 * c[2]
                if f < fbest:
                    fbest, best = f, c
        assert best is not None
        return best

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

    def _geometry_before(self, s):
        k = int(np.searchsorted(self.knots, s, side="left"))
        if 1 <= k <= len(self.segments) - 1 and self.knots[k] == s and self.blends[k] == 0.0:
            return self._line(k - 1, s)  # a sharp corner: the incoming segment at its end
        return self._geometry(s)

    def _rate(self, i: int) -> np.ndarray:
        """Constant unit rate c = [Δp; w]/L (6,) of segment i, w in the segment's own axes."""
        g = self.segments[i]
        return np.concatenate([g.dp, g.rot.w]) / g.length

    def _blend(self, k: int, s: float):
        """(p, R, dp/ds, ω/ṡ) on the blend around waypoint k (see the class docstring)."""
        d = self.blends[k]
        u = s - self.knots[k]
        beta, B = _smoothstep((u + d) / (2.0 * d))
        c_in, c_out = self._rate(k - 1), self._rate(k)
        y = u * c_in + 2.0 * d * B * (c_out - c_in)
        dy = c_in + beta * (c_out - c_in)
        Rk = self.poses[k, :3, :3]
        w = Rk @ (so3_left_jacobian(y[3:]) @ dy[3:])
        return self.poses[k, :3, 3] + y[:3], Rk @ so3_exp(y[3:]), dy[:3], w
