"""Paths through exact singularities, built so that their tangent lies in the range of J."""

import math

import numpy as np
import pytest

import ratectl as rc


def crossing_line(arm, q_star, qd_star, *, half=0.1, speed=0.25, acceleration=1.0):
    """Line through fk(q*) whose tangent twist is J(q*)·q̇* (normalised), and a start on the
    branch that passes through q* (IK from q* − h·q̇*)."""
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
    res = rc.ik(arm, Ta, np.asarray(q_star) - half * scale * qd_star, max_step=0.05)
    assert res.converged
    return rc.paths.Line(Ta, Tb, speed=speed, acceleration=acceleration), np.array(res.q)


#: UR5e exactly at the wrist singularity (q5 = 0) and a joint velocity that crosses it
UR5E_WRIST_Q = np.array([0.0, -2.0, -1.6, -1.2, 0.0, 0.0])
UR5E_WRIST_QD = np.array([0.1, -0.2, 0.15, 0.05, 1.0, -0.1])


@pytest.fixture(scope="session")
def ur5e_exact_wrist():
    """(arm, line, q0): a UR5e line through the wrist singularity q5 = 0 itself."""
    arm = rc.robots.ur5e()
    line, q0 = crossing_line(arm, UR5E_WRIST_Q, UR5E_WRIST_QD)
    return arm, line, q0
