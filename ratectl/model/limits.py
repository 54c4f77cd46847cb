"""Joint limits and how fast a joint may move toward a position limit.

`Limits` is the four per-joint arrays every limit-aware computation needs
(``lower``, ``upper`` [rad or m], ``vmax``, ``amax`` magnitudes; ±inf where absent). A
`Chain` carries the same arrays (plus ``jmax``) and is accepted wherever
limits are.

Braking toward a position limit at distance d has one home here, in the two motion
models the package uses:

* acceleration-limited, in steps of dt (the QP's and the unsmoothed controller's bound):
  `braking_speed_any_dt`, the largest speed that, held for this period, still leaves
  room to brake at amax whatever the later periods are (dt may change every cycle), and
  `braking_speed_discrete`, the exact discrete form of √(2·amax·d) for a dt that never
  changes (the approach to a target plans with it);
* jerk-limited, continuous (what Ruckig's time-optimal stop does, for smoothed control):
  `stopping_distance` and its inverse `braking_speed`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..arrays import read_only
from ..errors import InputError

__all__ = ["Limits", "braking_speed_any_dt", "speed_toward_limit", "braking_speed_discrete",
           "stopping_distance", "braking_speed", "braking_speed_slope"]


@dataclass(frozen=True, slots=True)
class Limits:
    """Joint limits in SI units; ±inf where absent. Shapes (n,).

    Attributes:
        lower: lower position limits [rad or m].
        upper: upper position limits [rad or m].
        vmax: velocity limits (magnitudes) [rad/s or m/s].
        amax: acceleration limits (magnitudes) [rad/s² or m/s²].
    """

    lower: np.ndarray
    upper: np.ndarray
    vmax: np.ndarray
    amax: np.ndarray

    def __post_init__(self) -> None:
        for name in ("lower", "upper", "vmax", "amax"):
            try:
                if np.iscomplexobj(getattr(self, name)):
                    raise TypeError("complex")
                a = read_only(getattr(self, name))
            except (TypeError, ValueError):
                raise InputError(f"Limits.{name} must be an array of numbers, got "
                                 f"{getattr(self, name)!r}", argument=name,
                                 value=getattr(self, name)) from None
            if a.ndim != 1:
                raise InputError(f"Limits.{name} must be a 1-D array (one value per joint), got "
                                 f"shape {a.shape}", argument=name, value=a)
            object.__setattr__(self, name, a)
        if not (self.lower.shape == self.upper.shape == self.vmax.shape == self.amax.shape):
            raise InputError("Limits.lower, upper, vmax and amax must have the same length",
                             argument="limits", value=self)
        _validate(self.lower, self.upper, self.vmax, self.amax, "Limits")

    @classmethod
    def of(cls, obj: Any, n: int) -> Limits:
        """Limits from a Chain, a Limits, any object with those four arrays, or None
        (unlimited)."""
        if obj is None:
            inf = np.full(n, math.inf)
            return cls(-inf, inf, inf, inf)
        if type(obj) is cls and obj.lower.shape == (n,):
            return obj
        try:
            arrs = [np.asarray(getattr(obj, k), dtype=float) for k in ("lower", "upper", "vmax", "amax")]
        except AttributeError:
            raise InputError("limits must have arrays lower, upper, vmax, amax (a Chain or "
                             f"ratectl.solvers.Limits), got {type(obj).__name__}",
                             argument="limits", value=obj) from None
        for name, a in zip(("lower", "upper", "vmax", "amax"), arrs, strict=True):
            if a.shape != (n,):
                raise InputError(f"limits.{name} must have one value per joint ({n}), got shape "
                                 f"{a.shape}", argument="limits", value=obj)
        return cls(*arrs)


def _validate(lower, upper, vmax, amax, what) -> None:
    """Refuse limits no motion can respect: NaN anywhere, vmax or amax not > 0, lower > upper,
    lower = +inf or upper = −inf."""
    for name, a in (("lower", lower), ("upper", upper), ("vmax", vmax), ("amax", amax)):
        bad = np.flatnonzero(np.isnan(a))
        if bad.size:
            raise InputError(f"{what}.{name} is NaN at joint {int(bad[0])}; use ±inf for an absent "
                             "limit", argument=name, value=a)
    for name, a in (("vmax", vmax), ("amax", amax)):
        bad = np.flatnonzero(~(a > 0))
        if bad.size:
            j = int(bad[0])
            raise InputError(f"{what}.{name}[{j}] = {a[j]!r}: velocity and acceleration limits must be "
                             "positive magnitudes (inf where absent)", argument=name, value=a)
    bad = np.flatnonzero(~(lower <= upper) | (lower == math.inf) | (upper == -math.inf))
    if bad.size:
        j = int(bad[0])
        raise InputError(f"{what}: joint {j} has lower = {lower[j]!r} and upper = {upper[j]!r}; "
                         "lower must not exceed upper, and neither may be infinite on the wrong "
                         "side", argument="lower", value=(lower, upper))


def braking_speed_any_dt(D: np.ndarray | float, dt: Any, two_over_a: Any):
    """Largest speed v [rad/s or m/s] toward a limit at distance D [rad or m] that may be
    commanded for the coming period dt [s] so that the joint can still stop before the
    limit with |Δq̇| ≤ a·dt' in every later period, **whatever the later periods dt' are**
    (``two_over_a`` = 2/a, precomputed by the caller; a huge a stands for no acceleration
    limit, and then v = D/dt):

        v·dt + v²/(2a) ≤ D   ⇔   v ≤ −a·dt + √((a·dt)² + 2a·D) = 2D / (dt + √(dt² + 2D/a))

    (the second form has no cancellation and no overflow for a huge a). For D < 0 (beyond
    the limit) it returns D/dt (move back; callers decide how fast).

    Why any dt: a joint that leaves a period at speed v with room R ≥ v²/(2a) brakes in
    later periods dt₁, dt₂, … at v − a·t₁, v − a·t₂, … (t_k = dt₁ + … + dt_k, until 0),
    and covers Σ max(v − a·t_k, 0)·dt_k, a right Riemann sum of the decreasing v − a·t, so
    at most ∫ = v²/(2a) ≤ R: it stops in time. And the bound is consistent with the
    acceleration limit for every next period dt': from v ≤ v_max(D, dt) the joint is at
    D' = D − v·dt ≥ v²/(2a), and u = v − a·dt' satisfies u·dt' + u²/(2a) = v²/(2a) − a·dt'²/2
    ≤ D', so the next bound is ≥ v − a·dt': "within the braking bound" and "within a·dt'
    of the previous q̇" always meet, unless a fault (a measured q that jumped, a state not
    produced by this bound) put the joint inside its stopping distance.

    Compared with `braking_speed_discrete` for a constant dt the speed is lower by about
    a·dt/2 far from the limit (√(2aD) − a·dt instead of √(2aD) − a·dt/2); both tend to D/dt
    as D → 0.
    """
    Dp = np.maximum(D, 0.0)
    return 2.0 * Dp / (dt + np.sqrt(dt * dt + Dp * two_over_a)) + np.minimum(D, 0.0) / dt


def braking_speed_any_dt_scalar(D: float, dt: float, two_over_a: float) -> float:
    """`braking_speed_any_dt` of one joint in plain arithmetic (a per-cycle caller on a
    handful of joints, where numpy's per-call cost dominates): the same formula."""
    if D > 0.0:
        return 2.0 * D / (dt + math.sqrt(dt * dt + D * two_over_a))
    return D / dt


def speed_toward_limit(D: np.ndarray, v_prev: np.ndarray | None, *, dt: float, two_over_a: Any,
                       adt: Any, vmax: Any) -> np.ndarray:
    """The position side of a joint's velocity box: the largest velocity toward a limit
    (positive toward it) [rad/s or m/s] at signed room D [rad or m] (D < 0: beyond it),
    given the previous command's velocity toward it ``v_prev`` (None: unknown), the period
    dt [s], ``two_over_a`` = 2/a, ``adt`` = a·dt and the velocity limit ``vmax``:

    * inside the range (D ≥ 0): `braking_speed_any_dt`, which stops the joint at the
      limit at the latest. When the acceleration window [v_prev − a·dt, v_prev + a·dt]
      lies wholly above it (only after a fault: a measured q that jumped into the
      stopping distance), **the position side wins**: the joint brakes harder than amax
      for that period (callers report it; the next period is consistent again, because
      the bound leaves room v²/(2a) to brake at amax);
    * beyond the limit (D < 0): back into the range, no faster than vmax, no harder than
      a·dt from ``v_prev`` and no farther than to the limit in one period, and **never
      further out**: min(0, max(D/dt, −vmax, v_prev − a·dt)). A joint still moving out
      faster than a·dt gets 0 (again harder than amax, reported by the caller).
    """
    b = braking_speed_any_dt(D, dt, two_over_a)
    if not (np.asarray(D) < 0.0).any():
        return b
    back = np.maximum(b, -vmax)
    if v_prev is not None:
        back = np.maximum(back, v_prev - adt)
    return np.where(D >= 0.0, b, np.minimum(back, 0.0))


def braking_speed_discrete(D: np.ndarray | float, adt: Any, inv_adt2: Any, inv_dt: Any):
    """Largest speed toward a limit at distance D (≥ 0) [rad or m] from which the joint
    can still stop before it, braking by at most a·dt per step of dt (arguments: D, a·dt,
    1/(a·dt²), 1/dt — precomputed by the caller, this runs every control cycle):

    the braking sequence v, v − a·dt, v − 2a·dt, … (down to 0) covers
    D(v) = a·dt²·((k + 1)·f + k(k + 1)/2) for v = (k + f)·a·dt (k integer, 0 ≤ f < 1);
    this inverts it exactly: u = D/(a·dt²), k = ⌊(√(8u + 1) − 1)/2⌋,
    f = min((u − k(k + 1)/2)/(k + 1), 1), v = (k + f)·a·dt. It is the discrete form of
    √(2a·D) and includes D/dt (k = 0: stop exactly at the limit within this step), and it
    is consistent with the acceleration bound: from v the next step's bound is ≥ v − a·dt.
    For D < 0 (beyond the limit) it returns D/dt (move back).

    Only for a dt that never changes: after a period of dt the next period's bound with a
    shorter dt' can lie below v − a·dt' (braking harder than amax); limits use
    `braking_speed_any_dt`.
    """
    Dp = np.maximum(D, 0.0)
    u = Dp * inv_adt2
    k = np.floor(0.5 * (np.sqrt(8.0 * u + 1.0) - 1.0))
    f = np.minimum((u - 0.5 * k * (k + 1.0)) / (k + 1.0), 1.0)
    return (k + f) * adt + np.minimum(D, 0.0) * inv_dt


def stopping_distance(v: np.ndarray | float, a: np.ndarray | float, amax: np.ndarray | float,
                      jmax: np.ndarray | float, *, exact_when_braking: bool = False) -> np.ndarray:
    """Distance a joint travels while a time-optimal jerk-limited stop brings it from
    velocity ``v`` ≥ 0 and acceleration ``a`` to rest (|q̈| ≤ amax, |q⃛| ≤ jmax); arrays
    broadcast. Units: rad (or m) for rad/s, rad/s², rad/s³.

    From rest acceleration (a = 0) the stop is a symmetric S-curve, so D = v·T/2:

        D₀(v) = v^{3/2}/√J                    for v ≤ A²/J (peak deceleration √(Jv) < A),
        D₀(v) = v²/(2A) + v·A/(2J)            otherwise (deceleration held at A).

    With a > 0 (still speeding up) the jerk first brings a to 0 in a/J, adding
    v·a/J + a³/(3J²) of travel and a²/(2J) of speed: D = v·a/J + a³/(3J²) + D₀(v + a²/(2J)).
    A negative a (already braking) is counted as 0, which over-estimates D (safe side);
    with ``exact_when_braking=True`` it is the exact distance of that stop too
    (`_braking_stop_distance`).
    """
    v = np.maximum(np.asarray(v, dtype=float), 0.0)
    a_in = np.asarray(a, dtype=float)
    a = np.maximum(a_in, 0.0)
    A = np.asarray(amax, dtype=float)
    J = np.asarray(jmax, dtype=float)
    if exact_when_braking and np.any(a_in < 0.0):
        return np.where(a_in < 0.0, _braking_stop_distance(v, np.minimum(a_in, 0.0), A, J),
                        stopping_distance(v, a, A, J))
    lead = v * a / J + a**3 / (3.0 * J * J)
    w = v + a * a / (2.0 * J)
    d0 = np.where(w <= A * A / J, w * np.sqrt(w / J), w * w / (2.0 * A) + w * A / (2.0 * J))
    return lead + d0


def _braking_stop_distance(v, a0, A, J):
    """The exact distance of the time-optimal jerk-limited stop (to v = 0, q̈ = 0) from
    v ≥ 0 while already braking, a0 ≤ 0 (|a0| ≤ A):

    * v ≤ a0²/(2J): even releasing the brake at once (jerk +J) reaches v = 0 before q̈ = 0;
      the forward travel ends at the first root t* = (|a0| − √(a0² − 2Jv))/J of
      v + a0·t + J·t²/2, D = v·t* + a0·t*²/2 + J·t*³/6;
    * otherwise the deceleration first grows (jerk −J) to a peak a_p, a_p² = J·v + a0²/2,
      then returns to 0 (jerk +J); if a_p² > A² it is held at −A in between (until the
      speed is A²/(2J)), and the last ramp travels A³/(6J²).
    """
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        disc = np.maximum(a0 * a0 - 2.0 * J * v, 0.0)
        ts = (-a0 - np.sqrt(disc)) / J
        d_release = v * ts + 0.5 * a0 * ts * ts + J * ts**3 / 6.0
        ap = np.minimum(np.sqrt(J * v + 0.5 * a0 * a0), A)  # |peak deceleration|
        t1 = np.maximum(ap + a0, 0.0) / J  # a0 → −ap
        d1 = v * t1 + 0.5 * a0 * t1 * t1 - J * t1**3 / 6.0
        v1 = v + a0 * t1 - 0.5 * J * t1 * t1
        vr = 0.5 * ap * ap / J  # the speed the last ramp (−ap → 0) removes
        th = np.maximum(v1 - vr, 0.0) / ap  # hold at −A (0 unless ap = A)
        dh = v1 * th - 0.5 * ap * th * th
        t3 = ap / J
        d3 = vr * t3 - 0.5 * ap * t3 * t3 + J * t3**3 / 6.0
    return np.where(v <= 0.5 * a0 * a0 / J, d_release, d1 + dh + d3)


def stopping_distance_scalar(v: float, a: float, amax: float, jmax: float, *,
                             exact_when_braking: bool = False) -> float:
    """`stopping_distance` of one joint in plain arithmetic: the same formulas on floats, in
    the same order (the same number to the last bit), for amax, jmax > 0; without the
    arrays' cost (a 1-D progress plans its stop with it every period)."""
    if not (amax > 0.0 and jmax > 0.0 and math.isfinite(amax + jmax + v + a)):  # (NaN, inf: as the arrays)
        return float(stopping_distance(v, a, amax, jmax, exact_when_braking=exact_when_braking))
    v = v if v > 0.0 else 0.0
    A, J = amax, jmax
    if exact_when_braking and a < 0.0:
        a0 = a
        if v <= 0.5 * a0 * a0 / J:  # the brake released at once reaches v = 0 first
            disc = a0 * a0 - 2.0 * J * v
            ts = (-a0 - math.sqrt(disc if disc > 0.0 else 0.0)) / J
            return v * ts + 0.5 * a0 * ts * ts + J * ts**3 / 6.0
        ap = min(math.sqrt(J * v + 0.5 * a0 * a0), A)
        x = ap + a0
        t1 = (x if x > 0.0 else 0.0) / J
        d1 = v * t1 + 0.5 * a0 * t1 * t1 - J * t1**3 / 6.0
        v1 = v + a0 * t1 - 0.5 * J * t1 * t1
        vr = 0.5 * ap * ap / J
        x = v1 - vr
        th = (x if x > 0.0 else 0.0) / ap
        dh = v1 * th - 0.5 * ap * th * th
        t3 = ap / J
        d3 = vr * t3 - 0.5 * ap * t3 * t3 + J * t3**3 / 6.0
        return d1 + dh + d3
    a = a if a > 0.0 else 0.0
    lead = v * a / J + a**3 / (3.0 * J * J)
    w = v + a * a / (2.0 * J)
    d0 = w * math.sqrt(w / J) if w <= A * A / J else w * w / (2.0 * A) + w * A / (2.0 * J)
    return lead + d0


def braking_speed(d: np.ndarray | float, amax: np.ndarray | float, jmax: np.ndarray | float) -> np.ndarray:
    """The largest speed from which a joint at zero acceleration can still stop within
    the distance ``d`` ≥ 0 under |q̈| ≤ amax, |q⃛| ≤ jmax: the inverse of
    `stopping_distance` at a = 0,

        v = (d·√J)^{2/3}                                   for d ≤ A³/J²,
        v = (−A²/J + √(A⁴/J² + 8·A·d))/2                   otherwise.
    """
    d = np.maximum(np.asarray(d, dtype=float), 0.0)
    A = np.asarray(amax, dtype=float)
    J = np.asarray(jmax, dtype=float)
    k = A * A / J
    return np.where(d <= A**3 / (J * J), np.cbrt(d * d * J), 0.5 * (-k + np.sqrt(k * k + 8.0 * A * d)))


def braking_speed_scalar(d: float, amax: float, jmax: float) -> float:
    """`braking_speed` of one joint in plain arithmetic: the same formula, for one
    float d ≥ 0 (negative d counts as 0)."""
    d = d if d > 0.0 else 0.0
    k = amax * amax / jmax
    if d <= amax * amax * amax / (jmax * jmax):
        return (d * d * jmax) ** (1.0 / 3.0)
    return 0.5 * (-k + math.sqrt(k * k + 8.0 * amax * d))


def braking_speed_slope(d: np.ndarray | float, amax: np.ndarray | float,
                        jmax: np.ndarray | float) -> np.ndarray:
    """The derivative db/dd [1/s] of `braking_speed` b(d): a joint braking along that
    curve toward a point at distance d decelerates at b'(d)·b(d), so a command that
    follows the curve has acceleration −b'(d)·b(d) (≤ amax, jerk-limited near d = 0):

        b' = (2/3)·b/d                   for d ≤ A³/J²,
        b' = 2A/√(A⁴/J² + 8·A·d)         otherwise.
    """
    d = np.maximum(np.asarray(d, dtype=float), 1e-300)
    A = np.asarray(amax, dtype=float)
    J = np.asarray(jmax, dtype=float)
    k = A * A / J
    return np.where(d <= A**3 / (J * J), (2.0 / 3.0) * braking_speed(d, A, J) / d,
                    2.0 * A / np.sqrt(k * k + 8.0 * A * d))
