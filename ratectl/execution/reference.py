"""The reference along a path: progress, pose and feed-forward — one implementation for
`ratectl.follow` and `ratectl.run`.

A `PathReference` holds the *schedule time* τ [s] of a path's progress and evaluates, at τ,

* the path parameter s(τ) [m] and the target pose P(s(τ)) (4×4);
* with a governor plan (`ratectl.planning.GovernorPlan`, sampled every ``plan.dt``): the
  joint-velocity feed-forward that carries the planned joints from τ to τ + h,

      q̇_ff = r · (q(τ + h) − q(τ)) / h,

  with q(τ) the plan's joint positions (linear between its samples), h the period ahead and
  r ∈ [0, 1] the progress rate (below); for a jerk-limited executor also the mean of that
  secant velocity and the next one, and their difference per period (``qdd_ff``);
* without a plan: the path's own time law, ``twist = dP/ds · ṡ(τ)``.

`follow` advances τ by exactly one period per step (r = 1): step k is the plan's sample k.
`run` advances τ by the *measured* period of the robot, ``τ ← τ + r·dt``, and re-times the
progress from the measured state (`PathReference.advance`): the measured joints are located on
the plan (the nearest planned configuration, searched forward from the last match), which gives
the robot's own progress τ_m; the reference may lead it by at most ``lead`` seconds of
schedule. The rate is

    r* = clip(2 (lead − (τ − τ_m)) / lead, 0, 1)    (1 up to half the lead, 0 at the lead),

reached at most ``1/ramp`` per second, so a robot that lags — held at a limit, slowed by its
own servo, stopped by friction — holds the reference back instead of letting it run away.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from ..paths import Path
    from ..planning import GovernorPlan

__all__ = ["PathReference", "Sample"]

_SNAP = 1e-9  # fractions of a plan period below this count as on the sample


class Sample:
    """What the controller is given at one schedule time (plain attributes, made per call)."""

    __slots__ = ("s", "pose", "twist", "qd_ff", "qdd_ff")

    def __init__(self, s: float, pose: np.ndarray, twist: np.ndarray | None,
                 qd_ff: np.ndarray | None, qdd_ff: np.ndarray | None) -> None:
        self.s, self.pose, self.twist, self.qd_ff, self.qdd_ff = s, pose, twist, qd_ff, qdd_ff


class PathReference:
    """Progress along ``path``: governed by ``plan``, or on the path's own time law (``plan`` None).

    Args:
        path: the Cartesian path.
        plan: the governor's plan, or None (the path's time law).
        lead: the most the reference may lead the measured progress [s of schedule] (`advance`).
        ramp: the time the rate takes to go from 1 to 0 or back [s] (`advance`).

    Attributes:
        tau: the schedule time [s]; rate: the progress rate r (1: on schedule);
        tau_measured: the schedule time of the measured state (`advance`) [s].
    """

    def __init__(self, path: Path, plan: GovernorPlan | None, *, lead: float = 0.05,
                 ramp: float = 0.1) -> None:
        self.path, self.plan = path, plan
        self.lead, self.ramp = float(lead), float(ramp)
        self.tau = 0.0
        self.rate = 1.0
        self.tau_measured = 0.0
        self._k_measured = 0
        if plan is not None:
            self.duration = float(plan.duration)
            self.end_s = float(plan.s[-1])
            # where the schedule ends: the path end, or where the governor had to stop
            self.end_pose = path.pose_at(self.end_s) if not plan.joint_path.complete else path.end
        else:
            self.duration = float(path.duration)
            self.end_s = float(path.length)
            self.end_pose = path.end

    @property
    def finished(self) -> bool:
        """True once the schedule has run out (τ at its duration)."""
        return self.tau >= self.duration - 1e-12

    # ------------------------------------------------------------------ evaluation
    def _index(self, tau: float) -> tuple[int, float]:
        """(k, fraction) of schedule time τ on the plan's samples, clamped to the plan."""
        plan = self.plan
        assert plan is not None
        u = min(max(tau / plan.dt, 0.0), len(plan) - 1.0)
        k = int(math.floor(u + _SNAP))
        frac = u - k
        if frac < _SNAP:
            frac = 0.0
        if k >= len(plan) - 1:
            return len(plan) - 1, 0.0
        return k, frac

    def _planned_q(self, tau: float) -> np.ndarray:
        plan = self.plan
        assert plan is not None
        k, f = self._index(tau)
        return plan.q[k] if f == 0.0 else plan.q[k] + f * (plan.q[k + 1] - plan.q[k])

    def _secant(self, tau: float, h: float) -> np.ndarray:
        """(q(τ + h) − q(τ)) / h: the planned joint velocity over the period ahead."""
        plan = self.plan
        assert plan is not None
        k, f = self._index(tau)
        if f == 0.0 and abs(h - plan.dt) <= _SNAP * plan.dt:
            return plan.qd_ff[k]  # on a sample, one plan period ahead: the plan's own secant
        return (self._planned_q(tau + h) - self._planned_q(tau)) / h

    def at(self, h: float, *, smoothed: bool = False) -> Sample:
        """The reference at the current τ for a period ``h`` [s] ahead.

        ``smoothed``: for a jerk-limited executor, ``qd_ff`` is the mean of this period's and
        the next period's secant velocity and ``qdd_ff`` their difference over h (the plan's
        continuous velocity and acceleration at the end of the period)."""
        tau, path, plan = self.tau, self.path, self.plan
        if plan is None:
            s, sd, _ = path.progress(tau)
            return Sample(s, path.pose_at(s), path.twist_at(s, sd=sd) * self.rate, None, None)
        k, f = self._index(tau)
        s = float(plan.s[k]) if f == 0.0 else float(plan.s[k] + f * (plan.s[k + 1] - plan.s[k]))
        v0 = self._secant(tau, h)
        r = self.rate
        if not smoothed:
            return Sample(s, path.pose_at(s), None, r * v0, None)
        v1 = self._secant(tau + h, h)
        return Sample(s, path.pose_at(s), None, r * 0.5 * (v0 + v1), r * (v1 - v0) / h)

    # ------------------------------------------------------------------ progress
    def step(self, dt: float) -> None:
        """Advance the schedule by ``dt`` [s] at the current rate (`follow`: one period, r = 1)."""
        self.tau = min(self.tau + self.rate * dt, self.duration)

    def measure(self, q: np.ndarray) -> float:
        """Locate the measured joints ``q`` on the plan: the schedule time of the nearest planned
        configuration, searched from the last match up to one lead past the reference [s]."""
        plan = self.plan
        if plan is None:
            return self.tau
        k0 = self._k_measured
        k1 = min(len(plan), int(math.ceil((self.tau + self.lead) / plan.dt)) + 2)
        if k1 <= k0:
            k1 = min(len(plan), k0 + 1)
        d = np.einsum("ij,ij->i", plan.q[k0:k1] - q, plan.q[k0:k1] - q)
        self._k_measured = k0 + int(np.argmin(d))
        self.tau_measured = self._k_measured * plan.dt
        return self.tau_measured

    def advance(self, dt: float, q: np.ndarray | None) -> None:
        """`run`'s progress over a measured period ``dt`` [s]: the rate is re-timed from the
        measured joints ``q`` (None: no fresh measurement, the rate holds), then τ advances."""
        if self.plan is not None and q is not None and np.all(np.isfinite(q)):
            gap = self.tau - self.measure(q)
            want = min(max(2.0 * (self.lead - gap) / self.lead, 0.0), 1.0)
            dr = dt / self.ramp
            self.rate = min(max(want, self.rate - dr), self.rate + dr)
        self.step(dt)
