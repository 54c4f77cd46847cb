"""Integral action on the joints' tracking gap, with anti-windup: `GapIntegral`, used by `ratectl.run`.

A resolved-rate loop is proportional on the pose error. On a real arm a joint held by static
friction (or a servo's dead band) does not move for a small velocity command, so the loop
stops where the proportional command no longer breaks the joint free: a steady-state error,
with the command, the pose and the joint all standing still. The loop closes it joint by joint,
as a robot streamed joint positions does with its own position servo: it integrates what it
commanded against what the joint measured,

    G ← G + (q̇_k − u_k) · dt − (q_{k+1} − q_k)        (the gap [rad or m], per joint)
    u_{k+1} = K_I · G                                    (sent with the next command [rad/s or m/s])

(q̇_k the command sent, u_k the correction it carried, so a joint that follows makes
Ġ = −K_I G: the gap closes at the rate K_I [1/s]). A joint held still by friction accumulates
its commanded displacement until the correction breaks it free. The correction is a joint
feed-forward to the controller (``qd_ff``), so every limit still holds over the total command.

Anti-windup:

* **clamp** — ``|G| ≤ max_gap`` per joint: a correction never exceeds K_I·max_gap, and a
  robot that does not follow at all (a frozen joint, a protective stop) stores no more;
* **conditional integration** — G only changes on a fresh state whose last command was
  unlimited (status ``"regular"`` or ``"target-reached"``): braking at a limit, slowed by a
  singularity, halting, the gap is held;
* **dead zone** — on the end pose within the run's tolerance the gap is emptied: what is left
  needs no more push, and a joint that sticks and slips is not made to hunt around the pose;
* **reset** — `reset` empties it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["GapIntegral"]

_UNLIMITED = ("regular", "target-reached")  # statuses whose command the limits left alone


class GapIntegral:
    """The joints' tracking gap and its correction (module docstring).

    Args:
        n: number of joints.
        gain: K_I [1/s], the rate the gap closes at.
        max_gap: the clamp of |G| per joint [rad or m] (scalar or (n,)).
        still_speed: a joint measured slower than this [rad/s or m/s] is standing still.
    """

    def __init__(self, n: int, *, gain: float = 10.0, max_gap: float | np.ndarray = 5e-3,
                 still_speed: float = 0.01) -> None:
        self.gain = float(gain)
        self.still_speed = float(still_speed)
        self.max_gap = np.broadcast_to(np.asarray(max_gap, dtype=float), (n,)).copy()
        self.gap = np.zeros(n)
        self.correction = np.zeros(n)  # u now [rad/s or m/s]
        self._moved = np.zeros(n)  # commanded displacement since the last fresh state
        self._held = 0.0  # loop time the commands were held for since then [s]
        self._q: np.ndarray | None = None
        self._t = 0.0  # robot time of the last fresh state [s]

    def reset(self) -> None:
        """Forget the gap."""
        self.gap = np.zeros_like(self.gap)
        self.correction = np.zeros_like(self.gap)
        self._moved[:] = 0.0
        self._held = 0.0
        self._q = None

    def sent(self, qd: np.ndarray, dt: float) -> None:
        """A command ``qd`` [rad/s or m/s] was in force for ``dt`` [s] (the previous cycle's,
        held until this one); what it commanded beyond its correction counts toward the gap."""
        self._moved += (qd - self.correction) * dt
        self._held += dt

    def update(self, q: np.ndarray, t: float, status: str, *, settled: bool = False) -> np.ndarray:
        """A fresh measured ``q`` at robot time ``t`` [s]; ``status`` of the last command;
        ``settled``: on the end pose within tolerance (the dead zone). Returns the correction u
        (n,). The commanded displacement counts for the robot time that passed, at most the
        loop's: a robot (or simulator) slower than the wall clock is not taken for a stuck joint."""
        if settled:
            self.reset()
        elif self._q is not None and status in _UNLIMITED and self._held > 0.0:
            h = min(t - self._t, self._held)
            dq = q - self._q
            still = np.abs(dq) <= self.still_speed * h
            # a joint held still accumulates what it was commanded; a moving one lets go at K_I
            gap = np.where(still, self.gap + self._moved * (h / self._held),
                           self.gap * max(0.0, 1.0 - self.gain * h))
            self.gap = np.clip(gap, -self.max_gap, self.max_gap)
            self.correction = self.gain * self.gap
        self._moved = np.zeros_like(self.gap)
        self._held = 0.0
        self._q, self._t = q, t
        return self.correction
