"""Jogging: the tool moves along the commanded twist ξ at a fraction c ∈ [0, 1] of it.

    q̇ = c·J⁺ξ

c changes within the acceleration share of `ProgressLimits` and never exceeds its bounds
(with ξ as the direction, one unit of progress per second is the full twist), so the tool's
velocity is always a non-negative multiple of the command: near a singularity or a joint
limit the arm slows down and stops along ξ, never sideways, and a command that leads away
moves at once.

`JogStage` is the controller's jog stage: it owns the `Jog`, solves the direction
(`ProgressStage`) and reports the bound that holds the progress.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from ..arrays import shared_zeros
from ..errors import RatectlError, SingularityError
from .cycle import Cycle, Motion, _finite_sum, _same
from .progress import ProgressCaps
from .smoothing import SpeedProfile

if TYPE_CHECKING:
    from ..model.chain import Chain
    from .command import Command
    from .progress_stage import ProgressStage

__all__ = ["Jog", "JogStage"]


class Jog:
    """The fraction c ∈ [0, 1] of the commanded twist the tool moves at (see the module
    docstring). Owns c and the last commanded twist."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.c = 0.0
        self.cd = 0.0  # ċ [1/s], with smoothing (c is then jerk-limited)
        self.twist: np.ndarray | None = None
        self.w_prev: np.ndarray | None = None
        self._profile: SpeedProfile | None = None

    def start(self, twist: np.ndarray) -> None:
        """A new commanded twist: c continues from the previous motion projected on it."""
        prev = self.twist
        if prev is not None and self.c > 0.0 and not _same(prev, twist):
            nn = float(twist @ twist)
            ratio = float(prev @ twist) / nn if nn > 0.0 else 0.0
            c = self.c * ratio
            self.c = min(max(c, 0.0), 1.0)
            # (smoothed) ċ likewise, where c is not clipped: a twist that turns a little every
            # period keeps its jerk-limited progress going
            self.cd = self.cd * ratio if 0.0 < c < 1.0 else 0.0
            self.w_prev = None
        self.twist = twist.copy()

    def advance(self, caps: ProgressCaps, dt: float) -> float:
        """c for the coming period: toward min(1, the speed bound), changed by at most the
        acceleration bound times dt (an exceeded speed bound is met at once, which the
        braking laws of the bound keep within amax in a fault-free loop)."""
        goal = min(1.0, caps.speed)
        step = caps.accel * dt
        c = self.c
        c = min(c + step, goal) if c < goal else goal
        self.c = max(c, 0.0)
        return self.c

    def advance_smoothly(self, caps: ProgressCaps, dt: float) -> float:
        """c for the coming period with smoothing: toward min(1, the speed bound) on a
        jerk-limited motion (`SpeedProfile`, within the acceleration and jerk bounds), so that
        the command c·w with its acceleration ċ·w + c·ẇ is a reference the filter meets
        exactly; updates c and ċ."""
        prof = self._profile
        if prof is None:
            prof = self._profile = SpeedProfile(dt)
        goal = max(min(1.0, caps.speed), 0.0)
        nxt = prof.step(self.c, self.cd, goal, amax=max(caps.accel, 1e-9), jmax=max(caps.jerk, 1e-6), dt=dt)
        if nxt is None:  # no jerk-limited motion found: the unsmoothed rule
            self.cd = 0.0
            return self.advance(caps, dt)
        c, cd = nxt
        if c <= 0.0:
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
        self._jogger = Jog()
        # with smoothing (jerk-limited progress bounds) c is jerk-limited and the command a
        # reference with its acceleration, which the filter meets without turning it
        self._smoothed = bool(np.all(np.isfinite(progress.bounds.jmax)))

    def reset(self) -> None:
        """No jog in progress: the next twist starts from the arm's motion."""
        self._jogger.reset()

    def step(self, cyc: Cycle, q, dt, twist) -> Command | None:
        """One period of jogging (`Jog`): q̇ = c·J⁺ξ with c ∈ [0, 1] within the joint limits mapped onto the
        commanded direction (`ProgressLimits`): the tool moves along ξ or slows down along it,
        never sideways."""
        J = cyc.J = self.chain.jacobian(q)
        cyc.e = shared_zeros(6)
        cyc.ep = cyc.eo = 0.0
        cyc.target = False
        jog = self._jogger
        if jog.twist is None and twist.any():  # a first twist: c from the arm's present motion
            moving = J @ self._m.qd
            jog.c = min(max(float(moving @ twist) / float(twist @ twist), 0.0), 1.0)
        jog.start(twist)
        if not twist.any():
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
        w_prime = (w - wp) / (jog.c * dt) if (wp is not None and jog.c > 0.0) else None
        pr = self._progress
        caps = pr.bounds.caps(q, w, dt=dt, sigma=pr.sigma_for_watch(sig_w), w_prime=w_prime,
                              q_lead=self._m.q_lead,
                              exact=lambda q2, share=True: pr.exact_direction(q2, twist, (q, J), share=share))
        c_prev = jog.c
        c = jog.advance_smoothly(caps, dt) if self._smoothed else jog.advance(caps, dt)
        w_rate = (w - wp) / dt if wp is not None else None
        jog.w_prev = w
        cyc.xi = twist * c
        if self._adds_rows:
            halt = self._solve(cyc, q, dt, None)
            if halt is not None:
                return halt
        else:
            cyc.res = pr.direction_result(J, twist, w, sig_w, damping_w)
            cyc.qd = w * c
            if self._smoothed:  # the reference's acceleration ċ·w + c·ẇ, met by the filter
                cyc.qdd_ff = w * jog.cd if w_rate is None else w * jog.cd + w_rate * c
                cyc.approach_qd = cyc.qd
            cyc.active = []
            cyc.scale = 1.0
            cyc.smin = None
        self._progress.flags(cyc, q, caps, c > 0.0, c >= caps.speed * (1.0 - 1e-9) and c < 1.0)
        if c > c_prev and c < min(1.0, caps.speed) * (1.0 - 1e-12):
            cyc.flags.append("acceleration-limited")
            cyc.reasons.append(f"accelerating along the commanded twist within amax ({c:.3g}× the twist)")
            cyc.active.append("acceleration")
        if "velocity" in cyc.active or caps.binding == "velocity":
            cyc.scale = c
        return None
