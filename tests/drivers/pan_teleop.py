"""The teleop scene of the joint-limit tests: an arm whose shoulder pan is limited to ±limit,
turned about its base by a tool twist along the horizontal circle through its tool point."""

from __future__ import annotations

import math

import numpy as np

import ratectl as rc


def pan_limited(base: rc.Chain, limit: float) -> rc.Chain:
    """``base`` with its first joint limited to ±``limit`` [rad], amax 4 and jmax 40."""
    qlim = np.column_stack([base.lower, base.upper])
    qlim[0] = (-limit, limit)
    return base.with_limits(qlim=qlim, amax=4.0, jmax=40.0)


def base_turn(arm: rc.Chain, q0: np.ndarray, *, speed: float, until: float):
    """``twist(t)``: the tool twist [v; ω] (base axes) that turns the tool point at ``speed``
    [m/s] about the base z axis from its place at ``q0``, and None after ``until`` [s]."""
    p = arm.fk(q0)[:3, 3]
    r, phi0 = math.hypot(p[0], p[1]), math.atan2(p[1], p[0])
    w = speed / r

    def twist(t):
        if t > until:
            return None
        phi = phi0 + w * t
        return np.array([-speed * math.sin(phi), speed * math.cos(phi), 0.0, 0.0, 0.0, w])

    return twist
