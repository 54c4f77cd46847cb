"""rc.ik: the one inverse kinematics of the package."""

import math

import numpy as np
import pytest

import ratectl as rc


def test_reaches_poses_of_random_configurations_near_the_start(arm, rng):
    for _ in range(10):
        q_goal = arm.random_q(rng=rng, margin=0.1)
        q0 = np.clip(q_goal + rng.uniform(-0.2, 0.2, arm.dof), arm.lower, arm.upper)
        res = rc.ik(arm, arm.fk(q_goal), q0)
        if rc.analyze(arm, q_goal).sigma_min < 1e-3:
            continue  # a singular goal: Newton may stop short, which the result says
        assert res.converged, res
        e = rc.spatial.pose_error(arm.fk(q_goal), arm.fk(res.q))
        assert np.linalg.norm(e[:3]) <= 1e-9 and np.linalg.norm(e[3:]) <= 1e-9


def test_a_half_turn_about_the_tool_axis_is_a_large_error_not_a_small_one():
    """The first-order error (sin θ) sees no rotation at θ = π; the exact log does."""
    arm = rc.robots.ur5e()
    q0 = np.array([0.3, -1.3, 1.6, -1.9, -1.2, 0.2])
    T = arm.fk(q0)
    T[:3, :3] = T[:3, :3] @ rc.spatial.rotz(math.pi)
    res = rc.ik(arm, T, q0)
    assert res.converged
    assert abs(abs(res.q[5] - q0[5]) - math.pi) < 1e-8  # the last joint turned by π
    assert res.iterations > 1


def test_an_unreachable_target_is_reported_not_raised():
    arm = rc.robots.ur5e()
    q0 = np.array([0.3, -1.3, 1.6, -1.9, -1.2, 0.2])
    T = arm.fk(q0)
    T[:3, 3] += [5.0, 0.0, 0.0]  # 5 m away: out of reach
    res = rc.ik(arm, T, q0, max_iter=50)
    assert not res.converged and res.iterations == 50
    assert res.position_error > 3.0 and np.all(np.isfinite(res.q))
    assert "NOT converged" in str(res)


def test_the_result_is_frozen_and_its_q_read_only():
    arm = rc.robots.planar2r()
    res = rc.ik(arm, arm.fk(np.array([0.3, 0.5])), np.array([0.2, 0.4]), tol=1e-10)
    with pytest.raises(ValueError, match="read-only"):
        res.q[0] = 1.0
    with pytest.raises(AttributeError):
        res.converged = False  # type: ignore[misc]
    assert res.error == (res.position_error, res.orientation_error)


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"tol": -1.0}, "tol must be"),
    ({"tol": (1e-9, 1e-9, 1e-9)}, "tol must be a number or a pair"),
    ({"damping": math.nan}, "damping must be"),
    ({"max_step": 0.0}, "max_step must be"),
    ({"max_iter": -1}, "max_iter"),
])
def test_bad_options_are_refused(kwargs, match):
    arm = rc.robots.ur5e()
    q0 = np.zeros(6)
    with pytest.raises(rc.InputError, match=match):
        rc.ik(arm, arm.fk(q0), q0, **kwargs)


@pytest.mark.parametrize("T", [np.eye(3), np.diag([2.0, 2.0, 2.0, 1.0]), np.diag([1.0, 1.0, -1.0, 1.0]),
                               np.full((4, 4), np.nan)])
def test_targets_that_are_not_rigid_transforms_are_refused(T):
    arm = rc.robots.ur5e()
    with pytest.raises(rc.InputError, match="T_target"):
        rc.ik(arm, T, np.zeros(6))
