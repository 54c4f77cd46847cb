"""The controller's servo stage: the approach to a target, `Servo`.

A target alone is a servo: the tool moves on the straight line to it (`StraightApproach`),
a jerk-limited progress within the joint limits mapped onto it (`ProgressLimits`, through
the `ProgressStage` it shares with the jog), and, where that line is blocked (a limit or a
singularity on the way) and ``blocked="joint-space"``, in joint space to an
inverse-kinematics solution of the target (`JointLine`; the IK core
`ratectl.solvers.ik`). `Servo.arrival` then says ``target-reached`` or
``target-unreachable``. The stage owns the approach, the joint line and what it learnt
about the current target (the IK alternative tried, the target found out of reach).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from ..errors import RatectlError, SingularityError
from ..solvers.base import DirectionTwist, SolveResult
from ..solvers.ik import ik_iterate
from ..spatial import pose_error_into, pose_error_rows
from .approach import AT_BLOCK, JointLine, StraightApproach
from .cycle import Cycle, Motion, _finite_sum, _same
from .progress_stage import with_kind

if TYPE_CHECKING:
    from ..model.chain import Chain
    from .command import Command
    from .progress_stage import ProgressStage
    from .smoothing import VelocityFilter

__all__ = ["Servo"]

_AT_LIMIT = 1e-4  # [rad or m]: a joint-line goal this close to the limit the joint stands at stays put
_LAG_MAX = 0.02  # [m, weighted]: the approach's progress stops when the arm is this far behind it


def _creeping(caps, speed: float, dt: float) -> bool:
    """A progress that creeps into a singularity's block by less than `AT_BLOCK` per period
    stands at it: that room, half the first-order distance to the σ_min of the stop, is
    estimated anew each period and shrinks with the progress that creeps into it, which
    then never quite comes to rest (a joint limit's room is exact: at rest there)."""
    return caps.room_by == "singularity" and speed * dt <= AT_BLOCK


def _twist_within(t: list[float], vtol: float, wtol: float) -> bool:
    """A twist [v; ω] (floats) with |v| ≤ ``vtol`` [m/s] and |ω| ≤ ``wtol`` [rad/s]."""
    return math.hypot(t[0], t[1], t[2]) <= vtol and math.hypot(t[3], t[4], t[5]) <= wtol


class Servo:
    """The servo stage (stage 3 for a target alone; see the module docstring).

    Args:
        chain: the arm.
        progress: the bounds and flags shared with the jog (`ProgressStage`).
        motion: the controller's last command (`Motion`).
        filter: the controller's smoothing filter or None (with one, the reference's
            end-of-period speed and acceleration are commanded: the filter integrates).
        gain: the feedback gain K (6,) [1/s].
        position_tolerance [m], orientation_tolerance [rad]: "target reached".
        blocked: ``"joint-space"`` or ``"stop"`` where the straight line is blocked.
        solve, adopt, halt: the controller's solve stage (`SolveStage.solve`, `SolveStage.adopt`)
            and safe halt.
    """

    def __init__(self, chain: Chain, progress: ProgressStage, motion: Motion, filter: VelocityFilter | None,
                 *, gain: np.ndarray, position_tolerance: float, orientation_tolerance: float, blocked: str,
                 solve: Callable[..., Command | None], adopt: Callable[..., Command | None],
                 halt: Callable[..., Command]) -> None:
        self.chain = chain
        self._progress = progress
        self._m = motion
        self.filter = filter
        self.gain = gain
        kmax = float(gain.max())
        self._inv_kmax = 1.0 / kmax if kmax > 0.0 else 0.0
        self.position_tolerance = position_tolerance
        self.orientation_tolerance = orientation_tolerance
        self.blocked = blocked
        self._solve = solve
        self._adopt = adopt
        self._halt = halt
        # an arm of fewer than 6 joints cannot follow a line in 6-D: its approach starts anew
        # from the measured pose every period (straight toward the target from where it is)
        self._pursuit = chain.dof < 6
        self._straight = StraightApproach(length=chain.characteristic_length)
        self._joint_line = JointLine()
        self._ik_tried: np.ndarray | None = None  # the last target an IK alternative was sought for
        self._line_blocked = ""
        self._lag_max = _LAG_MAX
        self._idle = False  # the approach is as `forget` leaves it (a jog cycle forgets only then)
        self.reset()

    def reset(self) -> None:
        """No approach, and nothing known about any target."""
        self.forget()
        self._unreachable: np.ndarray | None = None  # the target last found out of reach
        self._unreachable_block = ""  # the block it was found at ("" for a best effort)

    def step(self, cyc: Cycle, q, dt, target) -> Command | None:
        """The straight approach (`StraightApproach`): fk and J at q, the segment (a new one
        when the target changed), one period of the progress within the joint limits mapped
        onto it (`ProgressLimits`), and the command q̇ = ṡ̄·w + solver(K·e_ref) for the twist
        ξ = ṡ̄·d + K·e_ref: the mean progress speed of the period along the direction's own
        answer w (exact where J is regular) plus the solved feedback on the error to the
        reference pose T(s), both without the limits (the limiter's), from one solver entry
        on J (`Solver.solve_direction_twist`)."""
        self._idle = False
        T, J = self.chain.fk_jacobian(q)
        cyc.J = J
        cyc.target = True
        ap = self._straight
        jl = self._joint_line
        if jl.target is not None:
            if _same(target, jl.target):
                return self._joint_servo(cyc, q, dt, target, T, J)
            jl.reset()  # a new target: a straight line again, from where the arm is
            ap.reset()
        t = target.tolist()
        self._segment(ap, target, t, T, J, dt)
        e = cyc.e = np.zeros(6)
        cyc.ep, cyc.eo = pose_error_rows(e, t, Tl := T.tolist())  # (the rows of both poses, once)
        e_ref = np.zeros(6)
        pose_error_rows(e_ref, ap.pose_rows(ap.s), Tl)
        lag = ap.weighted_norm(e_ref)
        if lag > self._lag_max:
            # the arm is held off its line (a solver's extra rows such as collision avoidance,
            # or a robot that lags): a new straight segment from where it is, with its
            # velocity; its acceleration is the transient of being held off (with smoothing,
            # the filter's), and carried onto a short line it can leave no jerk-limited stop
            # on it: the arm overshoots, is held off again, and circles the target
            self._restart_from_arm(ap, target, T, J)
            e_ref[:] = 0.0
            lag = 0.0
            cyc.reasons.append("held off the straight line by more than "
                               f"{self._lag_max * 1e3:.3g} mm: a new line from where the arm is")
        caps = None
        w = None
        speed = 0.0
        # the feedback is solved without the limits (a box clips joints one by one and turns
        # the tool off its line): the progress is already within them, the limiter scales the rest
        cyc.xi = self.gain * e_ref
        if ap.L > 0.0:
            ans = self._direction_twist(cyc, q, dt, J, ap.d)
            if not isinstance(ans, DirectionTwist):
                return ans  # (the halt's command)
            w, sig_w = ans.w, ans.sigma
            if ap.end_accel == math.inf and not self._pursuit and ap.settled:
                self._end_bounds(ap, q, target, dt)  # (a target that moves every period: not yet)
            pr = self._progress
            caps = pr.bounds.caps(q, w, dt=dt, sigma=pr.sigma_for_watch(sig_w), w_prime=ap.w_prime(w),
                                  exact=lambda q2, share=True: pr.exact_direction(q2, ap.d, (q, J),
                                                                                  share=share),
                                  ahead=lambda a, j: ap.stopping_progress(dt, a, j))
            dw = None if ap.w_prev is None or self.filter is None else w - ap.w_prev
            w_rate = None if dw is None else dw / dt  # ẇ
            # the filter meets its reference at the end of the period, where the arm's w is
            # w + ẇ·dt (the progress's velocity stays on the line there, not one period
            # behind it), on a line whose target stayed put (a target that moves starts a
            # line every period, and ẇ then holds the line's turn as well)
            w_end = w + dw if dw is not None and ap.settled else w
            # (the room ahead is measured from the arm; the reference leads it along the line)
            speed = ap.advance(caps, dt, speed_scale=max(0.0, 1.0 - lag / self._lag_max),
                               lead=ap.weighted_dot(e_ref, ap.d))
            if self.filter is not None:
                # the filter integrates exactly: its target is the state at the end of the
                # period (ṡ₁ with s̈₁), where q + q̇·dt needs the period's mean speed
                speed = ap.sd
            ap.w_prev = w
            w = w_end  # (the direction sent: the command's progress part and its acceleration)
            if speed != 0.0:
                # the progress along the line on its own direction w (exact where J is regular),
                # not the solver's answer for ṡ·d, which a constant damping shrinks and turns
                cyc.xi = cyc.xi + ap.d * speed
                cyc.qd = cyc.qd + w * speed
            cyc.res = ans.result(cyc.xi, cyc.qd)
        else:
            halt = self._solve(cyc, q, dt, None, bounded=False)
            if halt is not None:
                return halt
        if w is not None and self.filter is not None:
            # the reference's acceleration s̈·w + ṡ·ẇ, which the filter then meets without lag
            cyc.qdd_ff = w * ap.sdd if w_rate is None else w * ap.sdd + w_rate * ap.sd
            cyc.approach_qd = cyc.qd
        if caps is not None:
            moving = ap.sd > 0.0 or speed > 0.0
            cyc.approach = ap.s / ap.L
            if ap.blocked:  # the stop is planned before a block (a limit, a singularity)
                at_block = ap.room_left <= AT_BLOCK and (not moving or _creeping(caps, speed, dt))
                caps.binding, caps.reason = caps.room_by, caps.room_reason
                block: str | None = caps.room_reason if at_block else ""
                if block and self.blocked == "joint-space":
                    block = self._try_joint_line(cyc, q, target, block)
                if block is not None:  # at the block, or braking before it
                    caps.blocked_by = caps.room_by if at_block else ""
                    self._progress.flags(cyc, q, caps, moving, True)
                    cyc.blocked = block
                # (else the arm goes on in joint space: it is not halted at the block, and the
                # reason says where the line is blocked and what the arm does instead)
            else:
                if caps.binding in ("position", "singularity"):
                    caps.binding = ""  # (those bounds are the room ahead, which is not the stop)
                self._progress.flags(cyc, q, caps, moving, ap.sd >= caps.free_speed * (1.0 - 1e-9))
        return None

    def _segment(self, ap: StraightApproach, target, t: list[list[float]], T, J, dt) -> None:
        """The segment of this period: a first target's from the measured pose ``T`` and the
        arm's motion; a new target's from the reference, which goes on without a jump (an
        arm of fewer than 6 joints: from the measured pose every period); the same target's
        segment kept, or, at rest on the run-on past it (a stop too late to rest on it, within
        `AT_BLOCK` [m, m/s], as a jerk-limited stop ends), a new one back along the same
        line. ``t``: the target's rows as floats."""
        if not ap.same_target(t) or self._pursuit:
            if ap.target is None:
                ap.retarget(target, T, J.dot(self._m.qd), J.dot(self._m.qdd))
            elif self._pursuit:  # (the progress's own motion carried on)
                ap.retarget(target, T, ap.sd * ap.d, ap.sdd * ap.d)
            else:
                ap.retarget_from_reference(target, dt=dt, rows=t)
            return
        ap.hold_target()
        if ap.past_end and ap.L - ap.s <= AT_BLOCK and ap.sd <= AT_BLOCK:
            ap.retarget_from_reference(target, rows=t)

    def _direction_twist(self, cyc: Cycle, q, dt, J, d) -> DirectionTwist | Command:
        """The line's direction w and the feedback c = solver(J, ξ) for ξ = ``cyc.xi``, on the
        same J (`ProgressStage.direction_twist`), c taken as the cycle's command
        (`SolveStage.adopt`); the halt's command when the solver fails or c is not finite."""
        try:
            ans = self._progress.direction_twist(J, d, cyc.xi, q, dt)
        except SingularityError as err:
            return self._halt(q, dt, f"singular: {err}", status="singular", sigma_min=err.sigma_min,
                              error=cyc.e, ep=cyc.ep, eo=cyc.eo)
        except (RatectlError, np.linalg.LinAlgError) as err:
            return self._halt(q, dt, f"solver failed: {err}", error=cyc.e, ep=cyc.ep, eo=cyc.eo)
        halt = self._adopt(cyc, q, dt, ans, ans.qd)
        return ans if halt is None else halt

    def _restart_from_arm(self, ap: StraightApproach, target, T, J) -> None:
        """A new line from the arm's pose ``T`` to ``target``, with the commanded motion J q̇
        projected on it, but no faster than the old reference moved along it: the command
        also carries the feedback on the lag that ends the old line, so for an arm that
        applies only part of each command (a velocity servo with a gain below 1) it grows
        with the lag, and lines restarted at it would ratchet the progress up until the stop
        from that speed ran the arm past the target."""
        planned = ap.sd * ap.d
        ap.retarget(target, T, J.dot(self._m.qd), np.zeros(6))
        ap.restart(min(ap.sd, max(ap.weighted_dot(planned, ap.d), 0.0)), 0.0)

    def _end_bounds(self, ap: StraightApproach, q, target, dt) -> None:
        """The progress's acceleration bound at the end of the line, where the arm will be:
        from the target's inverse kinematics (the IK core `ratectl.solvers.ik`, from the
        measured q, on the arm's branch) and the direction's q̇ there; a stop planned within
        the smaller of it and the present bound stays feasible as J changes on the way.
        Once per line (NaN when no solution was found: the present bound alone)."""
        res = ik_iterate(self.chain, target, q, tol_position=self.position_tolerance,
                         tol_orientation=self.orientation_tolerance, max_iter=30, damping=0.05,
                         max_step=0.2)
        ap.end_accel = math.nan
        if not res.converged:
            return
        q_end = np.array(res.q)
        try:
            J_end = self.chain.jacobian(q_end)
            w_end = self._progress.direction_qd(J_end, ap.d, q_end, dt)[0]
        except (RatectlError, np.linalg.LinAlgError):
            return
        if _finite_sum(w_end):
            ap.end_accel = self._progress.bounds.caps(q_end, w_end, dt=dt).accel

    def forget(self) -> None:
        """No approach in progress: the next target starts a new one from where the arm is."""
        if self._idle:  # (a cycle of another mode calls this every period)
            return
        self._straight.reset()
        self._joint_line.reset()
        self._ik_tried = None
        self._idle = True

    def _try_joint_line(self, cyc: Cycle, q, target, block: str) -> str | None:
        """The straight line is blocked where the arm stands (by ``block``, a sentence): the
        alternative is a straight line in joint space (`JointLine`) to an inverse-kinematics
        solution of the target on the arm's own branch (the IK core `ratectl.solvers.ik`,
        from the measured q, steps of at most 0.1 rad, within the joint limits). Taken when
        that solution is verified (the pose within a tenth of the tolerances): then the tool
        leaves its line, the reason says why, and None is returned; otherwise the line stays
        blocked (``target-unreachable``) and the block's sentence is returned. Tried once
        per target."""
        if self._ik_tried is not None and _same(target, self._ik_tried):
            return block
        self._ik_tried = target.copy()
        res = ik_iterate(self.chain, target, q, tol_position=0.1 * self.position_tolerance,
                         tol_orientation=0.1 * self.orientation_tolerance, max_iter=200,
                         damping=0.05, max_step=0.1)
        if not res.converged:
            return block + "; no inverse-kinematics solution within the joint limits from here"
        q_goal = np.array(res.q)
        if self.filter is not None:
            q_goal = self._off_held_limits(q, q_goal, target)
        self._joint_line.start(target, q, q_goal, self._m.qd)
        self._line_blocked = block
        cyc.reasons.append(f"the straight line is blocked ({block}): moving in joint space to an "
                           "inverse-kinematics solution of the target instead (the tool leaves the line)")
        return None

    def _off_held_limits(self, q, q_goal, target):
        """A joint that the solution puts on a position limit it already stands at (within
        `_AT_LIMIT`) stays where it is, if the pose is then still within the tolerances:
        the smoothed position guard holds a joint at rest that close to its limit, and the
        joint line, which the guard's clip scales as a whole, would then hold every joint."""
        ch = self.chain
        held = (np.abs(q_goal - q) < _AT_LIMIT) & ((q_goal >= ch.upper) | (q_goal <= ch.lower))
        if not held.any():
            return q_goal
        q_near = np.where(held, q, q_goal)
        e = np.zeros(6)
        ep, eo = pose_error_into(e, target, ch.fk(q_near))
        return q_near if ep <= self.position_tolerance and eo <= self.orientation_tolerance else q_goal

    def _joint_servo(self, cyc: Cycle, q, dt, target, T, J) -> Command | None:
        """One period on the `JointLine`: q̇ = ṡ̄·u + K·(q(s) − q) (the progress within the
        joint limits, w = u; feedback on the joint reference), its tool twist J q̇ reported."""
        jl = self._joint_line
        e = cyc.e = np.zeros(6)
        cyc.ep, cyc.eo = pose_error_into(e, target, T)
        q_ref = jl.q_at(jl.s)
        caps = self._progress.bounds.caps(q, jl.u, dt=dt)
        speed = jl.advance(caps, dt)
        if self.filter is not None:
            speed = jl.sd
            cyc.qdd_ff = jl.u * jl.sdd
        qd = jl.u * speed + (q_ref - q) * (1.0 / self._inv_kmax if self._inv_kmax > 0.0 else 0.0)
        cyc.qd = cyc.approach_qd = qd
        cyc.xi = J.dot(qd)
        cyc.res = SolveResult(qd=qd, achieved=cyc.xi, task_error=np.zeros(6), damping=0.0,
                              sigma_min=float("nan"), method="joint-line")
        cyc.approach = jl.s / jl.L if jl.L > 0.0 else 1.0
        cyc.reasons.append(f"moving in joint space to an inverse-kinematics solution of the target "
                           f"({cyc.approach:.0%}): the straight line is blocked ({self._line_blocked})")
        return None

    def arrival(self, cyc: Cycle, target: np.ndarray) -> None:
        """``target-reached`` or ``target-unreachable`` (first in the flags, so it is the
        status). Reached: within the tolerances with the command at rest, its tool twist
        J q̇ within K·tolerance (linear and angular; what the proportional law asks at the
        tolerance). Unreachable: outside the tolerances with J q̇, and J (q̇ + q̈/K) one
        time constant ahead, below 1 % of that: the arm has stopped short, no motion within
        the limits lowers the error from here. Where the line is blocked at the arm
        (``cyc.blocked``), unreachable with J q̇ within K·tolerance, as for reached. Once said
        for a target, it holds while J q̇ stays within the bound it was said at (K·tolerance
        at a block, 10 % of it at a best effort)."""
        within = cyc.ep <= self.position_tolerance and cyc.eo <= self.orientation_tolerance
        ap = self._straight
        said = self._unreachable is not None and _same(target, self._unreachable)
        if not (within or cyc.blocked or said) and (
                self._joint_line.target is not None  # on its way in joint space (see below)
                or (not self._pursuit and ap.target is not None and ap.s < ap.L and ap.sdd > 0.0)):
            return  # (neither status, whatever the twist: not computed)
        k = self.gain.tolist()  # (floats: cheaper than two numpy reductions)
        vtol = max(k[0], k[1], k[2]) * self.position_tolerance
        wtol = max(k[3], k[4], k[5]) * self.orientation_tolerance
        t = cyc.J.dot(cyc.qd).tolist()  # (ndarray.dot: the same product as @, cheaper)
        if not _twist_within(t, vtol, wtol):
            return
        if within:
            cyc.flags.insert(0, "target-reached")
            return
        block = cyc.blocked or (self._unreachable_block if said else "")
        if block:  # the straight line is blocked where the arm stands (or stood, this target)
            if not said:
                self._unreachable, self._unreachable_block = target.copy(), block
            if cyc.kind:  # the flags said the block with its kind: said once, here
                named = with_kind(block, cyc.kind)
                if named in cyc.reasons:
                    cyc.reasons.remove(named)
                block = named
            cyc.flags.insert(0, "target-unreachable")
            # (the distance left, not a share of the line: a line restarted from where the arm
            # is, held off it or after the target moved, begins anew at 0 %)
            cyc.reasons.insert(0, f"stopped {cyc.ep * 1e3:.3g} mm / {math.degrees(cyc.eo):.3g}° from the "
                               f"target: the straight line to it is blocked: {block}")
            return
        # (here the arm is on its line or at its end: not in joint space, which is on its way,
        # taken this period where the line is blocked; nor on a line whose progress speeds up,
        # from rest its first periods are slow: on its way too, unless the arm was found
        # stopped short of this target already)
        # stopped short: below 1 % of that, now and one time constant ahead (an arm that
        # creeps toward a singular target, damped, is still on its way); once said for this
        # target, below 10 % now (the last settling does not flicker back to "regular", nor
        # does a joint held at its limit whose command ticks between rest and a few µrad/s,
        # an acceleration of mrad/s² that one time constant ahead looks like a start)
        vtol *= 0.1 if said else 0.01
        wtol *= 0.1 if said else 0.01
        if not _twist_within(t, vtol, wtol):
            return
        if not said:
            if not _twist_within(cyc.J.dot(cyc.qd + cyc.qdd * self._inv_kmax).tolist(), vtol, wtol):
                return
            self._unreachable, self._unreachable_block = target.copy(), ""
        cyc.flags.insert(0, "target-unreachable")
        cyc.reasons.insert(0, f"stopped at a best effort {cyc.ep * 1e3:.3g} mm / "
                           f"{math.degrees(cyc.eo):.3g}° from the target: no motion within the limits "
                           "lowers the pose error from here (out of reach, or held by a limit or "
                           "a local minimum)")
