"""The limits stage of the controller (stage 4 of a cycle): `Limiter`.

The limiter owns the limit arrays (inverse vmax and amax, the position range with absent
limits made finite, the braking distances that decide "near a limit") and applies, in
this order: velocity (uniform scaling, which keeps the direction of motion), acceleration
(the change of q̇ per cycle scaled to fit amax·dt; not with smoothing, whose filter bounds
it), joint position (each joint may only move as fast as it can still stop before its
limit at amax whatever the later periods are, ``speed_toward_limit``; after a fault — a
measured q inside the stopping distance or beyond a limit — the position side wins over
amax, status ``limit-recovery``). A q̇ that a solver which enforces the limits itself
(``enforces_limits``, the QP) answered under its bounds is not limited again: its bounds and
extra rows are kept as solved and only reported. Every other q̇ is limited here, whatever
the solver: the servo's and the jog's commands (a direction scaled by a progress, which a
box would turn by clipping joints one by one) and the joint line of a blocked servo.
"""

from __future__ import annotations

from collections.abc import Mapping
from operator import gt as _gt
from operator import lt as _lt
from operator import mul as _mul
from operator import sub as _sub
from typing import TYPE_CHECKING, Any

import numpy as np

from ..model.limits import Limits, speed_toward_limit, stopping_distance
from .cycle import Cycle, Motion, _info

if TYPE_CHECKING:
    from ..model.chain import Chain
    from .smoothing import VelocityFilter

__all__ = ["Limiter"]

_BIG = 1e15  # an absent position or velocity limit in the bound arithmetic (no inf − inf)
_NO_AMAX = 1e200  # an absent acceleration limit: stopping takes one period


class Limiter:
    """The joint limits applied to a cycle's q̇ (see the module docstring).

    Args:
        chain: the arm (its joint names name the joints in reasons).
        limits: the controller's `Limits`, or None (no limits: nothing is limited).
        motion: the controller's last command (`Motion`), the "previous q̇".
        filter: the controller's smoothing filter or None (with one, the acceleration is
            the filter's and "near a limit" counts its jerk-limited stop).
        singular_sigma: below this σ_min a velocity-scaled solve is reported "singular".
        constant_damping: the solver's λ is a constant regulariser (the QP's): ``damped`` is
            reported only below ``singular_sigma``.
    A cycle whose q̇ a limit-enforcing solver answered under its bounds (``cyc.enforced``)
    is only reported.
    """

    def __init__(self, chain: Chain, limits: Limits | None, motion: Motion, filter: VelocityFilter | None,
                 *, singular_sigma: float, constant_damping: bool = False) -> None:
        self.chain = chain
        self.n = chain.dof
        self._m = motion
        self.filter = filter
        self.singular_sigma = singular_sigma
        self._constant_damping = constant_damping
        if limits is None:
            self.has_v = self.has_a = self.has_p = False
            return
        lim = limits
        self.has_v = bool(np.any(np.isfinite(lim.vmax)))
        self.has_a = bool(np.any(np.isfinite(lim.amax)))
        self.has_p = bool(np.any(np.isfinite(lim.lower) | np.isfinite(lim.upper)))
        big = _BIG
        self._inv_vmax = np.where(np.isfinite(lim.vmax), 1.0 / lim.vmax, 0.0)
        self._inv_vmax_l = self._inv_vmax.tolist()
        self._inv_amax = np.where(np.isfinite(lim.amax), 1.0 / lim.amax, 0.0)
        self._inv_amax_l = self._inv_amax.tolist()
        # an absent acceleration limit: a joint can stop in one period, so its position
        # limit is enforced by the velocity limit alone (the braking speed is d/dt)
        amax_f = np.where(np.isfinite(lim.amax), lim.amax, _NO_AMAX)
        self.inv_amax_f = 1.0 / amax_f
        self._two_over_a2 = np.concatenate([2.0 / amax_f, 2.0 / amax_f])
        self._amax_f2 = np.concatenate([amax_f, amax_f])
        self.plo = np.where(np.isfinite(lim.lower), lim.lower, -big)
        self.phi = np.where(np.isfinite(lim.upper), lim.upper, big)
        self.plo_l, self.phi_l = self.plo.tolist(), self.phi.tolist()  # (as floats)
        vf = np.where(np.isfinite(lim.vmax), lim.vmax, big)
        # distance within which a joint at full speed may need to brake (per side, so a
        # one-sided limit is watched too): v²/(2a), 0 without an acceleration limit; the
        # gate adds one period at vmax (braking_speed_any_dt reaches vmax there)
        fin = np.isfinite(lim.vmax) & np.isfinite(lim.amax)
        vfin = np.where(fin, vf, 0.0)
        self._pbrake = np.where(fin, vfin**2 / (2.0 * np.where(fin, amax_f, 1.0)),
                                np.where(np.isfinite(lim.vmax), 0.0, big))
        if filter is not None and self.has_p:
            # a jerk-limited joint needs more room to stop: widen the "near a limit" gate
            f = filter
            self._pbrake = np.maximum(self._pbrake, stopping_distance(f.vmax, f.amax, f.amax, f.jmax))
        self._vf = vf
        self._vf2 = np.concatenate([vf, vf])
        self._proom: np.ndarray | None = None
        self._proom_l: list[float] = []
        self._proom_dt: float | None = None

    def limit(self, cyc: Cycle, q, dt) -> bool:
        """Velocity, acceleration and position limits on ``cyc.qd`` (in that order; see the
        module docstring), or only the report of them for a solver that enforces them.
        Returns whether a joint is near a position limit (then, with smoothing, the
        jerk-limited guard of `ratectl.control.smooth_stage` runs too)."""
        enforcing = cyc.enforced
        if enforcing:
            # the solver (the QP, possibly with extra rows such as collision limits) already
            # bounds q̇ by the velocity, position and acceleration limits; limiting again here
            # would move q̇ off its optimum and could break its extra rows
            info = _info(cyc.res)
            cyc.qd, cyc.scale = self._report_solver_limits(cyc, cyc.res, cyc.qd, cyc.flags,
                                                           cyc.reasons, cyc.scale, info)
            if self.has_p:
                self._report_solver_recovery(cyc, q, dt, info)
        else:
            self._limit_velocity(cyc)
        if "velocity-scaled" in cyc.flags:
            cyc.reasons.append(f"q̇ scaled by {cyc.scale:.3g} to respect vmax")
            smin = cyc.sigma()
            if smin < self.singular_sigma:
                cyc.flags.insert(0, "singular")
                cyc.reasons[-1] = (f"near a singularity (σ_min = {smin:.3g}) the solver needs "
                                   f"{1 / cyc.scale:.3g}× vmax; q̇ scaled by {cyc.scale:.3g}")
        if self.has_a and self.filter is None and not enforcing:
            self._limit_acceleration(cyc, dt)
        near = self._near_position_limit(q, dt) if (not enforcing or self.filter is not None) else False
        if near and not enforcing:
            self._limit_position(cyc, q, dt)
        res = cyc.res
        if res.damping > 0.0 and not (self._constant_damping and cyc.sigma_at_least(self.singular_sigma)):
            # a QP's λ is a constant regulariser: it is reported only near a singularity
            cyc.flags.append("damped")
            cyc.reasons.append(f"damped least squares, λ = {res.damping:.3g} "
                               f"(σ_min = {cyc.sigma():.3g})")
        return near

    def _limit_velocity(self, cyc: Cycle) -> None:
        """Uniform scaling of q̇ into |q̇_i| ≤ vmax_i (keeps the direction of motion)."""
        if not self.has_v:
            return
        r = max(map(abs, map(_mul, cyc.qd.tolist(), self._inv_vmax_l)))  # (floats: a hot path)
        if r > 1.0:
            cyc.qd = cyc.qd / r
            cyc.scale /= r
            cyc.flags.append("velocity-scaled")
            if "velocity" not in cyc.active:
                cyc.active.append("velocity")

    def _limit_acceleration(self, cyc: Cycle, dt) -> None:
        """The change of q̇ from the previous cycle scaled uniformly into |Δq̇_i| ≤ amax_i dt."""
        r = max(map(abs, map(_mul, map(_sub, cyc.qd.tolist(), self._m.qd.tolist()),
                             self._inv_amax_l))) / dt  # (floats: a hot path)
        if r > 1.0:
            dq = cyc.qd - self._m.qd
            qd = self._m.qd + dq / r
            cyc.flags.append("acceleration-limited")
            cyc.reasons.append(f"change of q̇ scaled by {1 / r:.3g} to respect amax")
            cyc.active.append("acceleration")
            if self.has_v:  # the velocity limit wins if the previous q̇ was above it
                rv = float((np.abs(qd) * self._inv_vmax).max())
                if rv > 1.0:
                    qd = qd / rv
            cyc.qd = qd

    def _near_position_limit(self, q, dt) -> bool:
        """True if some joint is close enough to one of its position limits that it may
        need to brake: the room to the limit is below the braking distance plus one period
        at vmax (each side on its own, so a one-sided limit counts)."""
        if not self.has_p:
            return False
        if self._proom_dt != dt:
            self._proom = self._pbrake + self._vf * dt
            self._proom_l = self._proom.tolist()
            self._proom_dt = dt
        # (floats: a hot path) the room on either side, hi − x and x − lo, below the braking room
        ql = q.tolist()
        return (any(map(_lt, map(_sub, self.phi_l, ql), self._proom_l))
                or any(map(_lt, map(_sub, ql, self.plo_l), self._proom_l)))

    def _limit_position(self, cyc: Cycle, q, dt) -> None:
        """Clip each joint's q̇ to the speed from which it can still stop before its limits
        (`speed_toward_limit`: the braking bound `braking_speed_any_dt`, valid when dt
        changes between cycles; beyond a limit, back into the range within vmax and amax,
        never further out). The position side wins over the acceleration limit: a joint
        whose measured q jumped inside its stopping distance brakes harder than amax for
        one period (status ``limit-recovery``) rather than run past its limit."""
        hi_v, lo_v = self.position_box(q, dt)
        clipped = np.minimum(np.maximum(cyc.qd, lo_v), hi_v)
        changed = clipped != cyc.qd
        hard = None
        ratio = 0.0
        if changed.any():
            joints = np.flatnonzero(changed)
            cyc.qd = clipped
            if "joint-limit" in cyc.flags:  # (the approach held some already: one status)
                cyc.flags.remove("joint-limit")
            cyc.flags.insert(0, "joint-limit")
            cyc.reasons.insert(0, f"joint(s) {self.named(joints)} held at a position limit")
            cyc.active.append("position")
            if self.filter is None:  # (with smoothing the filter then keeps amax and jmax)
                step = np.abs(clipped - self._m.qd) * self.inv_amax_f / dt
                hard = changed & (step > 1.0 + 1e-9)
                ratio = float(step.max())
        self.report_limit_recovery(cyc, q, hard, ratio)  # also a joint measured beyond a limit

    def position_box(self, q, dt) -> tuple[np.ndarray, np.ndarray]:
        """(hi, lo): the position side of each joint's velocity box, `speed_toward_limit` toward
        the upper limit and (mirrored) the lower one, from the previous q̇; both sides in one
        stacked call."""
        n = self.n
        b = speed_toward_limit(np.concatenate([self.phi - q, q - self.plo]),
                               np.concatenate([self._m.qd, -self._m.qd]), dt=dt, two_over_a=self._two_over_a2,
                               adt=self._amax_f2 * dt, vmax=self._vf2)
        return b[:n], -b[n:]

    def _report_solver_limits(self, cyc, res, qd, flags, reasons, scale, info):
        """Flags and reasons for a solver that enforces the limits itself (the QP): which
        joints sit at which kind of bound, from ``res.bound`` and ``res.limits_active``.
        Only a q̇ beyond vmax by more than rounding (a bound conflict) is scaled back."""
        if self.has_v:
            r = max(map(abs, map(_mul, qd.tolist(), self._inv_vmax_l)))  # max |q̇_i|/vmax_i
            if r > 1.0 + 1e-9:
                qd = qd / r
                scale /= r
                flags.append("velocity-scaled")
                reasons.append(f"q̇ scaled by {1 / r:.3g} to respect vmax")
        kinds = res.limits_active
        joints = [i for i, held in enumerate(res.bound.tolist()) if held] if kinds else []
        if "position" in kinds:
            flags.insert(0, "joint-limit")
            reasons.insert(0, f"QP: joint(s) {self.named(joints)} held by a position limit")
        if "velocity" in kinds:
            smin = cyc.sigma()
            if smin < self.singular_sigma:
                flags.insert(0, "singular")
                reasons.append(f"near a singularity (σ_min = {smin:.3g}) the QP holds joint(s) "
                               f"{joints} at vmax")
            else:
                flags.append("velocity-scaled")
                reasons.append(f"QP: joint(s) {self.named(joints)} at vmax")
        if "acceleration" in kinds:
            flags.append("acceleration-limited")
            reasons.append(f"QP: joint(s) {self.named(joints)} at the acceleration bound")
        extra = info.get("extra_active")
        if extra is not None and np.any(extra):
            reasons.append(f"{int(np.count_nonzero(extra))} extra constraint row(s) active "
                           "(e.g. collision avoidance)")
        return qd, scale

    def _report_solver_recovery(self, cyc: Cycle, q, dt, info: Mapping[str, Any]) -> None:
        """``limit-recovery`` for a limit-enforcing solver: its box resolved a conflict of
        the acceleration bound against the position bound (``info["conflicts"]``, the
        position side won), or a joint is measured beyond a position limit."""
        conflicts = info.get("conflicts", ())
        if not conflicts:
            # a joint beyond a limit? (on Python floats: cheaper than two numpy comparisons)
            ql = q.tolist()
            if not (any(map(_gt, ql, self.phi_l)) or any(map(_lt, ql, self.plo_l))):
                return
        hard = np.zeros(self.n, dtype=bool)
        for joint, kinds in conflicts:
            if "acceleration" in kinds:
                hard[joint] = True
        step = np.abs(cyc.qd - self._m.qd) * self.inv_amax_f / dt
        self.report_limit_recovery(cyc, q, hard, float(step[hard].max()) if hard.any() else 0.0)

    def report_limit_recovery(self, cyc: Cycle, q, hard: np.ndarray | None, ratio: float) -> None:
        """Status ``limit-recovery`` (with the reason) for the joints ``hard`` (bool mask) whose
        position bound changed q̇ by more than amax·dt (``ratio`` = the largest |Δq̇|/(amax·dt)),
        and for joints measured beyond a position limit."""
        out = (q > self.phi) | (q < self.plo)
        some_hard = hard is not None and bool(hard.any())
        if not (some_hard or out.any()):
            return
        cyc.flags.insert(0, "limit-recovery")
        if some_hard:
            assert hard is not None
            cyc.reasons.insert(0, f"joint(s) {self.named(hard)} measured within the "
                               "stopping distance of a position limit (or beyond it): braking at "
                               f"{ratio:.3g}× amax to stay inside the range")
        if out.any():
            cyc.reasons.insert(0, f"joint(s) {self.named(out)} measured beyond a position "
                               "limit: commanded back into the range, never further out")

    def named(self, joints) -> str:
        """The chain's names of ``joints`` (a boolean mask or indices), for reasons."""
        idx = np.flatnonzero(joints) if np.asarray(joints).dtype == bool else np.asarray(joints, dtype=int)
        names = self.chain.joint_names
        return ", ".join(repr(names[int(i)]) for i in np.ravel(idx))
