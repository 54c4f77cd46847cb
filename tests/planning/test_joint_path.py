"""The joint path: exact singularity crossings on the smooth branch, specific stops, immutability."""

import dataclasses
import math

import numpy as np
import pytest
from singular_paths import full_reach_line

import ratectl as rc
from ratectl.planning import JointPath, joint_path


def test_exact_wrist_crossing_follows_the_smooth_branch(ur5e_exact_wrist):
    arm, line, q0 = ur5e_exact_wrist
    jp = joint_path(arm, line, q0)
    assert jp.complete, jp.message
    # it passes through the singular configuration itself (q5 changes sign) ...
    q5 = jp.q[:, 4]
    assert q5[0] * q5[-1] < 0 and np.min(np.abs(q5)) < 1e-3
    assert jp.sigma_min.min() < 1e-3
    # ... with a bounded joint tangent (no flip of q4, q6 by π): |q′| stays of the size it
    # has away from the singularity
    big = np.max(np.abs(jp.dq), axis=1)
    assert big.max() < 3.0 * np.median(big)
    assert np.max(np.abs(np.diff(jp.q, axis=0))) < 0.02
    # and says which branch it took
    (c,) = [c for c in jp.crossings if c.kind == "wrist"]
    assert c.branch == "configuration changes" and abs(c.s - line.length / 2) < 0.01
    # on the path everywhere
    for k in range(0, len(jp.s), 25):
        e = rc.spatial.pose_error(line.pose_at(jp.s[k]), arm.fk(jp.q[k]))
        assert np.linalg.norm(e) < 1e-9
    # q′ is dq/ds (finite differences of the grid)
    k = len(jp.s) // 3
    fd = (jp.q[k + 1] - jp.q[k - 1]) / (jp.s[k + 1] - jp.s[k - 1])
    assert np.allclose(fd, jp.dq[k], atol=1e-3 * np.abs(jp.dq[k]).max())


def test_tangent_outside_the_range_stops_with_the_reason():
    """At q5 = 0 a translation along the line of the conftest: outside the range of J."""
    arm = rc.robots.ur5e()
    q = np.array([0.0, -2.0, -1.6, -1.2, 0.0, 0.0])
    T0 = arm.fk(q)
    T1 = T0.copy()
    T1[:3, 3] += 0.1 * np.array([math.cos(math.radians(30)), math.sin(math.radians(30)), 0.0])
    jp = joint_path(arm, rc.paths.Line(T0, T1, speed=0.2, acceleration=1.0), q)
    assert not jp.complete
    assert "leaves the reachable set" in jp.message and "wrist" in jp.message
    assert jp.residual[-1] > 0.1 and jp.s[-1] < 1e-6


def test_line_beyond_full_reach_stops_at_the_boundary():
    arm, line, q0 = full_reach_line(beyond=0.02)
    jp = joint_path(arm, line, q0)
    assert not jp.complete and "leaves the reachable set" in jp.message and "elbow" in jp.message
    assert abs(jp.s[-1] - 0.1) < 1e-3  # stopped at full reach


def test_path_ending_at_full_reach_is_integrated_to_the_end():
    arm, line, q0 = full_reach_line()
    T_end = line.end
    jp = joint_path(arm, line, q0)
    assert jp.complete and jp.s[-1] == pytest.approx(0.1)
    assert np.linalg.norm(arm.fk(jp.q[-1])[:3, 3] - T_end[:3, 3]) < 1e-7
    assert np.max(np.abs(jp.dq[-1])) > 1e3  # q′ grows without bound at the singular end


def test_joint_path_is_immutable(ur5e_exact_wrist):
    arm, line, q0 = ur5e_exact_wrist
    jp = joint_path(arm, line, q0)
    with pytest.raises(ValueError):
        jp.q[0, 0] = 1.0
    with pytest.raises(ValueError):
        jp.dq[0, 0] = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        jp.complete = False  # type: ignore[misc]
    with pytest.raises(TypeError):
        JointPath(jp.s, jp.q, jp.dq, jp.ddq, jp.dddq, jp.sigma_min, jp.residual, True)  # type: ignore[misc]
    copy = dataclasses.replace(jp, message="x")
    assert copy.message == "x" and not copy.q.flags.writeable
