"""Cartesian tool paths and their time laws.

A path is a curve of tool poses ``P(s) = (p(s), R(s))`` over a path parameter
``s ∈ [0, length]`` [m], plus a *time law* ``s(t)`` built from Cartesian speed,
acceleration (and jerk) limits. Every path answers four questions:

* ``pose_at(s)`` → 4×4 pose, ``twist_at(s, sd=1)`` → ``[dp/ds; ω/ṡ]·ṡ`` (6,),
* ``pose(t)`` → 4×4 pose at time t, ``twist(t)`` → the tool twist ``[v; ω]`` at time t.

Positions move on the curve (a segment, a circular arc, blended segments); the
orientation moves on the SO(3) geodesic ``R(λ) = R₀ exp(λ w)`` (λ ∈ [0, 1] the
fraction of the segment), so the angular velocity in base axes is
``ω = R₀ w dλ/dt``.

The path parameter is the combined length ``s`` with ``ds² = dp² + (ρ dθ)²``,
ρ = ``rotation_length`` [m/rad] (default 0.1 m): on a path at constant
orientation ``s`` is the arc length of the tool origin, and a pure rotation still
has a positive length (so "speed" limits the angular rate to speed/ρ).

Time laws (``law=``):

* ``"trapezoidal"`` — constant acceleration a, cruise at v, constant deceleration;
  triangular when the path is shorter than v²/a.
* ``"jerk-limited"`` — the same with a jerk limit (a 1-D state-to-state Ruckig
  trajectory from rest at 0 to rest at ``length``).
* ``"quintic"`` — ``s = L(10τ³ − 15τ⁴ + 6τ⁵)``, τ = t/T, with T the shortest time for
  which the peak speed 15L/(8T) ≤ v and peak acceleration 10L/(√3 T²) ≤ a.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import InputError
from .spatial import so3_exp, so3_log

__all__ = [
    "TimeLaw", "Trapezoidal", "JerkLimited", "Quintic", "make_time_law",
    "Path", "Line", "Arc", "Waypoints", "LAWS",
]

LAWS = ("trapezoidal", "jerk-limited", "quintic")


def _positive(value, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a positive number, got {value!r}", argument=name,
                         value=value) from None
    if not (v > 0.0 and math.isfinite(v)):
        raise InputError(f"{name} must be a positive finite number, got {value!r}", argument=name,
                         value=value)
    return v


def _pose(T, name: str) -> np.ndarray:
    A = np.asarray(T, dtype=float)
    if A.shape != (4, 4) or not np.all(np.isfinite(A)):
        raise InputError(f"{name} must be a finite 4x4 homogeneous transform, got shape {A.shape}",
                         argument=name, value=T)
    R = A[:3, :3]
    if np.max(np.abs(R @ R.T - np.eye(3))) > 1e-6 or np.linalg.det(R) < 0:
        raise InputError(f"{name} must be a rigid transform (orthonormal rotation, det +1)",
                         argument=name, value=T)
    return A.copy()


def _vec3(v, name: str) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise InputError(f"{name} must be a finite 3-vector, got {v!r}", argument=name, value=v)
    return a


# ---------------------------------------------------------------------- time laws
class TimeLaw:
    """Maps time to progress: ``s(t), ṡ(t), s̈(t)`` on ``[0, duration]``, at rest at both ends.

    Attributes:
        length: path length L [m]; duration: T [s].
    """

    name = "base"
    length: float
    duration: float

    def __call__(self, t: float) -> tuple[float, float, float]:
        """``(s, ṡ, s̈)`` at time ``t`` [s]; clamped to the ends outside [0, T]."""
        if t <= 0.0:
            return 0.0, 0.0, 0.0
        if t >= self.duration:
            return self.length, 0.0, 0.0
        return self._eval(t)

    def _eval(self, t: float) -> tuple[float, float, float]:  # pragma: no cover - abstract
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}(length={self.length:.4g} m, duration={self.duration:.4g} s)"


class Trapezoidal(TimeLaw):
    """Trapezoidal speed profile: accelerate at ``acceleration`` to ``speed``, cruise, decelerate.

    If ``L < v²/a`` the profile is triangular with peak speed √(aL).
    """

    name = "trapezoidal"

    def __init__(self, length: float, *, speed: float, acceleration: float) -> None:
        self.length = float(length)
        v, a = _positive(speed, "speed"), _positive(acceleration, "acceleration")
        L = self.length
        if L <= 0.0:
            self.vpeak, self.ta, self.duration, self.a = 0.0, 0.0, 0.0, a
            return
        vp = min(v, math.sqrt(a * L))
        ta = vp / a
        self.vpeak, self.ta, self.a = vp, ta, a
        self.duration = 2.0 * ta + (L - vp * ta) / vp

    def _eval(self, t):
        a, ta, vp, T = self.a, self.ta, self.vpeak, self.duration
        if t < ta:
            return 0.5 * a * t * t, a * t, a
        if t <= T - ta:
            return 0.5 * a * ta * ta + vp * (t - ta), vp, 0.0
        r = T - t
        return self.length - 0.5 * a * r * r, a * r, -a


class Quintic(TimeLaw):
    """Quintic polynomial ``s = L(10τ³ − 15τ⁴ + 6τ⁵)``, τ = t/T (zero speed and acceleration at
    both ends); T = max(15L/(8v), √(10L/(√3 a)))."""

    name = "quintic"

    def __init__(self, length: float, *, speed: float, acceleration: float) -> None:
        self.length = float(length)
        v, a = _positive(speed, "speed"), _positive(acceleration, "acceleration")
        L = self.length
        T = max(15.0 * L / (8.0 * v), math.sqrt(10.0 * L / (math.sqrt(3.0) * a))) if L > 0 else 0.0
        self.duration = T

    def _eval(self, t):
        T, L = self.duration, self.length
        u = t / T
        s = L * u**3 * (10 - 15 * u + 6 * u * u)
        sd = L * 30 * u * u * (1 - u) ** 2 / T
        sdd = L * 60 * u * (1 - u) * (1 - 2 * u) / (T * T)
        return s, sd, sdd


class JerkLimited(TimeLaw):
    """Jerk-limited trapezoid: the time-optimal rest-to-rest motion over ``length`` with
    |ṡ| ≤ speed, |s̈| ≤ acceleration, |s⃛| ≤ jerk (a 1-D state-to-state Ruckig trajectory,
    computed once)."""

    name = "jerk-limited"

    def __init__(self, length: float, *, speed: float, acceleration: float, jerk: float) -> None:
        import ruckig

        self.length = float(length)
        v, a, j = _positive(speed, "speed"), _positive(acceleration, "acceleration"), _positive(jerk, "jerk")
        self.jerk = j
        if self.length <= 0.0:
            self.duration = 0.0
            self._traj = None
            return
        inp = ruckig.InputParameter(1)
        inp.current_position, inp.current_velocity, inp.current_acceleration = [0.0], [0.0], [0.0]
        inp.target_position, inp.target_velocity, inp.target_acceleration = [self.length], [0.0], [0.0]
        inp.max_velocity, inp.max_acceleration, inp.max_jerk = [v], [a], [j]
        traj = ruckig.Trajectory(1)
        res = ruckig.Ruckig(1).calculate(inp, traj)
        if res not in (ruckig.Result.Working, ruckig.Result.Finished):  # pragma: no cover
            raise InputError(f"cannot build a jerk-limited time law: Ruckig returned {res}",
                             argument="jerk", value=jerk)
        self._traj = traj
        self.duration = float(traj.duration)

    def _eval(self, t):
        p, v, a = self._traj.at_time(t)[:3]
        return float(p[0]), float(v[0]), float(a[0])


def make_time_law(law: str, length: float, *, speed: float, acceleration: float,
                  jerk: float | None = None) -> TimeLaw:
    """A time law by name (one of :data:`LAWS`)."""
    if law == "trapezoidal":
        return Trapezoidal(length, speed=speed, acceleration=acceleration)
    if law == "quintic":
        return Quintic(length, speed=speed, acceleration=acceleration)
    if law == "jerk-limited":
        if jerk is None:
            raise InputError("law='jerk-limited' needs jerk= [m/s³]", argument="jerk", value=jerk)
        return JerkLimited(length, speed=speed, acceleration=acceleration, jerk=jerk)
    raise InputError(f"law must be one of {LAWS}, got {law!r}", argument="law", value=law)


# ---------------------------------------------------------------------- paths
class Path:
    """Base class of Cartesian paths (see the module docstring).

    Subclasses implement ``_geometry(s) -> (p, R, dp/ds, ω/ṡ)``. Common keyword
    options: ``speed`` [m/s] and ``acceleration`` [m/s²] limits on ṡ and s̈, ``jerk``
    [m/s³] (enables the jerk-limited law by default), ``law`` (one of :data:`LAWS`),
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

    def position_at(self, s) -> np.ndarray:
        """Tool position p(s) [m] (3,)."""
        return self._geometry(self._clamp(s))[0]

    def pose_at(self, s) -> np.ndarray:
        """Tool pose P(s) (4×4) at path parameter ``s`` [m] (clamped to [0, length])."""
        p, R, _, _ = self._geometry(self._clamp(s))
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = p
        return T

    def twist_at(self, s, *, sd: float = 1.0) -> np.ndarray:
        """Tool twist ``[dp/ds; ω_s]·ṡ`` (6,) at ``s`` for progress rate ``ṡ = sd`` [m/s]
        (with the default sd = 1 it is the path tangent dP/ds)."""
        _, _, dp, w = self._geometry(self._clamp(s))
        return np.concatenate([dp, w]) * float(sd)

    def curvature_twist_at(self, s, *, h: float | None = None) -> np.ndarray:
        """Second derivative d²P/ds² as a twist-rate (6,) by central differences of
        :meth:`twist_at` (step ``h`` [m], default 1e-5·length)."""
        h = h or max(1e-5 * self.length, 1e-9)
        s = self._clamp(s)
        a, b = max(s - h, 0.0), min(s + h, self.length)
        if b <= a:
            return np.zeros(6)
        return (self.twist_at(b) - self.twist_at(a)) / (b - a)

    # -- time -----------------------------------------------------------------
    def progress(self, t) -> tuple[float, float, float]:
        """``(s, ṡ, s̈)`` of the nominal time law at time ``t`` [s]."""
        return self.law(float(t))

    def pose(self, t) -> np.ndarray:
        """Tool pose (4×4) at time ``t`` [s] of the nominal time law."""
        return self.pose_at(self.law(float(t))[0])

    def twist(self, t) -> np.ndarray:
        """Tool twist ``[v; ω]`` (6,) at time ``t`` [s] of the nominal time law."""
        s, sd, _ = self.law(float(t))
        return self.twist_at(s, sd=sd)

    def sample(self, dt: float):
        """Times, poses and twists of the nominal law every ``dt`` [s]: (t, (N,4,4), (N,6))."""
        dt = _positive(dt, "dt")
        n = int(math.ceil(self.duration / dt - 1e-9)) + 1
        t = np.minimum(np.arange(n) * dt, self.duration)
        return t, np.array([self.pose(x) for x in t]), np.array([self.twist(x) for x in t])

    # -- distance -------------------------------------------------------------
    def closest(self, point, *, s_hint: float | None = None, window: float | None = None) -> float:
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

    def distance(self, T, *, s_hint: float | None = None, window: float | None = None):
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

    def __init__(self, R0, w) -> None:
        self.R0 = R0
        self.w = w
        self.w_base = R0 @ w
        self.angle = float(np.linalg.norm(w))

    def at(self, lam: float) -> np.ndarray:
        if self.angle == 0.0:
            return self.R0
        return self.R0 @ so3_exp(lam * self.w)


class Line(Path):
    """Straight line from ``T_start`` to ``T_end`` (4×4 poses); orientation on the SO(3) geodesic.

    ``p(s) = p₀ + (s/L)(p₁ − p₀)``, ``R(s) = R₀ exp((s/L) log(R₀ᵀR₁))``,
    ``L = √(‖p₁ − p₀‖² + (ρθ)²)``.

    Args:
        T_start, T_end: start and end poses.
        speed: maximum ṡ [m/s]; acceleration: maximum |s̈| [m/s²]; jerk: optional [m/s³].
        law: time law (default trapezoidal, jerk-limited if ``jerk`` is given).
        rotation_length: ρ [m/rad] (see the module docstring).
    """

    def __init__(self, T_start, T_end, *, speed: float, acceleration: float, jerk: float | None = None,
                 law: str | None = None, rotation_length: float = 0.1) -> None:
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

    def closest(self, point, *, s_hint=None, window=None) -> float:
        """Exact projection onto the segment (the orientation does not enter)."""
        L = self.length
        d2 = float(self.dp @ self.dp)
        if L == 0.0 or d2 == 0.0:
            return super().closest(point, s_hint=s_hint, window=window)
        lam = float((np.asarray(point, dtype=float) - self.p0) @ self.dp) / d2
        return min(max(lam, 0.0), 1.0) * L


class Arc(Path):
    """Circular arc of the tool origin about an axis through ``centre``.

    ``p(φ) = c + Rot(k, φ)(p₀ − c)`` for φ ∈ [0, angle] (right-handed about the unit
    axis k; the start point is the position of ``T_start``). Orientation:
    ``"fixed"`` keeps R₀; ``"rotate"`` turns the tool with the arc, R(φ) = Rot(k, φ)R₀.
    Use :meth:`through` for an arc given by three points.

    Args:
        T_start: start pose (4×4).
        centre: a point on the axis [m] (3,); axis: axis direction (3,), normalised here.
        angle: swept angle [rad] (may be negative, |angle| ≤ 2π).
        orientation: ``"fixed"`` or ``"rotate"``.
        speed, acceleration, jerk, law, rotation_length: as for :class:`Line`.
    """

    def __init__(self, T_start, *, centre, axis, angle: float, orientation: str = "fixed",
                 speed: float, acceleration: float, jerk: float | None = None, law: str | None = None,
                 rotation_length: float = 0.1, _R_end=None) -> None:
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
        r0 = p0 - c
        r0 = r0 - (r0 @ k) * k  # radial part
        self.centre = c + ((p0 - c) @ k) * k
        self.axis, self.angle, self.radial = k, angle, r0
        self.radius = float(np.linalg.norm(r0))
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
        rho = _positive(rotation_length, "rotation_length")
        L = math.hypot(self.radius * abs(angle), rho * self.rot.angle)
        self._setup(L, speed=speed, acceleration=acceleration, jerk=jerk, law=law,
                    rotation_length=rotation_length)

    @classmethod
    def through(cls, T_start, via, T_end, *, speed: float, acceleration: float, jerk: float | None = None,
                law: str | None = None, rotation_length: float = 0.1) -> Arc:
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


def _smoothstep(x: float) -> tuple[float, float]:
    """Quintic smooth step α = 10x³ − 15x⁴ + 6x⁵ and dα/dx (α', α'' vanish at 0 and 1)."""
    return x**3 * (10 - 15 * x + 6 * x * x), 30 * x * x * (1 - x) ** 2


class Waypoints(Path):
    """A sequence of poses joined by straight segments with smooth blends at the corners.

    Each segment is a :class:`Line`. Around every inner waypoint i the path blends the
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
        speed, acceleration, jerk, law, rotation_length: as for :class:`Line`.
    """

    def __init__(self, poses, *, blend: float = 0.02, speed: float, acceleration: float,
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
