"""Time laws s(t): trapezoidal, jerk-limited (Ruckig) and quintic, at rest at both ends.
"""

from __future__ import annotations

import math

from ..checks import positive_number
from ..errors import InputError
from ..model.jerk_profile import PiecewiseJerk

__all__ = ['TimeLaw', 'Trapezoidal', 'JerkLimited', 'Quintic', 'make_time_law', 'LAWS']


LAWS = ("trapezoidal", "jerk-limited", "quintic")


# ---------------------------------------------------------------------- time laws
class TimeLaw:
    """Maps time to progress: ``s(t), ṡ(t), s̈(t)`` on ``[0, duration]``, at rest at both ends.

    Attributes:
        length: path length L [m].
        duration: T [s].
        max_jerk: the largest |s⃛| of the law [m/s³]: inf for the trapezoid (its s̈ jumps),
            the jerk limit of the jerk-limited law, 60L/T³ for the quintic (at both ends).
    """

    name = "base"
    length: float
    duration: float
    max_jerk: float = math.inf

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
        v, a = positive_number("speed", speed), positive_number("acceleration", acceleration)
        L = self.length
        if L <= 0.0:
            self.vpeak, self.ta, self.duration, self.a = 0.0, 0.0, 0.0, a
            return
        vp = min(v, math.sqrt(a * L))
        if not vp > 0.0:  # a·L underflows (a denormal acceleration): the motion never starts
            raise InputError(f"speed {v!r} and acceleration {a!r} cannot move {L:.3g} m in finite "
                             "time (√(acceleration·length) underflows to 0)", argument="acceleration",
                             value=acceleration)
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
        v, a = positive_number("speed", speed), positive_number("acceleration", acceleration)
        L = self.length
        T = max(15.0 * L / (8.0 * v), math.sqrt(10.0 * L / (math.sqrt(3.0) * a))) if L > 0 else 0.0
        self.duration = T
        self.max_jerk = 60.0 * L / T / T / T if T > 0 else 0.0  # (no ** : it raises on overflow)

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
    computed once).

    The law keeps only the numbers of Ruckig's profile (`ratectl.model.jerk_profile`):
    no Ruckig object outlives the constructor."""

    name = "jerk-limited"

    def __init__(self, length: float, *, speed: float, acceleration: float, jerk: float) -> None:
        import ruckig

        self.length = float(length)
        v, a = positive_number("speed", speed), positive_number("acceleration", acceleration)
        j = positive_number("jerk", jerk)
        self.jerk = self.max_jerk = j
        if self.length <= 0.0:
            self.duration = 0.0
            self._profile: PiecewiseJerk | None = None
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
        self._profile = PiecewiseJerk(traj)  # nothing of Ruckig is kept
        self.duration = self._profile.duration

    def _eval(self, t):
        assert self._profile is not None  # (length 0 never reaches here: duration 0)
        p, v, a = self._profile.at(t)
        return p[0], v[0], a[0]


def make_time_law(law: str, length: float, *, speed: float, acceleration: float,
                  jerk: float | None = None) -> TimeLaw:
    """A time law by name (one of `LAWS`); ``jerk`` belongs to the jerk-limited law only (a
    trapezoid or a quintic has no jerk setting, so a jerk given with them is refused rather
    than ignored)."""
    if jerk is not None and law in ("trapezoidal", "quintic"):
        raise InputError(f"jerk= is a setting of law='jerk-limited' only; law={law!r} has none "
                         "(drop jerk, or drop law: a jerk alone selects the jerk-limited law)",
                         argument="jerk", value=jerk)
    if law == "trapezoidal":
        return Trapezoidal(length, speed=speed, acceleration=acceleration)
    if law == "quintic":
        return Quintic(length, speed=speed, acceleration=acceleration)
    if law == "jerk-limited":
        if jerk is None:
            raise InputError("law='jerk-limited' needs jerk= [m/s³]", argument="jerk", value=jerk)
        return JerkLimited(length, speed=speed, acceleration=acceleration, jerk=jerk)
    raise InputError(f"law must be one of {LAWS}, got {law!r}", argument="law", value=law)
