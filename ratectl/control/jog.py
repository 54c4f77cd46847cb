"""Jogging: the tool moves along the commanded twist ξ at a fraction c ∈ [0, 1] of it (a
smoothed jog whose twist turns back: c ∈ [−1, 0) until it rises through rest).

    q̇ = c·J⁺ξ

c changes within the acceleration share of `ProgressLimits` and never exceeds its bounds
(with ξ as the direction, one unit of progress per second is the full twist), so the tool's
velocity is always a multiple of the command: near a singularity or a joint limit the arm
slows down and stops along ξ, never sideways, and a command that leads away moves at once.
With smoothing, a stop before a singularity is planned as the approach plans its own
(`Progress`); one planned too late brakes harder than its jerk share to end at rest, never
with a jump the filter could not follow. A smoothed twist that turns back against the motion
starts at c < 0 (down to −1) and c rises through rest: the tool decelerates on its line.

`JogStage` is the controller's jog stage: it owns the `Jog`, solves the direction
(`ProgressStage`) and reports the bound that holds the progress.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from ..arrays import shared_zeros
from ..errors import RatectlError, SingularityError
from .approach import Progress, stopping_progress
from .cycle import Cycle, Motion, _finite_sum, _same
from .progress import PLANNED_BRAKE, ProgressCaps
from .smoothing import SpeedProfile

if TYPE_CHECKING:
    from ..model.chain import Chain
    from .command import Command
    from .progress_stage import ProgressStage

__all__ = ["Jog", "JogStage"]

_TURN_SMALL = 0.05  # a new twist within this fraction of its norm of the last one turns it


class Jog:
    """The fraction c ∈ [0, 1] (down to −1 on a smoothed twist that turns back) of the
    commanded twist the tool moves at (see the module docstring). Owns c, ċ, the last
    commanded twist and a stop planned before a singularity."""

    def __init__(self, *, share: float = 1.0) -> None:
        # the share η of amax and jmax the progress bounds give it (the filter meets the rest)
        self.share = share
        self.reset()

    def reset(self) -> None:
        self.c = 0.0
        self.cd = 0.0  # ċ [1/s], with smoothing (c is then jerk-limited)
        self.twist: np.ndarray | None = None
        self.w_prev: np.ndarray | None = None
        self._profile: SpeedProfile | None = None
        self._bounds = (0.0, 0.0)  # the last period's bounds on ċ and c̈ (its stop)
        self._plan = Progress()  # the stop before a singularity's block (smoothed)
        self._plan.L = math.inf
        self._block: float | None = None  # where the planned stop ends, in the plan's progress
        self._block_by = ""  # what blocks there: "singularity" or "position"
        self._unwinding = False  # a planned stop ends on `_unwind`'s profile

    def start(self, twist: np.ndarray, *, signed: bool = False) -> None:
        """A new commanded twist: c continues from the previous motion projected on it.
        ``signed`` (a smoothed jog): a twist that turns back against the motion (c < 0 on
        it) keeps c negative, down to −1, and c then rises through rest on its jerk-limited
        profile: the tool decelerates along the line it moved on, and the filter meets a
        reference that never jumps (cut to rest, its joints would brake each on its own and
        carry the tool sideways). Otherwise c is clipped to [0, 1] (the limiter scales the
        jump of q̇ into amax·dt along the previous motion)."""
        prev = self.twist
        if prev is not None and self.c != 0.0 and not _same(prev, twist):
            self._block = None  # (a stop planned along the previous twist)
            self._unwinding = False
            nn = float(twist.dot(twist))  # (ndarray.dot: the same product as @, cheaper)
            ratio = float(prev.dot(twist)) / nn if nn > 0.0 else 0.0
            c = self.c * ratio
            lowest = -1.0 if signed else 0.0
            self.c = min(max(c, lowest), 1.0)
            # (smoothed) ċ likewise, where c is not clipped: a twist that turns a little every
            # period keeps its jerk-limited progress going
            self.cd = self.cd * ratio if lowest < c < 1.0 else 0.0
            # and its w = J⁺ξ: ẇ then includes the twist's own turn, the acceleration of the
            # reference c·w (a twist in tool axes turns with the tool every period; without
            # ẇ the smoothed filter lagged it and the tool slid across the twist); a twist
            # that jumps starts its w anew
            change = twist - prev
            if not float(change.dot(change)) <= _TURN_SMALL * _TURN_SMALL * nn:
                self.w_prev = None
        self.twist = twist.copy()

    @property
    def stopping(self) -> str:
        """What a stop under way is planned before (smoothed): ``"singularity"`` or
        ``"position"`` (a joint's limit); "" when none is."""
        return self._block_by if (self._block is not None or self._unwinding) else ""

    def stopping_progress(self, dt: float, accel: float | None = None, jerk: float | None = None) -> float:
        """The progress the jog needs to come to rest [twist·s]: one period at c, then the
        jerk-limited stop at the last period's bounds on ċ and c̈ (0 at rest or before the
        first period), or within the given bounds ``accel`` and ``jerk`` (those at a block)."""
        if accel is None or jerk is None:
            accel, jerk = self._bounds
        return stopping_progress(self.c, self.cd, accel, jerk, dt)

    def advance(self, caps: ProgressCaps, dt: float) -> float:
        """c for the coming period: toward min(1, the speed bound), changed by at most the
        acceleration bound times dt (an exceeded speed bound is met at once, which the
        braking laws of the bound keep within amax in a fault-free loop)."""
        self._bounds = (caps.accel, caps.jerk)
        goal = min(1.0, caps.speed)
        step = caps.accel * dt
        c = self.c
        c = min(c + step, goal) if c < goal else goal
        self.c = max(c, 0.0)
        return self.c

    def _stop_due(self, caps: ProgressCaps, by: str, room: float, dt: float) -> bool:
        """Whether a stop before the block ``room`` ahead is to be planned now: before a
        singularity once its braking speed binds (before that, every bound of this period
        holds through ``caps.speed``), before a position limit once the stop the plan would
        make needs half the room (a braking speed that falls as the joint nears its limit is
        more than a jerk-limited c can follow once it binds: the guard then brakes that joint
        alone, off the twist)."""
        if not self.c > 0.0:
            return False
        if by == "singularity":
            return caps.binding == "singularity" and caps.speed < 1.0
        return 2.0 * stopping_progress(self.c, self.cd, PLANNED_BRAKE * caps.accel, caps.jerk, dt) >= room

    def _full_jerk(self, caps: ProgressCaps) -> float:
        """The largest |c⃛| whose reference c·w the filter still meets on every joint: the
        whole of jmax, where the progress bound ``caps.jerk`` is its share η of it."""
        return caps.jerk / self.share if self.share > 0.0 else caps.jerk

    def _unwind(self, prof: SpeedProfile, caps: ProgressCaps, dt: float) -> float:
        """One period of the end of a planned stop that can no longer end at rest at its own
        jerk: c goes to rest on a jerk-limited profile (`SpeedProfile`) at the whole jmax along
        w (`_full_jerk`), braking no harder than it does, and where even that cannot ramp the
        braking out before rest, c dips below 0 and rises back to it: the tool ends its stop
        with a small motion back along the twist, never with a jump of the reference's
        acceleration, which the filter's joints would each ramp out on their own, off the
        twist. Updates c and ċ; the stop (`stopping`) stays in force until c is at rest.
        ``prof``: the jog's `SpeedProfile`."""
        self._unwinding = True
        self._block = None
        nxt = prof.step(self.c, self.cd, 0.0, amax=max(abs(self.cd), caps.accel / self.share, 1e-9),
                        jmax=max(self._full_jerk(caps), 1e-6), dt=dt)
        c, cd = nxt if nxt is not None else (0.0, 0.0)
        if abs(c) <= 1e-12 and abs(cd) <= 1e-9:
            c, cd = 0.0, 0.0
        if c == 0.0 and cd == 0.0:
            self._unwinding = False
        self.c, self.cd = c, cd
        return c

    def advance_smoothly(self, caps: ProgressCaps, dt: float) -> float:
        """c for the coming period with smoothing: toward min(1, the speed bound) on a
        jerk-limited motion (`SpeedProfile`, within the acceleration and jerk bounds), so that
        the command c·w with its acceleration ċ·w + c·ẇ is a reference the filter meets
        exactly; updates c and ċ."""
        prof = self._profile
        if prof is None:
            prof = self._profile = SpeedProfile(dt)
        self._bounds = (caps.accel, caps.jerk)
        if self._unwinding:
            return self._unwind(prof, caps, dt)
        plan = self._plan
        by = caps.room_by
        # a block ahead: a singularity's σ_min of the stop, or a joint's position limit less
        # the jog's margin inside it
        room = caps.room - caps.room_margin if by else math.inf
        if self._block is not None and (by != self._block_by or caps.room_peak):
            # a stop planned before, whose block this period's look-ahead no longer sees (a
            # stopping distance that shrank as the stop went on; no block, or only another
            # kind, such as a joint's far limit, while the stop is for a singularity), or a
            # peak of σ_min seen again (its estimate from nearer is no earlier): it ends
            # there, at rest, unless this period's block is nearer
            planned = self._block - plan.s
            if planned <= room:
                room, by = planned, self._block_by
        if room < math.inf and (self._block is not None or self._stop_due(caps, by, room, dt) or (
                by == "singularity" and self._stop_due(caps, "position", caps.limit_room, dt))):
            # (a singularity's block may hide a joint's limit just beyond it: a stop that the
            # limit needs is due by the limit's rule, and planned before the nearer block)
            # the stop is planned there, as the approach plans its own (`Progress`, at the
            # block's bounds; late before a singularity, it runs on a little past it), and
            # kept until the jog rests (a speed bound that falls faster than a jerk-limited c
            # can follow, or a stop cut short, would leave the filter's joints running on
            # while c·w turns with w)
            self._block = plan.s + max(room, 0.0)
            self._block_by = by
            plan.sd, plan.sdd = self.c, self.cd
            plan.advance(replace(caps, free_speed=min(1.0, caps.free_speed), room=max(room, 0.0),
                                 room_by=by), dt)
            ending = plan.sdd < 0.0 and plan.sdd * plan.sdd > 2.0 * self._full_jerk(caps) * max(plan.sd, 0.0)
            if ending and room > 0.0:
                # the plan reaches rest before its block still braking harder than even the
                # whole jmax ramps out (a block that came nearer, bounds that shrank on the
                # way): cut to rest there, the filter's joints would each ramp their braking
                # out on their own and carry the tool sideways; the stop ends on the line
                # instead (`_unwind`). Past the block (a stop that came too late and ran on
                # below the stop's σ_min, where |J⁺ξ| grows like 1/σ_min) a motion back along
                # ξ asks the joints for more than the filter's bounds: there it is cut
                return self._unwind(prof, caps, dt)
            self.c, self.cd = (plan.sd, plan.sdd) if plan.sd > 0.0 else (0.0, 0.0)
            if self.c == 0.0:
                self._block = None
            return self.c
        self._block = None
        goal = max(min(1.0, caps.speed), 0.0)
        nxt = prof.step(self.c, self.cd, goal, amax=max(caps.accel, 1e-9), jmax=max(caps.jerk, 1e-6), dt=dt)
        if nxt is None:  # no jerk-limited motion found: the unsmoothed rule
            self.cd = 0.0
            return self.advance(caps, dt)
        c, cd = nxt
        if c <= 0.0 and self.c >= 0.0:  # (a stop ends at rest; a motion back, c < 0, rises through it)
            c, cd = 0.0, 0.0
        self.c, self.cd = c, cd
        return c


class JogStage:
    """The controller's jog stage (stage 3 for a twist alone).

    Args:
        chain: the arm.
        progress: the bounds and flags shared with the approach (`ProgressStage`).
        motion: the controller's last command (`Motion`).
        adds_rows: the solver adds constraint rows of its own (e.g. collision avoidance): the
            scaled twist is solved again under them and the solver's bounds (otherwise the
            command is the direction's answer scaled, c·w, and the limiter bounds it
            uniformly: a box would clip joints one by one and turn the tool's motion).
        solve, halt: the controller's solve stage and safe halt.
    """

    def __init__(self, chain: Chain, progress: ProgressStage, motion: Motion, *, adds_rows: bool,
                 solve: Callable[..., Command | None], halt: Callable[..., Command]) -> None:
        self.chain = chain
        self._progress = progress
        self._m = motion
        self._adds_rows = adds_rows
        self._solve = solve
        self._halt = halt
        self._jogger = Jog(share=progress.bounds.accel_share)
        self._idle = True  # the jog is as `reset` leaves it (a servo cycle resets it only then)
        # with smoothing (jerk-limited progress bounds) c is jerk-limited and the command a
        # reference with its acceleration, which the filter meets without turning it
        self._smoothed = bool(np.all(np.isfinite(progress.bounds.jmax)))

    def reset(self) -> None:
        """No jog in progress: the next twist starts from the arm's motion."""
        if not self._idle:  # (a cycle of another mode calls this every period)
            self._jogger.reset()
            self._idle = True

    def step(self, cyc: Cycle, q, dt, twist) -> Command | None:
        """One period of jogging (`Jog`): q̇ = c·J⁺ξ with c ∈ [0, 1] within the joint limits mapped onto the
        commanded direction (`ProgressLimits`): the tool moves along ξ or slows down along it,
        never sideways."""
        self._idle = False
        J = cyc.J = self.chain.jacobian(q)
        cyc.e = shared_zeros(6)
        cyc.ep = cyc.eo = 0.0
        cyc.target = False
        jog = self._jogger
        nonzero = any(twist.tolist())  # (twist.any(), cheaper on 6 floats)
        if jog.twist is None and nonzero:  # a first twist: c from the arm's present motion
            moving = J.dot(self._m.qd)
            jog.c = min(max(float(moving.dot(twist)) / float(twist.dot(twist)), 0.0), 1.0)
        jog.start(twist, signed=self._smoothed)
        if not nonzero:
            jog.c = 0.0
            cyc.xi = twist.copy()
            return self._solve(cyc, q, dt, None)
        try:
            w, sig_w, damping_w = self._progress.direction_qd(J, twist, q, dt)
        except SingularityError as err:
            return self._halt(q, dt, f"singular: {err}", status="singular", sigma_min=err.sigma_min)
        except (RatectlError, np.linalg.LinAlgError) as err:
            return self._halt(q, dt, f"solver failed: {err}")
        if not _finite_sum(w):
            return self._halt(q, dt, "solver returned a non-finite q̇")
        wp = jog.w_prev
        dw = None if wp is None else w - wp
        w_prime = dw / (jog.c * dt) if (dw is not None and jog.c > 0.0) else None
        pr = self._progress
        caps = pr.bounds.caps(q, w, dt=dt, sigma=pr.sigma_for_watch(sig_w), w_prime=w_prime,
                              q_lead=self._m.q_lead, ahead=lambda a, j: jog.stopping_progress(dt, a, j),
                              exact=lambda q2, share=True: pr.exact_direction(q2, twist, (q, J), share=share))
        c_prev = jog.c
        c = jog.advance_smoothly(caps, dt) if self._smoothed else jog.advance(caps, dt)
        jog.w_prev = w
        cyc.xi = twist * c
        if self._adds_rows:
            halt = self._solve(cyc, q, dt, None)
            if halt is not None:
                return halt
        else:
            cyc.res = pr.direction_result(J, twist, w, sig_w, damping_w)
            if self._smoothed:  # the reference's acceleration ċ·w + c·ẇ, met by the filter
                # the filter meets its reference at the end of the period, where the arm's w
                # is w + ẇ·dt (the tool's velocity c·J w stays on the twist there, not one
                # period behind it: a lag of ẇ·dt with no feedback to take it back)
                w_end = w if dw is None else w + dw
                cyc.qd = w_end * c
                cyc.qdd_ff = w_end * jog.cd if dw is None else w_end * jog.cd + dw / dt * c
                cyc.approach_qd = cyc.qd
            else:
                cyc.qd = w * c
            cyc.active = []
            cyc.scale = 1.0
            cyc.smin = None
        at_bound = c >= caps.speed * (1.0 - 1e-9) and c < 1.0
        stop_by = jog.stopping
        # a stop planned before a block goes on to rest (whatever this period's speed bound
        # says): it is what holds the motion (before a position limit, once it slows the jog)
        if stop_by and (stop_by == "singularity" or jog.cd < 0.0
                        or c_prev >= c < min(1.0, caps.free_speed) * (1.0 - 1e-9)):
            if caps.binding != stop_by:
                caps.binding = stop_by
                if stop_by == "singularity":
                    caps.reason = ("stopping before a singularity: the commanded direction lowers σ_min "
                                   f"(σ_min = {caps.sigma:.3g}) on its way")
                else:
                    caps.reason = caps.room_reason or "stopping before a joint's position limit"
            at_bound = True
        self._progress.flags(cyc, q, caps, c != 0.0, at_bound)
        if c_prev < c < min(1.0, caps.speed) * (1.0 - 1e-12) and not stop_by:
            cyc.flags.append("acceleration-limited")
            cyc.reasons.append(f"accelerating along the commanded twist within amax ({c:.3g}× the twist)")
            cyc.active.append("acceleration")
        if "velocity" in cyc.active or caps.binding == "velocity":
            cyc.scale = c
        return None
