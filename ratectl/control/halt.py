"""The safe halt's motion: every joint to rest together, along the direction it moves in.

`brake` computes one period of it for the controller's ``_halt`` (which records the
command and says why). The joints slow down together, so the arm stops on the joint path
it was on and the tool on (very nearly) its own path, instead of each joint on its own,
which bends the tool off its line by millimetres while the fastest joints stop first:

* without smoothing, q̇ = q̇_prev·max(1 − ρ·dt, 0) with ρ = min_i amax_i/|q̇_prev,i| [1/s]:
  the joint that needs longest to stop brakes at its amax, the others at the same fraction
  of their speed (at most their amax); no acceleration limit: at rest at once;
* with smoothing, the filter's time-synchronised jerk-limited stop (all joints reach rest
  together, within amax and jmax).

A joint whose share of that common stop would run past a position limit (farther than
its room, or further out when it is already past one) is braked on its own instead, as
fast as its limits allow (|q̇_i| drops by amax_i·dt per period; with smoothing its own
time-optimal jerk-limited stop): a joint that was braking for its limit keeps braking at
its full rate. The common stop takes no longer than the slowest joint's own stop.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..errors import RatectlError

if TYPE_CHECKING:
    from ..model.limits import Limits
    from .smoothing import VelocityFilter

__all__ = ["brake"]


def brake(base: np.ndarray, qd_prev: np.ndarray, dt: float, filter: VelocityFilter | None,
          limits: Limits | None, reason: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """One period of the halt from position ``base`` and velocity ``qd_prev`` over ``dt``
    [s]: ``(q_next, q̇, q̈, reason)`` (see the module docstring); with a smoothing
    ``filter`` its synchronised stop, or — when the filter fails — the stop without it,
    with the failure added to ``reason``."""
    n = base.shape[0]
    if filter is not None:
        try:
            own = (None if limits is None  # (joints whose share would pass a limit stop on their own)
                   else filter.synchronised_stop_passes(base, limits.lower, limits.upper))
            q_next, qd, qdd = filter.update(base, np.zeros(n), independent=own)
            return q_next, qd, qdd, reason
        except RatectlError as err:  # the filter failed: brake without it
            reason = f"{reason}; smoothing failed while halting ({err})"
    qd = _common_stop(base, qd_prev, dt, limits)
    q_next = base + qd * dt
    qdd = (qd - qd_prev) / dt
    return q_next, qd, qdd, reason


def _common_stop(base: np.ndarray, qd_prev: np.ndarray, dt: float, limits: Limits | None) -> np.ndarray:
    """The joint velocities one period ``dt`` [s] into the halt without smoothing, from
    ``qd_prev`` [rad/s or m/s] at ``base``: q̇_prev·max(1 − ρ·dt, 0), ρ = min amax_i/|q̇_prev,i|
    over the joints that stop together, and sign(q̇_prev,i)·max(|q̇_prev,i| − amax_i·dt, 0)
    for a joint whose share of that stop, |q̇_prev,i|·(1/(2ρ) + dt), is longer than its
    room to the position limit ahead of it (no limits: every joint at once)."""
    if limits is None:
        return np.zeros_like(qd_prev)
    amax = limits.amax
    speed = np.abs(qd_prev)
    moving = speed > 0.0
    rho = _common_rate(speed, amax, moving)
    if rho < np.inf:
        room = np.where(qd_prev > 0.0, limits.upper - base, base - limits.lower)
        own = moving & (speed * (0.5 / rho + dt) > room)
        if own.any():  # (the others' common rate without them)
            rho = _common_rate(speed, amax, moving & ~own)
            together = qd_prev * max(1.0 - rho * dt, 0.0)
            return np.where(own, np.sign(qd_prev) * np.maximum(speed - amax * dt, 0.0), together)
    return qd_prev * max(1.0 - rho * dt, 0.0)  # (inf: no moving joint has an amax, at rest at once)


def _common_rate(speed: np.ndarray, amax: np.ndarray, among: np.ndarray) -> float:
    """ρ = min amax_i/|q̇_i| over the joints ``among`` [1/s] (inf when none, or when
    none of them has an acceleration limit): the rate at which their common speed fraction
    may fall."""
    if not among.any():
        return np.inf
    return float(np.min(amax[among] / speed[among]))
