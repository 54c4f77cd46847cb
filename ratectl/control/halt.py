"""The safe halt's motion: every joint to rest as fast as its own limits allow.

`brake` computes one period of it for the controller's ``_halt`` (which records the
command and says why): each joint on its own, so a joint that was braking for its
position limit keeps braking at its full rate; |q̇_i| drops by amax_i·dt per period (at
once without an acceleration limit), or, with smoothing, along each joint's time-optimal
jerk-limited stop.
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
          limits: Limits | None, independent: np.ndarray,
          reason: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """One period of the halt from position ``base`` and velocity ``qd_prev`` over ``dt``
    [s]: ``(q_next, q̇, q̈, reason)``; with a smoothing ``filter`` its stop of every joint
    (``independent``: all of them, each on its own), or — when the filter fails — the
    amax braking q̇ = sign(q̇_prev)·max(|q̇_prev| − amax·dt, 0), q_next = base + q̇·dt, with
    the failure added to ``reason``."""
    n = base.shape[0]
    if filter is not None:
        try:
            q_next, qd, qdd = filter.update(base, np.zeros(n), independent=independent)
            return q_next, qd, qdd, reason
        except RatectlError as err:  # the filter failed: brake without it
            reason = f"{reason}; smoothing failed while halting ({err})"
    amax = limits.amax if limits is not None else np.full(n, np.inf)
    speed = np.maximum(np.abs(qd_prev) - amax * dt, 0.0)  # inf amax: 0 at once
    qd = np.sign(qd_prev) * speed
    q_next = base + qd * dt
    qdd = (qd - qd_prev) / dt
    return q_next, qd, qdd, reason
