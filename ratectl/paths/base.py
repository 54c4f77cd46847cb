"""The `Path` base class: a curve of tool poses over the path parameter s, with a time law.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from ..spatial import so3_exp, so3_log
from .checks import _positive
from .time_laws import make_time_law

__all__ = ['Path', 'MAX_STEPS']


#: Default cap on the number of steps of a loop over a path (`Path.steps`): 10⁶
#: (about 17 minutes at 1 kHz).
MAX_STEPS = 1_000_000


# ---------------------------------------------------------------------- paths
class Path:
    """Base class of Cartesian paths (see the module docstring).

    Subclasses implement ``_geometry(s) -> (p, R, dp/ds, ω/ṡ)``. Common keyword
    options: ``speed`` [m/s] and ``acceleration`` [m/s²] limits on ṡ and s̈, ``jerk``
    [m/s³] (enables the jerk-limited law by default), ``law`` (one of `LAWS`),
    ``rotation_length`` ρ [m/rad].
    """

    length: float

    def _setup(self, length: float, *, speed, acceleration, jerk, law, rotation_length) -> None:
        self.speed = _positive(speed, "speed")
        self.acceleration = _positive(acceleration, "acceleration")
        self.jerk = None if jerk is None else _positive(jerk, "jerk")
        self.rotation_length = _positive(rotation_length, "rotation_length")
        if law is None:
            law = "trapezoidal" if jerk is None else "jerk-limited"
        self.length = float(length)
        self.law = make_time_law(law, self.length, speed=self.speed, acceleration=self.acceleration,
                                 jerk=self.jerk)

    # -- geometry -------------------------------------------------------------
    def _geometry(self, s: float):  # pragma: no cover - abstract
        raise NotImplementedError

    def _clamp(self, s) -> float:
        s = float(s)
        if not math.isfinite(s):
            raise InputError(f"path parameter s must be finite, got {s!r}", argument="s", value=s)
        return min(max(s, 0.0), self.length)

    @property
    def duration(self) -> float:
        """Duration of the nominal time law [s]."""
        return self.law.duration

    @property
    def start(self) -> np.ndarray:
        """Pose at s = 0."""
        return self.pose_at(0.0)

    @property
    def end(self) -> np.ndarray:
        """Pose at s = length."""
        return self.pose_at(self.length)

    def position_at(self, s: ArrayLike) -> np.ndarray:
        """Tool position p(s) [m] (3,)."""
        return self._geometry(self._clamp(s))[0]

    def pose_at(self, s: ArrayLike) -> np.ndarray:
        """Tool pose P(s) (4×4) at path parameter ``s`` [m] (clamped to [0, length])."""
        p, R, _, _ = self._geometry(self._clamp(s))
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = p
        return T

    def twist_at(self, s: ArrayLike, *, sd: float = 1.0) -> np.ndarray:
        """Tool twist ``[dp/ds; ω_s]·ṡ`` (6,) at ``s`` for progress rate ``ṡ = sd`` [m/s]
        (with the default sd = 1 it is the path tangent dP/ds)."""
        _, _, dp, w = self._geometry(self._clamp(s))
        return np.concatenate([dp, w]) * float(sd)

    def curvature_twist_at(self, s: ArrayLike, *, h: float | None = None) -> np.ndarray:
        """Second derivative d²P/ds² as a twist-rate (6,) by central differences of
        `twist_at` (step ``h`` [m], default 1e-5·length)."""
        h = h or max(1e-5 * self.length, 1e-9)
        s = self._clamp(s)
        a, b = max(s - h, 0.0), min(s + h, self.length)
        if b <= a:
            return np.zeros(6)
        return (self.twist_at(b) - self.twist_at(a)) / (b - a)

    # -- time -----------------------------------------------------------------
    def progress(self, t: float) -> tuple[float, float, float]:
        """``(s, ṡ, s̈)`` of the nominal time law at time ``t`` [s]."""
        return self.law(float(t))

    def pose(self, t: float) -> np.ndarray:
        """Tool pose (4×4) at time ``t`` [s] of the nominal time law."""
        return self.pose_at(self.law(float(t))[0])

    def twist(self, t: float) -> np.ndarray:
        """Tool twist ``[v; ω]`` (6,) at time ``t`` [s] of the nominal time law."""
        s, sd, _ = self.law(float(t))
        return self.twist_at(s, sd=sd)

    def steps(self, dt: float, *, max_steps: int = MAX_STEPS) -> int:
        """Number of samples N = ⌈duration/dt⌉ + 1 of the nominal law every ``dt`` [s],
        checked up front: more than ``max_steps`` raises `InputError`
        naming the duration and dt (instead of running out of time or memory later).
        Loops over a path (sampling, following it) call this before any work."""
        dt = _positive(dt, "dt")
        n = self.duration / dt
        if not n <= max_steps - 1:
            raise InputError(
                f"{type(self).__name__} lasts {self.duration:.6g} s; every dt = {dt:.3g} s that is "
                f"{n:.3g} steps, more than the {max_steps} allowed; use a larger dt, a faster path "
                "(speed, acceleration), or pass a larger max_steps", argument="dt", value=dt)
        return int(math.ceil(n - 1e-9)) + 1

    def sample(self, dt: float, *, max_steps: int = MAX_STEPS):
        """Times, poses and twists of the nominal law every ``dt`` [s]: (t, (N,4,4), (N,6)).
        At most ``max_steps`` samples (see `steps`)."""
        dt = _positive(dt, "dt")
        n = self.steps(dt, max_steps=max_steps)
        t = np.minimum(np.arange(n) * dt, self.duration)
        return t, np.array([self.pose(x) for x in t]), np.array([self.twist(x) for x in t])

    # -- distance -------------------------------------------------------------
    def closest(self, point: ArrayLike, *, s_hint: float | None = None, window: float | None = None) -> float:
        """Path parameter of the point of the curve nearest to ``point`` (3,).

        Without ``s_hint``: a grid of 101 samples over the whole path, then Newton steps on
        ``(p(s) − x)·p'(s) = 0``. With ``s_hint``: Newton steps from it only (a local
        search, for tracking the nearest point along a motion), kept within
        ``s_hint ± window``.
        """
        x = np.asarray(point, dtype=float)
        L = self.length
        if L <= 0.0:
            return 0.0
        if s_hint is None:
            lo, hi = 0.0, L
            grid = np.linspace(lo, hi, 101)
            d = [float(np.sum((self._geometry(g)[0] - x) ** 2)) for g in grid]
            s = float(grid[int(np.argmin(d))])
            step = (hi - lo) / 100.0
        else:
            s = self._clamp(s_hint)
            w = L if window is None else float(window)
            lo, hi = max(0.0, s - w), min(L, s + w)
            step = max(w, 1e-9)
        for _ in range(12):
            p, _, dp, _ = self._geometry(s)
            g2 = float(dp @ dp)
            if g2 < 1e-18:
                break
            ds = -float((p - x) @ dp) / g2
            ds = max(-step, min(step, ds))
            s_new = min(max(s + ds, lo), hi)
            if abs(s_new - s) < 1e-12:
                s = s_new
                break
            s = s_new
        return s

    def distance(self, T: ArrayLike, *, s_hint: float | None = None, window: float | None = None):
        """Distance of the pose ``T`` from the path: ``(position [m], orientation [rad], s)`` where
        s is the nearest point of the curve and the orientation error is the angle between
        R and R(s)."""
        T = np.asarray(T, dtype=float)
        s = self.closest(T[:3, 3], s_hint=s_hint, window=window)
        p, R, _, _ = self._geometry(s)
        dpos = float(np.linalg.norm(T[:3, 3] - p))
        dang = float(np.linalg.norm(so3_log(R.T @ T[:3, :3])))
        return dpos, dang, s

    def __repr__(self) -> str:
        return (f"{type(self).__name__}(length={self.length:.4g} m, speed={self.speed:g} m/s, "
                f"law={self.law.name}, duration={self.duration:.4g} s)")


class _Geodesic:
    """Orientation ``R(λ) = R₀ exp(λ w)``; angular velocity per unit λ in base axes ``R₀ w``."""

    def __init__(self, R0: np.ndarray, w: np.ndarray) -> None:
        self.R0 = R0
        self.w = w
        self.w_base = R0 @ w
        self.angle = float(np.linalg.norm(w))

    def at(self, lam: float) -> np.ndarray:
        if self.angle == 0.0:
            return self.R0
        return self.R0 @ so3_exp(lam * self.w)
