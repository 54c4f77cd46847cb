"""The position guard of a smoothed controller: `SmoothGuard`.

The Ruckig filter (`ratectl.control.smoothing`) lags the command, so a smoothed joint must
start braking for a position limit while its jerk-limited stop still fits
(`SmoothGuard.guard`, after the limits stage when a joint is near a limit); and after a
fault — a measured q inside the jerk-limited stopping distance — the position side wins
over the filter's jerk and acceleration limits for one period (`SmoothGuard.recover`,
after the filter, status ``limit-recovery``). The guard reads the limit arrays of the
controller's `Limiter` and the filter's own limits.
"""

from __future__ import annotations

from operator import le as _le
from typing import TYPE_CHECKING

import numpy as np

from ..model.limits import braking_speed, stopping_distance
from .cycle import Cycle, Motion, _scaled_like

if TYPE_CHECKING:
    from .limiter import Limiter
    from .smoothing import VelocityFilter

__all__ = ["SmoothGuard"]


class SmoothGuard:
    """The position guard around the filter ``filter`` with the limits of ``limiter``;
    ``motion``: the controller's last command (the filter's state, q̇ and q̈)."""

    def __init__(self, limiter: Limiter, filter: VelocityFilter, motion: Motion) -> None:
        self._lim = limiter
        self.filter = filter
        self._m = motion

    def guard(self, cyc: Cycle, q, dt) -> None:
        """Before the filter, for a cycle with a joint near a position limit: the
        jerk-limited guard (`_jerk_limited_position_guard`) on ``cyc.qd``; the joints it
        stops go to ``cyc.braking``. An approach keeps its direction: the guard's clip
        then scales its whole motion."""
        # the progress reference is not met exactly: the worst case one period ahead
        reference: np.ndarray | None = None
        wanted = cyc.qd
        cyc.qd, cyc.braking = self._jerk_limited_position_guard(q, cyc.qd, dt, cyc.flags,
                                                                cyc.reasons, cyc.active, reference)
        if cyc.approach_qd is not None and cyc.qd is not wanted:
            # an approach keeps its direction: the guard's clip scales the whole motion
            cyc.qd = _scaled_like(wanted, cyc.qd)

    def _jerk_limited_position_guard(self, q, qd, dt, flags, reasons, active, qdd_ref=None):
        """Keep a smoothed joint inside its position range: the Ruckig filter lags the
        command, so braking must start while the jerk-limited stop still fits.

        From the filter's state (v, a) the worst case one period ahead towards a limit is
        a₁ = min(a + J·dt, A), v₁ = v + a·dt + J·dt²/2 after travelling v·dt + a·dt²/2 +
        J·dt³/6. If the jerk-limited stop from (v₁, a₁) (`
        stopping_distance`) no longer fits in the room left, the command towards that
        limit is 0 now (Ruckig then brakes time-optimally); otherwise it is at most
        `braking_speed` of the room. The same mirrored towards
        the lower limit. Returns (q̇, braking): the joints that must stop, which the filter
        then moves time-optimally on their own instead of synchronised with the others.

        With the approach's reference (q̇, ``qdd_ref``), which the filter meets exactly, the
        next state is known instead of the worst case: a joint whose jerk-limited stop from
        that state, after the period's constant-jerk travel v·dt + a·dt²/2 + (a₁ − a)·dt²/6,
        still fits before its limit keeps the reference."""
        f = self.filter
        A, Jm = f.amax, f.jmax
        v, a = self._m.qd, self._m.qdd
        jdt = Jm * dt
        ahead_v = 0.5 * jdt * dt
        ahead_x = jdt * dt * dt / 6.0
        room_up = self._lim.phi - q
        room_lo = q - self._lim.plo
        # towards the upper limit
        a1 = np.minimum(a + jdt, A)
        v1 = v + a * dt + ahead_v
        stop_up = stopping_distance(v1, a1, A, Jm) >= room_up - (v * dt + 0.5 * a * dt * dt + ahead_x)
        hi_v = np.where(stop_up, 0.0, braking_speed(room_up, A, Jm))
        # towards the lower limit (mirrored)
        a1 = np.minimum(-a + jdt, A)
        v1 = -v - a * dt + ahead_v
        stop_lo = stopping_distance(v1, a1, A, Jm) >= room_lo - (-v * dt - 0.5 * a * dt * dt + ahead_x)
        lo_v = np.where(stop_lo, 0.0, -braking_speed(room_lo, A, Jm))
        if qdd_ref is not None:
            travel = v * dt + 0.5 * a * dt * dt + (qdd_ref - a) * (dt * dt / 6.0)
            slack = Jm * dt**3  # more than any other one-period motion to the same state travels
            # the exact stop of a reference that is already braking (counting its deceleration
            # as 0 over-estimates the stop: a plan braking onto a goal at the limit was cut off
            # and the other joints ran ahead of the line)
            fits = ((stopping_distance(qd, qdd_ref, A, Jm, exact_when_braking=True)
                     < room_up - travel - slack)
                    & (stopping_distance(-qd, -qdd_ref, A, Jm, exact_when_braking=True)
                       < room_lo + travel - slack))
            hi_v = np.where(fits, np.inf, hi_v)
            lo_v = np.where(fits, -np.inf, lo_v)
            stop_up = stop_up & ~fits
            stop_lo = stop_lo & ~fits
        clipped = np.minimum(np.maximum(qd, lo_v), hi_v)
        changed = clipped != qd
        if changed.any():
            # reported only where the clip changes the motion (not a 1e-13 rad/s remainder)
            joints = np.flatnonzero(np.abs(clipped - qd) > 1e-9).tolist()
            if joints:
                if "joint-limit" not in flags:
                    flags.insert(0, "joint-limit")
                moving = np.abs(v[joints]).max() > 1e-9
                what = ("braking for a position limit (jerk-limited stop)" if moving
                        else "held at a position limit")
                reasons.insert(0, f"joint(s) {self._lim.named(joints)} {what}")
                active.append("position")
        else:
            clipped = qd  # unchanged: the same array (the approach's acceleration stays valid)
        return clipped, stop_up | stop_lo  # the braking joints stop time-optimally, on their own

    def recover(self, cyc: Cycle, q, dt) -> None:
        """The position side wins over the filter's jerk and acceleration limits: a joint
        whose smoothed motion would end this period beyond a position limit (further out
        than it is measured) — possible only after a fault, a measured q that jumped inside
        the jerk-limited stopping distance — is commanded, for this period, the largest
        speed that still leaves room for the filter's own jerk-limited stop from rest
        acceleration afterwards (≤ `speed_toward_limit`; beyond a limit: back into the
        range, never further out); its filter state is set to that velocity with the
        period's mean acceleration clipped to ±amax, or 0 where that would speed the joint
        up (``Command.qdd``), and the status is ``limit-recovery``. The later periods are
        then jerk-limited again."""
        q_next = cyc.q_next
        braking = cyc.braking is not None and cyc.braking.any()
        if not braking:
            # (floats, the common case: every joint ends this period within its limits, where
            # none is beyond the test below; NaN fails these comparisons and goes on to it)
            ql = q_next.tolist()
            if all(map(_le, self._lim.plo_l, ql)) and all(map(_le, ql, self._lim.phi_l)):
                return
        tol = 1e-12 * (1.0 + np.abs(q))
        out = (q_next > np.maximum(self._lim.phi, q) + tol) | (q_next < np.minimum(self._lim.plo, q) - tol)
        f = self.filter
        assert f is not None
        if braking:
            # a joint the guard brakes: is it already inside its stopping distance? (for the
            # others even the guard's look-ahead stop fits, so the stop from now fits too)
            out |= self._inside_stopping_distance(q, f, cyc.braking)
        if not out.any():
            return
        bounds = []
        hi_b, lo_b = self._lim.position_box(q, dt)
        for room, b in ((self._lim.phi - q, hi_b), (q - self._lim.plo, -lo_b)):
            # after this period the filter brakes jerk-limited from (b, 0): that stop must fit
            rest = np.maximum(room - np.maximum(b, 0.0) * dt, 0.0)
            bounds.append(np.where(room >= 0.0, np.minimum(b, braking_speed(rest, f.amax, f.jmax)), b))
        qd = np.where(out, np.minimum(np.maximum(cyc.qd, -bounds[1]), bounds[0]), cyc.qd)
        cyc.q_next = np.where(out, q + qd * dt, q_next)
        fd = (qd - self._m.qd) / dt
        ratio = float(np.max(np.abs(fd[out]) * self._lim.inv_amax_f[out]))
        # the filter goes on from there, at the period's mean acceleration clipped to ±amax,
        # or 0 where that would still speed the joint up: its jerk-limited stop from that
        # state is no longer than from (q̇, 0), which fits the room left
        acc = np.where(fd * qd > 0.0, 0.0, np.minimum(np.maximum(fd, -f.amax), f.amax))
        cyc.qdd = np.where(out, acc, cyc.qdd)
        cyc.qd = qd
        f.reset(qd, cyc.qdd)
        joints = np.flatnonzero(out).tolist()
        cyc.flags.insert(0, "limit-recovery")
        cyc.reasons.insert(0, f"joint(s) {self._lim.named(joints)} measured inside their jerk-limited "
                           "stopping distance of a position limit (or beyond it): smoothing overridden for "
                           "one period, "
                           f"braking at {ratio:.3g}× amax to stay inside the range (never further out)")
        if "position" not in cyc.active:
            cyc.active.append("position")

    def _inside_stopping_distance(self, q, f, braking: np.ndarray) -> np.ndarray:
        """Joints (mask) among ``braking`` that can no longer stop before a position limit
        from the filter state (q̇, q̈) at the start of the period: the exact distance of the
        time-optimal jerk-limited stop toward the limit it moves to (`stopping_distance`
        with ``exact_when_braking``, what Ruckig does when told to stop) exceeds the room.
        The guard never lets that happen (it starts braking while the stop still fits):
        only a fault does. The default `stopping_distance` (an over-estimate while braking)
        screens the joints first; the exact one is computed only for those it flags."""
        inside = np.zeros(self._lim.n, dtype=bool)
        i = np.flatnonzero(braking & (self._m.qd != 0.0))
        if not i.size:
            return inside
        up = self._m.qd[i] > 0.0  # moving toward the upper limit, else toward the lower one
        room = np.where(up, self._lim.phi[i] - q[i], q[i] - self._lim.plo[i])
        v = np.abs(self._m.qd[i])
        a = np.where(up, self._m.qdd[i], -self._m.qdd[i])
        A, Jm = f.amax[i], f.jmax[i]
        limit = room * (1.0 + 1e-9) + 1e-12
        cand = (room >= 0.0) & (stopping_distance(v, a, A, Jm) > limit)
        if cand.any():
            k = np.flatnonzero(cand)
            cand[k] = stopping_distance(v[k], a[k], A[k], Jm[k], exact_when_braking=True) > limit[k]
        inside[i] = cand
        return inside
