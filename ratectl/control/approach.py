"""The servo's straight approach to a target.

**Approach** (`StraightApproach`): the tool moves on the straight pose interpolation from
where the approach began to the target — the position on the straight line, the orientation
on the SO(3) geodesic — parametrised by its length

    s ∈ [0, L],  L = √(‖Δp‖² + ℓ²θ²),   T(s) = (p₀ + (s/L)Δp,  exp((s/L)·r) R₀)

with Δp = p_d − p₀, r = log(R_d R₀ᵀ) (base axes, θ = ‖r‖) and ℓ a length that weighs the
rotation (the chain's characteristic length). The unit direction d = [Δp; r]/L has
‖d‖_W = 1 in the metric ⟨a, b⟩_W = a_v·b_v + ℓ² a_ω·b_ω. The progress s(t) is a
jerk-limited 1-D motion to L (Ruckig with one degree of freedom), re-planned every
period from its own state under the bounds of `ProgressLimits` (joint limits mapped onto
the progress). When the target changes, a new segment starts at the current reference pose,
with the reference's motion projected onto the new direction, so a target that moves is
pursued without a jump of the reference; the target's own velocity v (from its last two
poses) is the speed at which the progress meets it, planned in the target's frame (the gap
closed to relative rest, `ProgressProfile`), so a target that moves steadily is met moving
rather than chased to a stop, and no faster than a run-on past it could still stop before a
block beyond it (`Progress._meeting_speed`).

Jogging along a commanded twist uses the same bounds (`ratectl.control.jog`).
"""

from __future__ import annotations

import math

import numpy as np

from ..arrays import shared_zeros
from ..model.limits import braking_speed_scalar, stopping_distance_scalar
from ..spatial import rotation_error_rows, so3_exp_rows
from .cycle import _same_rotation
from .progress import PLANNED_BRAKE, ProgressCaps
from .smoothing import ProgressProfile, SpeedProfile

__all__ = ["Progress", "StraightApproach", "JointLine"]

_URGENT = 2.0  # a late stop brakes with up to this multiple of the bound (all of amax at η = 1/2)
AT_BLOCK = 1e-5  # [progress units ~ m]: a progress this close to a block, and creeping, stands at it


def _stop_bound(v: float, a: float, brake: float, jerk: float) -> float:
    """An upper bound of `_stop` in plain arithmetic: the acceleration first ramped to
    −brake at the jerk limit (at most (a + brake)/jerk, at most v plus a·that faster),
    then v'²/(2·brake) (the exact test runs only when this bound does not fit)."""
    t = (max(a, 0.0) + brake) / jerk
    v1 = v + max(a, 0.0) * t
    return v1 * t + v1 * v1 / (2.0 * brake)


def _stop(v: float, a: float, brake: float, jerk: float) -> float:
    """The distance of the jerk-limited stop from speed ``v`` and acceleration ``a``."""
    return stopping_distance_scalar(v, a, brake, jerk, exact_when_braking=True)


def stopping_progress(v: float, a: float, brake: float, jerk: float, dt: float) -> float:
    """The progress a motion at speed ``v`` ≥ 0 and acceleration ``a`` needs to come to rest
    [progress units]: one period ``dt`` at ``v``, then the jerk-limited stop braking at
    ``brake`` with jerk ``jerk`` (0 at rest or without a braking bound yet)."""
    if not (v > 0.0 and brake > 0.0 and jerk > 0.0):
        return 0.0
    return v * dt + _stop(v, a, brake, jerk)


class Progress:
    """A progress s ∈ [0, L] toward rest at L, one jerk-limited period at a time within the
    bounds of `ProgressLimits` (see `advance`). Owns (s, ṡ, s̈)."""

    def __init__(self) -> None:
        self._profile: ProgressProfile | None = None
        self._stopper: SpeedProfile | None = None
        self.L = 0.0
        self.restart()

    def restart(self, sd: float = 0.0, sdd: float = 0.0) -> None:
        """Progress 0 with speed ``sd`` and acceleration ``sdd``."""
        self.s = 0.0
        self.sd = sd
        self.sdd = sdd
        self.s_prev = 0.0
        self._brake = 0.0
        self._nominal = 0.0
        self._jerk = 0.0
        self.blocked = False
        self.room_left = math.inf
        self._periods = 0  # periods advanced since the segment began
        self.end_accel = math.inf  # the acceleration bound at the end of the line, when known
        self.end_speed = 0.0  # the speed of a target that moves along the line, met at it (0: at rest)

    def _extend(self, by: float) -> bool:
        """Run the segment on past its end by ``by`` [progress units], on the same line:
        whether it could (a progress without a line to extend cannot)."""
        return False

    def _late_stop(self, brake: float, x: float, amax: float, jmax: float, caps: ProgressCaps,
                   lead: float, v_end: float = 0.0) -> tuple[float, bool, bool]:
        """A stop from the present state that no longer fits in ``x`` at ``brake``:
        ``(brake, overrun, extended)``. It brakes just as hard as needed, up to `_URGENT` × ``amax``.
        A target that moves at ``v_end`` > 0 is met in its frame (the speed ṡ − v_end stops
        in ``x``; its bounds shrink on the way as J changes, so a time-optimal plan made at
        the nominal level comes late). Where even that does not fit, a moving target is met
        as fast as that allows (the progress that reaches the segment's end is held there at
        the target's speed); a target at rest:

        * before a singularity's block (its σ_min of the stop, or the peak of σ_min below
          it), ``overrun``: the stop runs on along the direction, a little past it (σ_min
          stays above 0 there), never as a jump to rest, which no jerk-limited arm follows
          (its joints would carry on off the direction);
        * at the target (one that stopped, or a switch close ahead), the segment runs on
          past it on the same line (`_extend`, ``extended``), far enough for the stop at
          that bound, if nothing blocks the way there; a new segment then comes back."""
        v = self.sd - v_end
        lo, hi = brake, max(_URGENT * amax, brake)
        at_hi = _stop(v, self.sdd, hi, jmax)
        if at_hi <= x:
            for _ in range(12):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if _stop(v, self.sdd, mid, jmax) > x else (lo, mid)
            return hi, False, False
        if v_end > 0.0:
            return hi, False, False
        if not self.blocked:
            past = at_hi * (1.0 + 1e-6) - x
            if past <= caps.room - max(lead, 0.0) - x and self._extend(past):
                return hi, False, True
        return hi, self.blocked and caps.room_by == "singularity", False

    def _meeting_speed(self, caps: ProgressCaps, speed_scale: float, lead: float, end: float) -> float:
        """The speed at which the progress meets a target that moves (`end_speed`; 0 for one
        at rest), at most the speed bound (× ``speed_scale``) and the speed from which the
        run-on past the target, were it to stop there, still stops before a block beyond it
        (a limit, a singularity: ``caps.room`` from the arm, which this progress leads by
        ``lead``), at the planned share of the bounds there: a target that moves toward a
        block is followed ever slower as the room shrinks, never at a speed only a jump to
        rest on it could stop."""
        v = min(self.end_speed, caps.free_speed * speed_scale)
        if v > 0.0 and caps.room < math.inf:
            beyond = caps.room - max(lead, 0.0) - end
            accel = PLANNED_BRAKE * min(caps.accel, self.end_accel, caps.room_accel)
            jerk = max(min(caps.jerk, caps.room_jerk), 1e-6)
            v = min(v, braking_speed_scalar(beyond, max(accel, 1e-9), jerk))
        return v

    def stopping_progress(self, dt: float, accel: float | None = None, jerk: float | None = None) -> float:
        """The progress this motion needs to come to rest [progress units]: one period at its
        speed, then the jerk-limited stop the last period planned (its nominal braking, not a
        late stop's harder one: the distance a stop planned now needs; 0 at rest or before
        the first period), or, given the bounds ``accel`` on |s̈| and ``jerk`` on |s⃛| (those
        at a block), the stop `advance` would plan within them."""
        if accel is not None and jerk is not None:
            return stopping_progress(self.sd, self.sdd, PLANNED_BRAKE * min(accel, self.end_accel), jerk, dt)
        return stopping_progress(self.sd, self.sdd, self._nominal, self._jerk, dt)

    def advance(self, caps: ProgressCaps, dt: float, *, speed_scale: float = 1.0, lead: float = 0.0) -> float:
        """One period of the progress toward rest at L within ``caps`` (the speed bound
        multiplied by ``speed_scale`` ∈ [0, 1]); returns the mean progress speed over the
        period, (s₁ − s₀)/dt, and updates (s, ṡ, s̈). ``lead`` is how far this progress is
        ahead of the arm (the room ahead of a block is measured from the arm)."""
        self._periods += 1
        end = self.L - self.s
        if not end > 0.0 and not self.sd > 0.0:  # at the end: the reference rests on the target
            self.s, self.sd, self.sdd = self.L, 0.0, 0.0
            return 0.0
        # (at the end still moving: it met a target that moved and has now stopped; the stop
        # below runs on past it on the line, as from anywhere too close to stop before it)
        # the stop is planned at the target, or before a block ahead (a joint limit, the
        # σ_min at which a singularity stops the motion): at rest there, the line is blocked
        x = min(end, caps.room - max(lead, 0.0))
        self.blocked = x < end
        v_end = self._meeting_speed(caps, speed_scale, lead, end) if not self.blocked else 0.0
        self.room_left = x
        if not x > 0.0 and self.sd == 0.0:
            self.sdd = 0.0
            return 0.0
        prof = self._profile
        if prof is None:
            prof = self._profile = ProgressProfile(dt)
        vmax = max(caps.free_speed * speed_scale, 1e-12)
        amax = max(caps.accel, 1e-9)
        jmax = max(caps.jerk, 1e-6)
        block_accel = math.inf
        if self.blocked:  # the stop ends at the block: within its bounds there (smaller near a singularity)
            block_accel = caps.room_accel
            jmax = max(min(jmax, caps.room_jerk), 1e-6)
        # the stop is planned at half the acceleration bound, here or at the end of the line
        # whichever is smaller (the bound can shrink on the way, as J changes: near a
        # singularity by several times); where the stop from the present
        # state no longer fits, the plan brakes just as hard as needed to stop at L, up to
        # twice the bound (the whole of amax at η = 1/2; the jerk stays within its share), instead
        # of passing the target and coming back; only a stop that does not fit even so runs on
        # past the target, on the line (`_extend`). A stop once planned harder keeps its level
        # (planned again at the nominal level, the time-optimal plan would brake later each
        # period and ratchet up to the reserve).
        nominal = PLANNED_BRAKE * min(amax, self.end_accel, block_accel)
        brake = max(nominal, self._brake) if self.sdd < 0.0 else nominal
        if self.sd > vmax:  # above a speed bound: its braking law assumes the whole bound
            brake = max(brake, amax)
        overrun = False
        v_rel = self.sd - v_end  # toward the end in the target's frame (at rest: ṡ)
        if v_rel > 0.0 and _stop_bound(v_rel, self.sdd, brake, jmax) > x \
                and _stop(v_rel, self.sdd, brake, jmax) > x * (1.0 + 1e-9):
            brake, overrun, extended = self._late_stop(brake, x, amax, jmax, caps, lead, v_end)
            if extended:  # (the segment now runs on past its target)
                end = x = self.L - self.s
        self._brake, self._nominal, self._jerk = brake, nominal, jmax
        if overrun:
            stopper = self._stopper
            if stopper is None:
                stopper = self._stopper = SpeedProfile(dt)
            brake = max(brake, abs(self.sdd))
            # the stop comes too late for the block's bounds: it brakes within the bounds
            # that hold where the arm is (the joints' jerk now, not the smaller one at the block)
            jmax = max(caps.jerk, jmax)
            # braking harder than the jerk bound lets the speed end at rest (a stop from
            # speed v at deceleration a needs the jerk a²/2v at least, or the speed would dip
            # below rest: back along the direction, by a²/2j, which a small jerk bound near a
            # singularity makes as large as the speed itself)
            if self.sdd < 0.0:
                jmax = max(jmax, self.sdd * self.sdd / (2.0 * self.sd) * (1.0 + 1e-9))
            vel = stopper.step(self.sd, self.sdd, 0.0, amax=brake, jmax=jmax, dt=dt)
            if vel is not None and vel[0] <= 1e-12:
                vel = (0.0, 0.0)
            # (the distance of one period of constant jerk from its two end states)
            nxt = None if vel is None else (dt * (0.5 * (self.sd + vel[0]) + dt * (self.sdd - vel[1]) / 12.0),
                                            vel[0], vel[1])
        else:
            nxt = prof.step(x, self.sd, self.sdd, vmax=vmax, amax=amax, jmax=jmax, dt=dt, brake=brake,
                            v_end=v_end)
        if nxt is None:  # no jerk-limited motion found: brake at the acceleration bound
            sd1 = max(self.sd - amax * dt, 0.0)
            dx, sdd1 = 0.5 * (self.sd + sd1) * dt, (sd1 - self.sd) / dt
        else:
            dx, sd1, sdd1 = nxt
        self.s_prev = self.s
        if dx >= end:  # the end of the segment (a motion too fast to stop on it ends there)
            dx = end
            if v_end > 0.0:  # with the moving target: the next segment carries the speed on
                self.s, self.sd, self.sdd = self.L, min(max(sd1, 0.0), v_end), 0.0
            else:
                self.s, self.sd, self.sdd = self.L, 0.0, 0.0
        elif dx >= x and self.blocked and not overrun:  # at the block: rest there
            dx = max(x, 0.0)
            self.s, self.sd, self.sdd = self.s + dx, 0.0, 0.0
        else:
            self.s, self.sd, self.sdd = self.s + dx, max(sd1, 0.0), sdd1
        return dx / dt


class StraightApproach(Progress):
    """The reference of the servo's approach: a straight segment and the progress along it
    (see the module docstring). Owns the segment and the progress state.

    Args:
        length: ℓ [m], the length that weighs rotation against translation in the progress.
    """

    def __init__(self, *, length: float) -> None:
        super().__init__()
        self.length = float(length)
        self._l2 = self.length * self.length
        self.reset()

    def reset(self) -> None:
        """Forget the segment and the progress (the next target starts a new approach)."""
        self.target: np.ndarray | None = None
        self.past_end = False  # the segment runs on past the target (`_extend`)
        self._t: list[list[float]] = []  # the target's rows as floats (its last estimate of motion)
        # the segment in plain floats (a target that moves starts a segment every period)
        self._p0 = [0.0, 0.0, 0.0]
        self._R0 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
        self._dp = [0.0, 0.0, 0.0]
        self._r = [0.0, 0.0, 0.0]
        self._pose_at: tuple[float, np.ndarray] | None = None
        self._v_target = 0.0  # the last estimate of the target's speed along its segment
        self.L = 0.0
        self.d = shared_zeros(6)
        self._d = [0.0] * 6
        self.w_prev: np.ndarray | None = None
        self.restart()

    def _extend(self, by: float) -> bool:
        """The segment runs on past its target by ``by`` > 0 [progress units] on the same
        line, T(s) for s up to L + by (Δp and r scaled, d kept); `past_end` says so until
        a new segment begins."""
        if not (self.L > 0.0 and by > 0.0):
            return False
        f = (self.L + by) / self.L
        self._dp = [x * f for x in self._dp]
        self._r = [x * f for x in self._r]
        self.L += by
        self._pose_at = None
        self.past_end = True
        return True

    def weighted_dot(self, a: np.ndarray, b: np.ndarray) -> float:
        """⟨a, b⟩_W = a_v·b_v + ℓ² a_ω·b_ω for two twists (6,)."""
        return self._wdot(a.tolist(), self._d if b is self.d else b.tolist())

    def _wdot(self, a: list[float], b: list[float]) -> float:
        """`weighted_dot` of two twists given as 6 floats."""
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + self._l2 * (a[3] * b[3] + a[4] * b[4] + a[5] * b[5])

    def weighted_norm(self, e: np.ndarray) -> float:
        """‖e‖_W for a twist or a pose error (6,)."""
        el = e.tolist()
        return math.sqrt(max(self._wdot(el, el), 0.0))

    @property
    def settled(self) -> bool:
        """The target has stayed the same since the segment began (at least one period)."""
        return self._periods > 0

    def retarget(self, target: np.ndarray, T_from: np.ndarray, twist: np.ndarray,
                 accel: np.ndarray) -> None:
        """A new segment from ``T_from`` to ``target`` (4×4 poses); the progress starts at 0
        with the speed and acceleration of the motion ``twist``, ``accel`` (6,) projected on
        the new direction (never backwards)."""
        f = T_from.tolist()
        self._segment(target, [f[0][3], f[1][3], f[2][3]], [f[0][:3], f[1][:3], f[2][:3]])
        if self.L > 0.0:
            sd = max(self.weighted_dot(twist, self.d), 0.0)
            a = self.weighted_dot(accel, self.d)
            self.restart(sd, a if sd > 0.0 else max(a, 0.0))
        else:
            self.restart()

    def same_target(self, rows: list[list[float]]) -> bool:
        """Whether the segment ends at the target whose rows of floats (its ``tolist()``) are
        ``rows``, entry for entry (``np.array_equal`` of the two poses)."""
        return self.target is not None and rows == self._t

    def retarget_from_reference(self, target: np.ndarray, *, dt: float | None = None,
                                rows: list[list[float]] | None = None) -> None:
        """A new segment from the present reference pose T(s) to ``target``: the reference
        goes on without a jump, its motion (ṡ, s̈ along the old direction d) projected on
        the new direction d′ as ṡ′ = ṡ⟨d, d′⟩_W, s̈′ = s̈⟨d, d′⟩_W (never backwards).
        Equal to ``retarget(target, pose(s), ṡ·d, s̈·d)``.

        With ``dt`` [s], the time since the previous target: the target's own velocity,
        τ = [Δp; log(R R_prevᵀ)]/dt, gives the speed v = ⟨τ, d′⟩_W at which the progress
        meets the target (``end_speed``), so that a target that moves is met moving instead
        of being chased from behind by a reference that plans to rest on it. A target that
        jumps (a switch) is not moving: v counts only when two successive estimates agree
        within 25 %, and the smaller is taken. ``rows``: the target's rows of floats, when
        the caller has them."""
        d_old, sd, sdd = self._d, self.sd, self.sdd
        t = target.tolist() if rows is None else rows
        tau = self._target_rate(t, dt) if dt is not None else None
        p, R = self._pose_rows(self.s)
        self._segment(target, p, R, t)
        if self.L > 0.0:
            proj = self._wdot(d_old, self._d)
            v = max(sd * proj, 0.0)
            a = sdd * proj
            self.restart(v, a if v > 0.0 else max(a, 0.0))
            if tau is not None:
                v_t = max(self._wdot(tau, self._d), 0.0)
                prev, self._v_target = self._v_target, v_t
                if v_t > 0.0 and prev > 0.0 and abs(v_t - prev) <= 0.25 * max(v_t, prev):
                    self.end_speed = min(v_t, prev)
        else:
            self.restart()
            self._v_target = 0.0

    def _target_rate(self, t: list[list[float]], dt: float) -> list[float] | None:
        """τ = [p − p_prev; log(R R_prevᵀ)]/dt of the target with rows ``t`` (floats) after the
        present one (base axes), or None without a present one."""
        if self.target is None or not dt > 0.0:
            return None
        o = self._t
        if _same_rotation(t, o):
            x = y = z = 0.0  # the same orientation: log(R Rᵀ) is exactly 0 (the product's
            # off-diagonal pairs are the same dot products, whose skew part cancels exactly)
        else:
            x, y, z, _ = rotation_error_rows(t, o)
        k = 1.0 / dt
        return [(t[0][3] - o[0][3]) * k, (t[1][3] - o[1][3]) * k, (t[2][3] - o[2][3]) * k,
                x * k, y * k, z * k]

    def hold_target(self) -> None:
        """The target did not move this period: the progress plans to rest on it."""
        self.end_speed = 0.0
        self._v_target = 0.0

    def _segment(self, target: np.ndarray, p0: list[float], R0: list[list[float]],
                 t: list[list[float]] | None = None) -> None:
        """The segment from (p0, R0) (floats) to ``target`` (its rows as floats ``t``, when the
        caller has them): Δp, r = log(R_d R₀ᵀ), L, d."""
        self.target = target.copy()
        if t is None:
            t = target.tolist()
        self._t = t
        self.past_end = False  # the segment runs on past the target (`_extend`)
        self._p0, self._R0 = p0, R0
        dp = self._dp = [t[0][3] - p0[0], t[1][3] - p0[1], t[2][3] - p0[2]]
        x, y, z, _ = rotation_error_rows(t, R0)
        self._r = [x, y, z]
        L = math.sqrt(dp[0] * dp[0] + dp[1] * dp[1] + dp[2] * dp[2] + self._l2 * (x * x + y * y + z * z))
        self.L = L
        self.w_prev = None
        self._pose_at = None
        if L > 0.0:
            k = 1.0 / L
            d = self._d = [dp[0] * k, dp[1] * k, dp[2] * k, x * k, y * k, z * k]
        else:
            d = self._d = [0.0] * 6
        self.d = np.array(d)
        self.d.setflags(write=False)  # (= self._d, which weighted_dot reads for it)

    def _pose_rows(self, s: float) -> tuple[list[float], list[list[float]]]:
        """(p, R) of T(s) as floats: p₀ + (s/L)Δp and exp((s/L)·r) R₀."""
        f = s / self.L if self.L > 0.0 else 1.0
        p0, dp = self._p0, self._dp
        p = [p0[0] + f * dp[0], p0[1] + f * dp[1], p0[2] + f * dp[2]]
        if f == 0.0:
            return p, self._R0
        r = self._r
        (e0, e1, e2), (g0, g1, g2), (h0, h1, h2) = so3_exp_rows(f * r[0], f * r[1], f * r[2])
        (a0, a1, a2), (b0, b1, b2), (c0, c1, c2) = self._R0
        return p, [[e0 * a0 + e1 * b0 + e2 * c0, e0 * a1 + e1 * b1 + e2 * c1, e0 * a2 + e1 * b2 + e2 * c2],
                   [g0 * a0 + g1 * b0 + g2 * c0, g0 * a1 + g1 * b1 + g2 * c1, g0 * a2 + g1 * b2 + g2 * c2],
                   [h0 * a0 + h1 * b0 + h2 * c0, h0 * a1 + h1 * b1 + h2 * c1, h0 * a2 + h1 * b2 + h2 * c2]]

    def pose_rows(self, s: float) -> list[list[float]]:
        """The first three rows [R | p] of T(s) as floats (`pose` without the array)."""
        p, (a, b, c) = self._pose_rows(s)
        return [[a[0], a[1], a[2], p[0]], [b[0], b[1], b[2], p[1]], [c[0], c[1], c[2], p[2]]]

    def pose(self, s: float) -> np.ndarray:
        """T(s), the reference pose at progress ``s`` (4×4; the same array for the same s
        until the segment changes: do not write to it)."""
        cached = self._pose_at
        if cached is not None and cached[0] == s:
            return cached[1]
        p, (a, b, c) = self._pose_rows(s)
        T = np.array((a[0], a[1], a[2], p[0], b[0], b[1], b[2], p[1], c[0], c[1], c[2], p[2],
                      0.0, 0.0, 0.0, 1.0)).reshape(4, 4)
        self._pose_at = (s, T)
        return T

    def w_prime(self, w: np.ndarray) -> np.ndarray | None:
        """dw/ds from the previous period's w (None until the progress has moved)."""
        wp, ds = self.w_prev, self.s - self.s_prev
        if wp is None or not abs(ds) > 1e-9:
            return None
        return (w - wp) / ds


class JointLine(Progress):
    """The servo's alternative where its straight line is blocked (a joint limit or a
    singularity on the way): a straight line in joint space from where the arm is to a
    verified inverse-kinematics solution of the target, q(s) = q₀ + s·u, u = (q_g − q₀)/L,
    L = ‖q_g − q₀‖ [rad or m], with the same progress within the joint limits (w = u)."""

    def __init__(self) -> None:
        super().__init__()
        self.reset()

    def reset(self) -> None:
        self.target: np.ndarray | None = None
        self.q0 = np.zeros(0)
        self.u = np.zeros(0)
        self.L = 0.0
        self.restart()

    def start(self, target: np.ndarray, q0: np.ndarray, q_goal: np.ndarray, qd: np.ndarray) -> None:
        """The line from ``q0`` to ``q_goal`` for ``target``; the progress starts with the
        arm's motion ``qd`` projected on it (never backwards)."""
        self.target = target.copy()
        self.q0 = q0.copy()
        dq = q_goal - q0
        self.L = float(np.sqrt(dq @ dq))
        self.u = dq / self.L if self.L > 0.0 else np.zeros_like(dq)
        self.restart(max(float(qd @ self.u), 0.0), 0.0)

    def q_at(self, s: float) -> np.ndarray:
        """q(s), the reference on the joint line."""
        return self.q0 + s * self.u
