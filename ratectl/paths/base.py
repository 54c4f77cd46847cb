"""The `Path` base class: a curve of tool poses over the path parameter s, with a time law.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from ..checks import positive_number
from ..errors import InputError
from ..spatial import so3_exp, so3_log
from .checks import _pose, _vec3
from .time_laws import make_time_law

__all__ = ['Path', 'MAX_STEPS']


#: Default cap on the number of steps of a loop over a path (`Path.steps`): 10⁶
#: (about 17 minutes at 1 kHz).
MAX_STEPS = 1_000_000


def _real(v, name: str) -> float:
    """``v`` as a float; text and complex numbers are refused, not converted."""
    if type(v) is float:
        return v
    try:
        if isinstance(v, str | bytes) or np.iscomplexobj(v):
            raise TypeError(name)
        return float(v)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{name} must be a number [m], got {v!r}"[:200], argument=name, value=v) from None


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
        self.speed = positive_number("speed", speed)
        self.acceleration = positive_number("acceleration", acceleration)
        self.jerk = None if jerk is None else positive_number("jerk", jerk)
        self.rotation_length = positive_number("rotation_length", rotation_length)
        if law is None:
            law = "trapezoidal" if jerk is None else "jerk-limited"
        if not (math.isfinite(length) and length < 1e100):
            raise InputError(f"{type(self).__name__}: the path is {length:.3g} m long; a path must be "
                             "shorter than 1e100 m (its poses are too far apart for floating point)",
                             argument="length", value=length)
        self.length = float(length)
        self.law = make_time_law(law, self.length, speed=self.speed, acceleration=self.acceleration,
                                 jerk=self.jerk)

    # -- geometry -------------------------------------------------------------
    def _geometry(self, s: float):  # pragma: no cover - abstract
        raise NotImplementedError

    def _clamp(self, s, name: str = "s") -> float:
        """``s`` as a float clamped to [0, length]; text, complex, NaN or inf raise."""
        v = _real(s, name)
        if not math.isfinite(v):
            raise InputError(f"path parameter {name} must be a finite number [m], got {s!r}",
                             argument=name, value=s)
        return min(max(v, 0.0), self.length)

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

    def twist_at(self, s: ArrayLike, *, sd: float = 1.0, side: str = "after") -> np.ndarray:
        """Tool twist ``[dp/ds; ω_s]·ṡ`` (6,) at ``s`` for progress rate ``ṡ = sd`` [m/s]
        (with the default sd = 1 it is the path tangent dP/ds). At a corner (`corners`) the
        tangent has two values: ``side="after"`` (default) gives the outgoing one,
        ``side="before"`` the incoming one (the limit from below); elsewhere both agree."""
        if side not in ("after", "before"):
            raise InputError(f"side must be 'after' or 'before', got {side!r}", argument="side", value=side)
        s = self._clamp(s)
        _, _, dp, w = self._geometry_before(s) if side == "before" else self._geometry(s)
        return np.concatenate([dp, w]) * float(sd)

    def _geometry_before(self, s: float):
        """`_geometry` with the incoming tangent at a corner (the limit from below)."""
        return self._geometry(s)

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
        dt = positive_number("dt", dt)
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
        dt = positive_number("dt", dt)
        n = self.steps(dt, max_steps=max_steps)
        t = np.minimum(np.arange(n) * dt, self.duration)
        return t, np.array([self.pose(x) for x in t]), np.array([self.twist(x) for x in t])

    # -- distance -------------------------------------------------------------
    @property
    def corners(self) -> np.ndarray:
        """Path parameters [m] of the corners: inner points where the tangent dP/ds jumps
        (sharp corners of `Waypoints` with ``blend=0``). A motion that stays on the path
        must come to rest at each of them (the joint velocity q′ṡ would jump otherwise);
        the governor plans ṡ = 0 there. Empty for smooth paths."""
        return np.zeros(0)

    def _search_grid(self) -> np.ndarray:
        """Samples of s for the global nearest-point search (101 over the path)."""
        return np.linspace(0.0, self.length, 101)

    def _pose_terms(self, s: float, x: np.ndarray, Rx: np.ndarray | None) -> tuple[float, ...]:
        """(f, g, h, e², θ²) at s of the squared pose distance f = e² + ρ²θ², e² = ‖p(s) − x‖²,
        θ² = ‖φ‖², φ = log(R(s)R_xᵀ) (ρ = ``rotation_length``; without ``Rx`` the position part
        only): g = ½ df/ds exactly (dp/ds·(p − x) + ρ² ω_s·φ, because J_l(φ)ᵀφ = φ) and its
        Gauss–Newton curvature h = ‖dp/ds‖² + ρ²‖ω_s‖²."""
        p, R, dp, w = self._geometry(s)
        e = p - x
        e2, g, h, a2 = float(e @ e), float(dp @ e), float(dp @ dp), 0.0
        if Rx is not None:
            phi = so3_log(R @ Rx.T)
            r2 = self.rotation_length ** 2
            a2 = float(phi @ phi)
            g += r2 * float(w @ phi)
            h += r2 * float(w @ w)
        return e2 + self.rotation_length ** 2 * a2, g, h, e2, a2

    def _descend(self, s: float, x: np.ndarray, Rx: np.ndarray | None, lo: float, hi: float,
                 step: float) -> tuple[float, float, float]:
        """Local minimum (s, e², θ²) of the squared pose distance from ``s`` within [lo, hi]:
        Gauss–Newton steps of at most ``step`` [m], halved until the distance decreases."""
        cur = self._pose_terms(s, x, Rx)
        tiny = 1e-13 * max(self.length, 1e-3)
        for _ in range(40):
            f, g, h = cur[:3]
            if g == 0.0:
                break
            ds = -g / h if h > 1e-18 else -math.copysign(step, g)  # a cusp (dP/ds = 0): probe
            ds = max(-step, min(step, ds))
            for _ in range(80):  # halving: ds reaches `tiny` long before 80 halvings
                s_new = min(max(s + ds, lo), hi)
                if abs(s_new - s) <= tiny:
                    return s, cur[3], cur[4]
                new = self._pose_terms(s_new, x, Rx)
                if new[0] <= f:
                    break
                ds *= 0.5
            else:
                return s, cur[3], cur[4]
            converged = abs(s_new - s) <= 1e-12 * max(self.length, 1e-3)
            s, cur = s_new, new
            if converged:
                break
        return s, cur[3], cur[4]

    def _target(self, x: ArrayLike) -> tuple[np.ndarray, np.ndarray | None]:
        """(position, rotation or None) of a point (3,) or a pose (4, 4), both finite (a pose
        rigid)."""
        try:
            shape = np.shape(x)
        except (TypeError, ValueError):  # a ragged sequence
            shape = None
        if shape == (4, 4):
            a = _pose(x, "point")
            return a[:3, 3], a[:3, :3]
        if shape == (3,):
            return _vec3(x, "point"), None
        raise InputError(f"expected a point (3,) or a rigid pose (4, 4), got {x!r}"[:200],
                         argument="point", value=x)

    def _start_estimate(self, x: np.ndarray, Rx: np.ndarray | None) -> tuple[float, float] | None:
        """A closed-form (s, step) to start the global search from, or None (grid search)."""
        return None

    def closest(self, point: ArrayLike, *, s_hint: float | None = None, window: float | None = None) -> float:
        """Path parameter s [m] of the point of the path nearest to ``point``.

        ``point`` is a pose (4×4) or a position (3,). For a pose the distance is the
        path's own metric, d² = ‖p(s) − p‖² + ρ²θ², θ the angle between R(s) and R and
        ρ = ``rotation_length`` [m/rad] (the metric in which s is measured): a pure rotation,
        or a path that passes the same position twice with different orientations, has a
        well-defined nearest point. For a position (3,) only ‖p(s) − p‖ counts.

        Without ``s_hint``: the best of a grid of samples (101, plus the knots of a
        `Waypoints`), refined by Gauss–Newton steps — the global nearest point (the first
        one where the path revisits a pose); a `Waypoints` path is searched segment by
        segment and blend by blend. With ``s_hint`` (in [0, length], clamped): the local
        minimum reached from it, within ``s_hint ± window`` (``window`` > 0 [m], default:
        the whole path) — the search to use along a motion, from the commanded s, where a
        path revisits a pose or turns back on itself. A point or pose with NaN or infinite
        entries, a non-rigid pose, a NaN ``s_hint`` or a ``window`` ≤ 0 raise `InputError`.
        """
        return self._nearest(point, s_hint, window)[0]

    def _nearest(self, point: ArrayLike, s_hint: float | None, window: float | None):
        """(s, e², θ²) of the nearest point (see `closest`)."""
        x, Rx = self._target(point)
        L = self.length
        if window is not None:
            window = positive_number("window", window, allow_inf=True, unit="[m]")
        if s_hint is not None:
            s_hint = self._clamp(s_hint, "s_hint")
        if L <= 0.0:
            return self._descend(0.0, x, Rx, 0.0, 0.0, 1e-9)
        if s_hint is not None:
            s = s_hint
            w = L if window is None else min(window, L)
            lo, hi = max(0.0, s - w), min(L, s + w)
            return self._descend(s, x, Rx, lo, hi, max(min(w, L / 20.0), 1e-9))
        return self._global_nearest(x, Rx)

    def _global_nearest(self, x: np.ndarray, Rx: np.ndarray | None) -> tuple[float, float, float]:
        """(s, e², θ²) of the global nearest point without a hint: a closed-form start
        (`_start_estimate`) or the best of a grid of samples, refined by `_descend`."""
        L = self.length
        start = self._start_estimate(x, Rx)
        if start is not None:
            return self._descend(start[0], x, Rx, 0.0, L, start[1])
        grid = self._search_grid()
        f = [self._pose_terms(float(g), x, Rx)[0] for g in grid]
        k = int(np.argmin(f))
        lo, hi = float(grid[max(k - 1, 0)]), float(grid[min(k + 1, len(grid) - 1)])
        return self._descend(float(grid[k]), x, Rx, lo, hi, max(hi - lo, 1e-9))

    def distance(self, T: ArrayLike, *, s_hint: float | None = None, window: float | None = None):
        """Distance of the pose ``T`` (4×4) from the path: ``(position [m], orientation [rad], s)``
        at the nearest point s of the path in the pose metric of `closest` (searched near
        ``s_hint`` when given); the orientation error is the angle between R and R(s).
        ``T`` must be a rigid transform (`InputError` otherwise, NaN included)."""
        T = _pose(T, "T")
        s, e2, a2 = self._nearest(T, s_hint, window)
        return math.sqrt(e2), math.sqrt(a2), s

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
