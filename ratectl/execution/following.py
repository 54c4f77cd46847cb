"""Is the robot following its command? `FollowWatch`, used by `ratectl.run`.

Over a sliding window of W seconds of robot time the watch compares, joint by joint, the
displacement the loop commanded — the integral of the commanded velocity, each command held
from the cycle it was sent until the next, Δq_cmd = Σ q̇_k (t_{k+1} − t_k) — with the
displacement the robot measured, Δq = q(t) − q(t − W). A joint whose commanded displacement is
at least ``min_motion`` and that moved less than ``ratio`` of it,

    |Δq_cmd| ≥ min_motion   and   |Δq| < ratio · |Δq_cmd|,

is not following: a stalled or frozen joint, a robot held by a protective stop, a dead band
the command cannot leave. Slower commands are not judged (friction and noise dominate
there). A robot's latency passes: with the defaults (W = 0.5 s, ratio 0.25) a robot that starts
150 ms late from rest has still covered about half of what was commanded. A command counts for
at most ``max_hold`` seconds: a robot that holds a velocity command only briefly (franky holds
it 20 ms) stops by itself when the loop stalls, and the stall is not its fault.
"""

from __future__ import annotations

import math
from collections import deque
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from ..model import Chain

__all__ = ["FollowWatch"]


class FollowWatch:
    """The sliding-window check of commanded against measured motion (module docstring).

    Args:
        chain: the arm (its joint names go into the message).
        window: W [s] of robot time; 0 switches the watch off.
        min_motion: the least commanded displacement judged [rad or m].
        ratio: the share of it the measured displacement must at least cover.
        max_hold: the longest a command counts for [s].
    """

    def __init__(self, chain: Chain, window: float, *, min_motion: float = 0.02, ratio: float = 0.25,
                 max_hold: float = 0.01) -> None:
        self.max_hold = float(max_hold)
        self.names = tuple(chain.joint_names)
        self.units = tuple("mm" if j.kind == "prismatic" else "mrad" for j in chain.joints)
        self.window, self.min_motion, self.ratio = float(window), float(min_motion), float(ratio)
        n = chain.dof
        self._cum = np.zeros(n)  # commanded displacement since the start
        self._qd = np.zeros(n)  # the command in force
        self._t: float | None = None
        self._hist: deque[tuple[float, np.ndarray, np.ndarray]] = deque()

    def update(self, t: float, q: np.ndarray, qd_cmd: np.ndarray, dt: float) -> str:
        """Note the measured ``q`` at robot time ``t`` [s] and the command ``qd_cmd`` sent now
        (``dt``: unused, the periods come from the times). Returns "" or why the robot does
        not follow."""
        if self._t is not None:
            self._cum = self._cum + self._qd * min(t - self._t, self.max_hold)
        self._t, self._qd = t, np.array(qd_cmd, dtype=float)
        if not self.window > 0.0 or not np.all(np.isfinite(q)):
            return ""
        hist = self._hist
        hist.append((t, np.array(q, dtype=float), self._cum))
        while len(hist) > 1 and t - hist[1][0] >= self.window:
            hist.popleft()
        t0, q0, c0 = hist[0]
        if t - t0 < self.window:
            return ""
        cmd = self._cum - c0
        meas = hist[-1][1] - q0
        bad = (np.abs(cmd) >= self.min_motion) & (np.abs(meas) < self.ratio * np.abs(cmd))
        if not bad.any():
            return ""
        j = int(np.argmax(np.where(bad, np.abs(cmd), -math.inf)))
        u = self.units[j]
        return (f"the robot does not follow its command: joint {self.names[j]!r} moved "
                f"{meas[j] * 1e3:.3g} {u} of {cmd[j] * 1e3:.3g} {u} commanded over the last "
                f"{t - t0:.2f} s")
