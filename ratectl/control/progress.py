"""How fast the arm may progress along a commanded direction: one mechanism for the servo's
straight approach and for jogging.

Both modes move the tool along a direction fixed in task space: the straight segment to a
target, or the twist a teleoperator streams. With ``w = J⁺d`` the joint velocity per unit of
progress along the direction ``d`` (6,), the joint motion is

    q̇ = ṡ w,    q̈ = s̈ w + ṡ² w′    (w′ = dw/ds, the change of w along the way)

so every joint limit becomes a bound on the scalar progress ``s``, and obeying it scales the
motion along ``d`` without ever turning it. `ProgressLimits.caps` computes those bounds at the
measured q, for the coming period:

* **velocity**: ṡ ≤ minᵢ vmaxᵢ/|wᵢ|;
* **acceleration**: s̈ within a share η of amax, minᵢ η·amaxᵢ/|wᵢ| (the rest, (1 − η)·amax,
  is kept for the ṡ²w′ term: ṡ ≤ √((1 − η)·amaxᵢ/|w′ᵢ|)), and the jerk likewise;
* **position limits**: joint i moving toward a limit at distance Dᵢ may move at most at the
  speed from which it still stops there at η·amaxᵢ whatever the later periods are
  (`braking_speed_any_dt`), so ṡ ≤ that speed/|wᵢ|;
* **singularities**, for a direction that is being lost (more than a fifth of its exact
  joint speed |J⁺d|² goes into the weakest singular direction of J, so it needs joint
  speeds ∝ 1/σ_min as σ_min → 0): σ_min(J) must not fall below ``stop_sigma`` while the
  motion lowers it. Its rate along the direction, σ′ = dσ_min/ds, comes from a finite
  difference of σ_min one small step ahead along w; the remaining progress before σ_min
  reaches ``stop_sigma`` is estimated as Δs = (σ_min − stop)/(2|σ′|) (half the first-order
  estimate: σ_min falls like √(distance) at a boundary singularity); σ_min one joint step
  further ahead gives its bend, and where the parabola through the three bends down, its
  crossing of ``stop_sigma`` (or, below the stop, the peak of a rise) bounds the room too
  (`_bend_room`: a line that grazes a singularity). Near a singularity
  the direction's joint path is also followed ahead along the exact w = J⁺d, over 1.5×
  the distance a stop at the bounds of a block needs (`caps`'s ``ahead``): the block is
  the first point where σ_min is at most ``stop_sigma`` with the direction lost there, or,
  below ``stop_sigma``, the peak of σ_min a motion rising away would pass
  (`_room_ahead`); vmax on the way bounds ṡ now. The arm therefore stops *before* the
  lost direction, with the direction of the tool motion unchanged, and moves away at once
  (a rise of σ_min is never bounded). A direction that stays in the range of J at the
  singular configuration is not bounded by this (vmax bounds it as everywhere). A stop
  before a singularity is planned at the joints' bounds at the block (``room_accel``,
  ``room_jerk``), where |w| is larger.

The position and singularity bounds come in two forms: ``room``, the progress left before
the nearest block (the servo's approach plans its stop there), and a speed bound, the
jerk-limited braking speed within that room (a jog meets it). A speed bound of zero with
the progress at rest means the direction is **blocked**: ``blocked_by`` says by what
("singularity" or "position"), with the joint (by the chain's joint name) or σ_min, in
``reason``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..model.limits import Limits, braking_speed_any_dt_scalar, braking_speed_scalar

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ["ProgressCaps", "ProgressLimits"]

_TINY_W = 1e-12  # a joint with |w_i| below this does not move along the direction
_LIMIT_MARGIN = 1e-3  # [rad or m] a jog's speed bound stops this far inside a joint's position limit
_VMAX_HEADROOM = 0.05  # the share of vmax a smoothed progress leaves to its filter
_LOST = 0.2  # share of |J⁺d|² in the weakest direction above which a direction is being lost
_AHEAD_STEPS = 4  # at most this many steps of the singularity look-ahead along the direction's joint path
_FAR_ABOVE = 2.0  # the look-ahead runs below this many times stop_sigma
_AHEAD_JOINT_STEP = 0.05  # [rad or m] a look-ahead step moves a joint at most this far (w at q)
_AT_STOP = 1e-9  # [rad or m]: a joint that may move less than this in a period stands at its stop
PLANNED_BRAKE = 0.5  # a stop is planned at this share of the progress's acceleration bound (approach, jog)
_SIGMA_NOISE = 1e-10  # a change of σ_min over the look-ahead step below this is rounding
_BEND_STEP = 0.02  # [rad or m] the joint step (w at q) over which the bend of σ_min ahead is measured
_UNBOUNDED = 1e9  # an absent bound on the progress (Ruckig needs finite limits)
_JERK_BIG = 1e12  # an unbounded progress jerk in the jerk-limited braking formula


@dataclass(slots=True)
class ProgressCaps:
    """Bounds on the progress ṡ along a direction for the coming period.

    Attributes:
        speed: largest admissible ṡ now [progress units/s] (0: stop).
        accel: largest |s̈| [progress units/s²]; jerk: largest |s⃛| [progress units/s³].
        binding: what sets ``speed`` ("velocity", "position", "singularity",
            "curvature" or "" when nothing bounds it).
        blocked_by: "position" or "singularity" when the bound is zero (the direction is
            blocked where the arm is), else "".
        joint: index of the binding joint (position and velocity bounds), or -1.
        sigma: σ_min(J) at q (NaN when not computed: far from every singularity).
        reason: a sentence for the command ("" when nothing binds).
        free_speed: the bound on ṡ from vmax and the curvature alone, without the braking
            toward a position limit or a singularity (those are ``room``).
        room: the progress still free ahead of the nearest block, a position limit or the
            σ_min of ``stop_sigma`` (first-order estimates, inf when none): a motion that
            plans its stop (the approach) plans it there instead of meeting ``speed``.
        room_by, room_reason: what blocks there ("position" or "singularity") and a sentence
            for the command.
        room_accel, room_jerk: the bounds on |s̈| and |s⃛| at the block, where a stop planned
            before it ends (a singularity's: its joint speeds per unit progress are larger
            there than at q, see `ProgressLimits._singularity`; inf when no block is ahead or
            the bounds there are those at q).
        room_peak: the block is the peak of σ_min below ``stop_sigma`` (a motion that rises
            away from a singularity and would then lower σ_min again).
        room_margin: the progress of the margin a jog keeps inside a position limit
            (`_LIMIT_MARGIN` of the joint that blocks, in progress units; 0 for a singularity).
        limit_room: the progress still free ahead of the nearest position limit less the
            jog's margin inside it, whatever block is nearer (inf when no joint moves toward
            a limit): a singularity's block may hide a limit just beyond it, whose stop is
            due earlier.
    """

    speed: float
    accel: float
    jerk: float
    binding: str = ""
    blocked_by: str = ""
    joint: int = -1
    sigma: float = math.nan
    reason: str = ""
    free_speed: float = math.inf
    room: float = math.inf
    room_by: str = ""
    room_reason: str = ""
    room_accel: float = math.inf
    room_jerk: float = math.inf
    room_peak: bool = False
    room_margin: float = 0.0
    limit_room: float = math.inf


@dataclass(slots=True)
class _Ahead:
    """What the singularity look-ahead found (`ProgressLimits._room_ahead`): the room before
    the block (inf: none within reach), whether it is a peak of σ_min, the bounds on |s̈|
    and |s⃛| at the block (inf: no block), and the bound on ṡ now from vmax on the way."""

    room: float = math.inf
    peak: bool = False
    accel: float = math.inf
    jerk: float = math.inf
    speed: float = math.inf


class ProgressLimits:
    """The joint limits of a chain as bounds on progress along a direction (see the module
    docstring). Owns the limit arrays in the forms the cycle needs.

    Args:
        chain: the arm (its Jacobian is evaluated one small step ahead near singularities,
            and its joint names appear in the reasons).
        limits: the controller's `Limits` (None: no joint limits).
        jmax: per-joint jerk limits (n,) or None (the progress jerk is then unbounded).
        accel_share: η, the share of amax (and jmax) the progress may use itself.
        stop_sigma: σ_min(J) at which motion that lowers σ_min must have stopped [units of σ].
        watch_sigma: below this σ_min the singularity bound is evaluated (above it, never
            binding and not computed).
    """

    def __init__(self, chain: Chain, limits: Limits | None, *, jmax: np.ndarray | None,
                 accel_share: float, stop_sigma: float, watch_sigma: float) -> None:
        self.chain = chain
        self.names = chain.joint_names
        n = chain.dof
        self.accel_share = float(accel_share)
        self.stop_sigma = float(stop_sigma)
        self.watch_sigma = float(watch_sigma)
        inf = np.full(n, np.inf)
        lim = limits
        self.vmax = lim.vmax if lim is not None else inf
        self.amax = lim.amax if lim is not None else inf
        self.lower = lim.lower if lim is not None else -inf
        self.upper = lim.upper if lim is not None else inf
        self.jmax = np.asarray(jmax, dtype=float) if jmax is not None else inf
        self._has_p = bool(np.any(np.isfinite(self.lower) | np.isfinite(self.upper)))
        share_a = self.accel_share * self.amax
        share_j = self.accel_share * self.jmax
        # 2/a for the braking law at the share (a huge a for an absent limit: stop in one period)
        two_over_a = np.where(np.isfinite(share_a), 2.0 / np.where(np.isfinite(share_a), share_a, 1.0), 0.0)
        # with jerk limits (a smoothed command) the stop toward a position limit is jerk-limited
        fin_j = np.isfinite(share_j) & np.isfinite(share_a)
        jerk_limited = fin_j.any()
        # a jerk-limited (smoothed) command keeps _VMAX_HEADROOM of vmax free: the feedback on
        # top of the progress and a bound that shrinks along the way must not meet the filter
        # at vmax with an acceleration it can no longer ramp out
        vcap = self.vmax * (1.0 - _VMAX_HEADROOM) if jerk_limited else self.vmax

        # as Python floats: `caps` runs every period on a handful of joints, where plain
        # arithmetic beats numpy's per-call cost
        def floats(a) -> list[float]:
            return np.broadcast_to(a, (n,)).tolist()

        self._l_vcap = floats(vcap)
        self._l_share_a = floats(share_a)
        self._l_share_j = floats(share_j)
        self._l_curv_a = floats((1.0 - self.accel_share) * self.amax)
        self._l_lower = floats(self.lower)
        self._l_upper = floats(self.upper)
        self._l_two_over_a = floats(two_over_a)
        self._l_slack = floats(np.where(np.isfinite(self.vmax), self.vmax, 0.0))  # one period at vmax
        self._l_jerk = ((floats(np.where(fin_j, share_a, 1.0)), floats(np.where(fin_j, share_j, 1e300)))
                        if jerk_limited else None)
        self._reasons: dict[tuple[int, bool, bool], str] = {}  # `_limit_reason`'s sentences

    def name(self, i: int) -> str:
        """The chain's name of joint ``i`` (quoted), for reasons."""
        return repr(self.names[i])

    def caps(self, q: np.ndarray, w: np.ndarray, *, dt: float, sigma: float | None = None,
             w_prime: np.ndarray | None = None, exact=None,
             q_lead: np.ndarray | None = None, ahead=None) -> ProgressCaps:
        """The bounds on ṡ, s̈, s⃛ at ``q`` for motion ``q̇ = ṡ w`` (ṡ ≥ 0).

        Args:
            q: measured joint positions (n,).
            w: joint velocity per unit progress (n,).
            dt: the coming period [s].
            sigma: None when σ_min(J(q)) is at least ``watch_sigma``, else σ_min or an
                upper bound of it below ``watch_sigma`` (`ProgressStage.sigma_for_watch`):
                only compared with ``watch_sigma`` (the singularity bound computes σ_min
                itself).
            w_prime: dw/ds (n,) if known (the curvature term), else None.
            q_lead: the position the commands have sent the arm to (n,) (the controller's
                sum of commanded displacements, `Motion.commanded`), or None: an arm that lags
                its velocity command still gets there once the command stops, so a joint's
                room to its limit is measured from whichever of q and q_lead is nearer the
                limit.
            exact: ``f(q, share=True) -> (σ_min, share, w)``: σ_min(J) at any q, the share
                of the direction's exact joint speed |J⁺d|² in the weakest direction and that
                joint velocity per unit progress w = J⁺d (NaN and None with ``share=False``:
                σ_min alone), for the singularity look-ahead (None: no singularity bound).
            ahead: ``f(accel, jerk) -> float``, the progress the motion needs to come to rest
                from its present state within the bounds ``accel`` on |s̈| and ``jerk`` on |s⃛|
                [progress units] (0 at rest), called only near a singularity with the bounds
                a block ahead could have: σ_min is also evaluated about that far ahead, so
                that a σ_min that falls faster on the way than its slope at q says, or a
                direction not yet lost here, is stopped for in time (None: not evaluated).
        """
        wl = w.tolist()
        inf = math.inf
        speed = accel = jerk = inf
        jv = -1
        vcap, share_a, share_j = self._l_vcap, self._l_share_a, self._l_share_j
        # position limits: joints moving toward a limit brake in time at the share of amax
        # (in the same pass over the joints as the velocity and acceleration bounds)
        has_p = self._has_p
        if has_p:
            ql = q.tolist()
            ll = q_lead.tolist() if q_lead is not None else None
            lower, upper, two_over_a = self._l_lower, self._l_upper, self._l_two_over_a
            jl = self._l_jerk
            slack = self._l_slack
        p_min = p_room = inf
        jp = p_joint = -1
        p_inv = 0.0
        moving = False
        for i, wi in enumerate(wl):
            awi = wi if wi >= 0.0 else -wi
            if not awi > _TINY_W:  # the joint does not move along the direction
                continue
            moving = True
            inv = 1.0 / awi
            v = vcap[i] * inv
            if v < speed:
                speed, jv = v, i
            x = share_a[i] * inv
            if x < accel:
                accel = x
            x = share_j[i] * inv
            if x < jerk:
                jerk = x
            if not has_p:
                continue
            # the room ahead of whichever of q and q_lead is nearer the limit
            a = ql[i]
            if wi > 0.0:
                if ll is not None:
                    b = ll[i]
                    a = b if b > a else a
                room = upper[i] - a
            else:
                if ll is not None:
                    b = ll[i]
                    a = b if b < a else a
                room = a - lower[i]
            if not -inf < room < inf:
                continue
            # the speed bound stops _LIMIT_MARGIN short (a jog of an arm that lags its
            # command then does not press a joint onto its limit); the room ahead of an
            # approach ends at the limit itself (a target may lie on it)
            D = room - _LIMIT_MARGIN
            b = braking_speed_any_dt_scalar(D, dt, two_over_a[i])
            if jl is not None:  # and the jerk-limited stop fits as well
                b = min(b, braking_speed_scalar(max(D - slack[i] * dt, 0.0), jl[0][i], jl[1][i]))
            x = (b if b > 0.0 else 0.0) * inv
            if x < p_min:
                p_min, jp = x, i
            x = (room if room > 0.0 else 0.0) * inv
            if x < p_room:
                p_room, p_joint, p_inv = x, i, inv
        if not moving:  # no joint moves along the direction
            return ProgressCaps(speed=_UNBOUNDED, accel=_UNBOUNDED, jerk=_UNBOUNDED)
        binding, joint = ("velocity", jv) if speed < inf else ("", -1)
        if w_prime is not None:
            curv_a = self._l_curv_a
            c_min, jc = inf, -1
            for i, x in enumerate(w_prime.tolist()):
                ax = x if x >= 0.0 else -x
                if ax > _TINY_W:
                    c = math.sqrt(curv_a[i] / ax)
                    if c < c_min:
                        c_min, jc = c, i
            if c_min < speed:
                speed, binding, joint = c_min, "curvature", jc
        free_speed = speed
        blocked_by = ""
        reason = ""
        if p_min < speed:
            speed, binding, joint = p_min, "position", jp
            blocked_by = "position" if speed <= 0.0 else ""
            # (at its stop point once the joint may move less than _AT_STOP this period: the
            # bound of an arm at rest there is a creep of D/dt, not a motion toward the limit)
            reason = self._limit_reason(wl, jp, at=speed * abs(wl[jp]) * dt <= _AT_STOP)
        caps = ProgressCaps(speed=speed, accel=min(accel, _UNBOUNDED), jerk=min(jerk, _UNBOUNDED),
                            binding=binding, blocked_by=blocked_by, joint=joint, reason=reason,
                            free_speed=free_speed)
        if p_room < inf:
            caps.room, caps.room_by, caps.room_margin = p_room, "position", _LIMIT_MARGIN * p_inv
            caps.limit_room = p_room - caps.room_margin
            caps.room_reason = self._limit_reason(wl, p_joint, at=p_room <= 0.0)
        if exact is not None and sigma is not None and sigma < self.watch_sigma:
            self._singularity(caps, q, w, exact, ahead)
        return caps

    def _bounds_at(self, w: np.ndarray) -> tuple[float, float, float]:
        """The bounds on ṡ (vmax, with a smoothed command's headroom), |s̈| and |s⃛| (the
        progress's shares of amax and jmax) for motion q̇ = ṡ w, in one pass over the joints."""
        speed = accel = jerk = math.inf
        for v, a, j, wi in zip(self._l_vcap, self._l_share_a, self._l_share_j, w.tolist(), strict=True):
            awi = wi if wi >= 0.0 else -wi
            if awi > _TINY_W:
                inv = 1.0 / awi
                x = v * inv
                if x < speed:
                    speed = x
                x = a * inv
                if x < accel:
                    accel = x
                x = j * inv
                if x < jerk:
                    jerk = x
        return speed, accel, jerk

    def _room_ahead(self, q, w, w_inf: float, exact, sigma: float, share: float, D: float) -> _Ahead:
        """What lies within the progress ``D`` ahead (a little more than the motion needs to
        come to rest at the bounds of a block) near a singularity, where the slope of σ_min
        at q says nothing yet (past a maximum of σ_min, before it, or for a direction not
        yet lost here). The joint path of the direction is followed in up to `_AHEAD_STEPS` steps
        (as few as move no joint more than `_AHEAD_JOINT_STEP` by w at q, ``w_inf`` = max |w_i|),
        each along the exact w = J⁺d where it starts (σ_min, the share and w from one SVD
        per step). The block is the first point where σ_min is at most ``stop_sigma`` with
        the direction lost there (its share of |J⁺d|² above 0.2; the share grows as σ_min
        falls toward a singularity whose lost direction the motion heads into):

        * where σ_min falls through the stop with the direction lost, at the crossing
          (linear between the two steps around it);
        * where the share rises through 0.2 below the stop, at that crossing;
        * below the stop with the direction lost here, a motion rising away from the
          singularity may not end lower than it is: where σ_min falls after rising, the
          motion stops at the peak (the parabola through the three steps around it; a rise
          that goes on, however it bends, never stops it).

        On the way, vmax bounds ṡ at each step by vmax/|w|; the speed from which the motion
        still slows to that bound by then, braking at half its share of amax with its share
        of jmax, bounds ṡ now (|w| grows toward a singularity faster than a jerk-limited
        progress slows once the bound binds)."""
        stop = self.stop_sigma
        rising = sigma <= stop and share > _LOST  # only a rise away from the singularity is free
        steps = min(_AHEAD_STEPS, max(1, math.ceil(w_inf * D / _AHEAD_JOINT_STEP)))
        dx = D / steps
        xs, ss, hs = [0.0], [sigma], [share]
        q_k, w_k = q, w
        out = _Ahead()
        for k in range(1, steps + 1):
            q_k = q_k + w_k * dx
            s_k, h_k, w_next = exact(q_k)
            x_k = k * dx
            a_k = j_k = math.inf  # the bounds at this step (those at the block, if it is here)
            if w_next is not None:
                v_k, a_k, j_k = self._bounds_at(w_next)
                if v_k < math.inf:  # vmax at this step
                    slow = (braking_speed_scalar(x_k, PLANNED_BRAKE * a_k, j_k) if a_k < math.inf
                            else math.inf)
                    out.speed = min(out.speed, math.sqrt(v_k * v_k + slow * slow))
            s_prev, h_prev, x_prev = ss[-1], hs[-1], xs[-1]
            if rising:
                if s_k < s_prev:  # falls after rising: stop at the peak
                    out.peak = True
                    if k == 1:
                        out.room = 0.0
                        return out
                    x0, s0 = xs[-2], ss[-2]
                    curv = (s0 - 2.0 * s_prev + s_k) / (2.0 * dx * dx)
                    slope = (s_prev - s0) / dx - curv * dx  # at x0
                    top = x0 + (-slope / (2.0 * curv) if curv < 0.0 else dx)
                    out.room = min(max(top, x0), x_k)
                    return out
            elif s_k <= stop and h_k > _LOST:
                out.accel, out.jerk = a_k, j_k
                if s_prev > stop:
                    out.room = x_prev + dx * (s_prev - stop) / (s_prev - s_k)
                else:
                    out.room = x_prev + dx * max(_LOST - h_prev, 0.0) / (h_k - h_prev)
                return out
            if w_next is None:
                break
            xs.append(x_k)
            ss.append(s_k)
            hs.append(h_k)
            w_k = w_next
        return out

    def _limit_reason(self, w: list[float], i: int, *, at: bool) -> str:
        """The sentence for joint ``i`` moving toward the limit on the side of w_i (``w``:
        the direction's joint velocities as floats); each sentence is made once, on its
        first use, and kept (`caps` names a joint's room every period)."""
        key = (i, w[i] > 0.0, at)
        text = self._reasons.get(key)
        if text is None:
            side = "upper" if key[1] else "lower"
            text = self._reasons[key] = (f"joint {self.name(i)} is at its {side} limit" if at
                                         else f"joint {self.name(i)} braking toward its {side} limit")
        return text

    def _bend_room(self, q, w, w_inf: float, exact, sigma: float, slope: float) -> float:
        """Where σ_min, bending down ahead, holds the motion: on the parabola through σ_min
        at q with its slope there (``slope`` = dσ_min/ds) and σ_min one joint step
        `_BEND_STEP` ahead along w (``w_inf`` = max |w_i|), σ(x) = σ + m·x + ½c·x² with c < 0:

        * above ``stop_sigma``, the progress before it falls to the stop,
          x = (m + √(m² − 2c(σ − stop)))/(−c);
        * at or below the stop, while it rises or stands flat (m ≥ 0 to rounding), its peak
          x = max(m, 0)/(−c), where a motion rising away from the singularity stops (it may
          not end lower than it is): 0 for an arm at rest at that peak.

        A direction that grazes a singularity (σ_min rises, turns over and falls) is slowed
        while σ_min still rises, where the slope alone sees no block; inf where σ_min does
        not bend down."""
        h = _BEND_STEP / w_inf
        sigma_h = exact(q + w * h, share=False)[0]
        c = 2.0 * (sigma_h - sigma - slope * h) / (h * h)
        if not c < -_SIGMA_NOISE * (1.0 + sigma) / (h * h):
            return math.inf
        if sigma > self.stop_sigma:
            return (slope + math.sqrt(slope * slope - 2.0 * c * (sigma - self.stop_sigma))) / -c
        return max(slope, 0.0) / -c  # (0 at the peak: flat to rounding, and bending down)

    def _singularity(self, caps: ProgressCaps, q, w, exact, ahead=None) -> None:
        """The singularity bound (see the module docstring) applied to ``caps``: only for a
        direction that is being lost, here or within the look-ahead, most of whose exact
        joint speed |J⁺d|² goes into the weakest direction of J (share above 0.2: as σ_min → 0
        it needs joint speeds ∝ 1/σ_min); a direction that stays in the range of J at the
        singular configuration (a target on the smooth branch, q5 → 0 on a UR wrist) needs
        bounded joint speeds and is not blocked (vmax bounds it as everywhere, and on the way
        ahead)."""
        sigma, share, _ = exact(q)
        caps.sigma = sigma
        norm = float(np.sqrt(w @ w))
        if not norm > 0.0:
            return
        ds = 1e-4 / norm  # a 1e-4 rad (or m) joint step along w
        w_inf = max(abs(x) for x in w.tolist())  # (the largest joint speed per unit progress)
        room = math.inf
        bend_peak = False
        if share > _LOST:  # being lost here: the slope of σ_min at q, and its bend
            drop = sigma - exact(q + w * ds, share=False)[0]
            falls = drop > _SIGMA_NOISE * (1.0 + sigma)  # (else moving away from it, or along it)
            if falls:
                room = (sigma - self.stop_sigma) / (2.0 * drop / ds)
            # (below the stop, unless it falls here: the slope already stops it)
            if sigma > self.stop_sigma or not falls:
                bend = self._bend_room(q, w, w_inf, exact, sigma, -drop / ds)
                if bend < room:  # (below the stop: the peak of a rise)
                    room, bend_peak = bend, sigma <= self.stop_sigma
        # the look-ahead reaches as far as a stop at the bounds of a block would need: |w| is
        # at most σ_min/stop times larger there (a lost direction's weakest component grows
        # like 1/σ_min), and the bounds on s̈ and s⃛ that much smaller; it runs below
        # _FAR_ABOVE × the stop only (above, the slope at q bounds a lost direction, and a
        # block is farther than a stop from there needs: the look-ahead sees it on the way)
        # — and at least one joint step `_BEND_STEP` (w at q), even for a motion at rest: an
        # arm that stopped where the direction's share crosses `_LOST` below the stop reads
        # a share just under it at q, rounding either way; only a look at the way ahead
        # keeps that block where it is (else the progress creeps on, meets it again and
        # stops, and the status flickers between the block and moving)
        reach = max(sigma / self.stop_sigma, 1.0)
        near = sigma <= _FAR_ABOVE * self.stop_sigma
        D = 0.0
        if ahead is not None and room > 0.0 and near:
            D = max(ahead(caps.accel / reach, caps.jerk / reach), _BEND_STEP / w_inf)
        peak = bend_peak
        block_bounds = None
        if D > ds:
            found = self._room_ahead(q, w, w_inf, exact, sigma, share, 1.5 * D)
            if found.speed < caps.speed:  # vmax on the way
                caps.speed = found.speed
                caps.binding, caps.joint, caps.reason, caps.blocked_by = "velocity", -1, "", ""
            caps.free_speed = min(caps.free_speed, found.speed)
            if found.room < room:
                room, peak = found.room, found.peak
                block_bounds = (min(caps.accel, found.accel), min(caps.jerk, found.jerk))
        if room == math.inf:
            return  # moving away from the singularity, or along it: never bounded
        if room <= 0.0:
            reason = (f"stopped before a singularity: σ_min = {sigma:.3g} ≤ {self.stop_sigma:.3g} and the "
                      "commanded direction lowers it further")
        elif sigma > self.stop_sigma:
            reason = (f"approaching a singularity (σ_min = {sigma:.3g}, stops at {self.stop_sigma:.3g}): "
                      "slowed along the commanded direction")
        elif not peak:
            reason = (f"approaching a singularity (σ_min = {sigma:.3g} ≤ {self.stop_sigma:.3g}): the "
                      "commanded direction lowers it and is being lost ahead: slowed to stop before")
        else:
            reason = (f"approaching a singularity (σ_min = {sigma:.3g} ≤ {self.stop_sigma:.3g}): the "
                      "commanded direction rises away from it, then lowers σ_min again: slowed to stop "
                      "at its peak")
        # at the block the joint speed per unit progress is larger: the look-ahead's w there,
        # or, for a block from the slope at q, the share of |w|² in the weakest direction
        # grown like 1/σ_min² (the rest stays): |w| grows by ρ = √((1 − share) + share·
        # (σ_min/stop)²) and the bounds on s̈ and s⃛ shrink by 1/ρ there; a stop planned at
        # the bounds at q would ask the joints for up to ρ× their share of amax and jmax as it
        # ends (a smoothed command cannot follow: the tool leaves its line)
        if block_bounds is None:
            rho = math.sqrt(max(1.0 - share, 0.0) + share * reach * reach)
            block_bounds = (caps.accel / rho, caps.jerk / rho)
        accel_block, jerk_block = block_bounds
        if max(room, 0.0) < caps.room:  # the room ahead (an approach plans its stop there)
            # (said of the block itself: whether the arm still moves is the status's to say)
            caps.room, caps.room_by, caps.room_margin = max(room, 0.0), "singularity", 0.0
            caps.room_accel, caps.room_jerk = accel_block, jerk_block
            caps.room_peak = peak and 0.0 < room
            caps.room_reason = (f"a singularity whose lost direction the line heads into (σ_min = "
                                f"{sigma:.3g}; the motion stops at {self.stop_sigma:.3g})")
        # the speed bound (a jog): the jerk-limited stop within that room at the acceleration
        # bound (a stop then planned, `Progress`, plans it at the block's bounds)
        bound = braking_speed_scalar(room, caps.accel, min(caps.jerk, _JERK_BIG)) if room > 0.0 else 0.0
        if bound < caps.speed:
            caps.speed, caps.binding, caps.joint, caps.reason = bound, "singularity", -1, reason
            caps.blocked_by = "singularity" if bound <= 0.0 else ""
