"""Paths through (or next to) exact singularities, built so that their tangent lies in the range
of J. Shared by the planning tests (``conftest.py``) and ``benchmarks/bench_governor.py``."""

from __future__ import annotations

import math

import numpy as np

import ratectl as rc

#: UR5e exactly at the wrist singularity (q5 = 0) and a joint velocity that crosses it
UR5E_WRIST_Q = np.array([0.0, -2.0, -1.6, -1.2, 0.0, 0.0])
UR5E_WRIST_QD = np.array([0.1, -0.2, 0.15, 0.05, 1.0, -0.1])


def followable(arm, path, q0) -> bool:
    """The joint path from q0 reaches the end inside the joint range."""
    jp = rc.planning.joint_path(arm, path, np.array(q0))
    return jp.complete and bool(np.all((jp.q >= arm.lower) & (jp.q <= arm.upper)))


def crossing_line(arm, q_star, qd_star, *, half=0.12, speed=0.25, acceleration=1.0, offset=0.0):
    """(line, q0): a line (position and rotation) through fk(q*) with tangent twist J(q*)·q̇*
    (normalised), ``half`` [m] of path parameter on each side, and a start q0 on the branch
    that passes through q* (IK from q* − h·q̇*). ``offset`` [m] shifts the line sideways,
    along the translation J loses at q* (a near crossing), to whichever side is followable."""
    Tc, J = arm.fk_jacobian(np.asarray(q_star, float))
    qd_star = np.asarray(qd_star, float)
    xi = J @ qd_star
    scale = 1.0 / math.hypot(np.linalg.norm(xi[:3]), 0.1 * np.linalg.norm(xi[3:]))
    v, w = xi[:3] * scale, xi[3:] * scale
    Ta, Tb = Tc.copy(), Tc.copy()
    Ta[:3, 3] -= half * v
    Tb[:3, 3] += half * v
    Ta[:3, :3] = rc.spatial.so3_exp(-half * w) @ Tc[:3, :3]
    Tb[:3, :3] = rc.spatial.so3_exp(half * w) @ Tc[:3, :3]
    u = np.linalg.svd(J)[0][:3, -1]
    if offset:
        u -= (u @ v) * v / (v @ v)
        Ta[:3, 3] += offset * u / np.linalg.norm(u)
        Tb[:3, 3] += offset * u / np.linalg.norm(u)
    guess = np.asarray(q_star) - half * scale * qd_star
    for side in (1.0, -1.0):  # the side of the singularity the line is reachable on
        line = rc.paths.Line(Ta, Tb, speed=speed, acceleration=acceleration)
        res = rc.ik(arm, Ta, guess, max_step=0.05)
        if res.converged and followable(arm, line, res.q):
            return line, np.array(res.q)
        if not offset:
            break
        Ta[:3, 3] -= 2 * side * offset * u / np.linalg.norm(u)
        Tb[:3, 3] -= 2 * side * offset * u / np.linalg.norm(u)
    raise RuntimeError(f"the crossing line of {arm.name} is not followable: {res}")


def full_reach_line(*, beyond: float = 0.0):
    """(arm, line, q0): a 0.1 m UR5e line that ends at full reach, the elbow straight (an
    exact boundary singularity at its end), from a regular start q0 found by IK; with
    ``beyond`` > 0 [m] the line continues that far past full reach (out of the reachable set)."""
    arm = rc.robots.ur5e()
    q_end = np.array([0.3, -0.8, 0.0, -0.8, 1.4, 0.2])  # elbow straight: full reach
    T_end = arm.fk(q_end)
    d = T_end[:3, 3] - arm.frames(q_end)[1][:3, 3]
    d /= np.linalg.norm(d)
    T_start, T_stop = T_end.copy(), T_end.copy()
    T_start[:3, 3] -= 0.1 * d
    T_stop[:3, 3] += beyond * d
    q0 = np.array(rc.ik(arm, T_start, np.array([0.27, -1.28, 1.0, -1.33, 1.4, 0.23])).q)
    return arm, rc.paths.Line(T_start, T_stop, speed=0.2, acceleration=1.0), q0
