"""The governor plan: immutable, time-optimal up to its margins, local margin reduction, honest
about limits it cannot meet."""

import dataclasses
import pickle

import numpy as np
import pytest
from singular_paths import UR5E_WRIST_Q, UR5E_WRIST_QD, crossing_line

import ratectl as rc
from ratectl.planning import Governor, GovernorPlan, joint_path
from ratectl.planning.topp import reachability_profile

DT = 2e-3


@pytest.fixture(scope="module")
def wrist_plan(ur5e_exact_wrist):
    arm, line, q0 = ur5e_exact_wrist
    return Governor().plan(arm, line, q0, dt=DT)


def test_plan_crosses_the_exact_wrist_singularity_within_limits(ur5e_exact_wrist, wrist_plan):
    arm, line, _ = ur5e_exact_wrist
    plan = wrist_plan
    assert plan.complete and plan.within_limits and plan.message == ""
    assert plan.s[-1] == pytest.approx(line.length)
    qd = np.diff(plan.q, axis=0) / DT
    qdd = np.diff(qd, axis=0) / DT
    assert np.all(np.abs(qd) <= arm.vmax) and np.all(np.abs(qdd) <= arm.amax)
    # the sampled motion is the reachability profile itself: its duration, to a period
    assert plan.duration == pytest.approx(plan.optimal_duration, abs=DT)
    assert [c.branch for c in plan.joint_path.crossings if c.kind == "wrist"] == ["configuration changes"]


def test_plan_is_immutable(wrist_plan):
    plan = wrist_plan
    for name in ("t", "s", "sd", "sdd", "q", "qd_ff", "x_limit"):
        with pytest.raises(ValueError):
            getattr(plan, name)[0] = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        plan.complete = False  # type: ignore[misc]
    with pytest.raises(TypeError):
        plan.info["iterations"] = 3  # type: ignore[index]
    with pytest.raises(TypeError):
        GovernorPlan(DT, plan.t)  # type: ignore[misc]  # keyword-only
    with pytest.raises(ValueError):
        plan.joint_path.q[0, 0] = 0.0
    again = pickle.loads(pickle.dumps(plan))
    assert np.array_equal(again.q, plan.q) and again.info["iterations"] == plan.info["iterations"]


def test_singular_end_margins_are_lowered_only_locally():
    """A line that ends at full reach: the plan reaches within 0.1 mm of the end and is as fast
    as the time-optimal profile at the default margins, to 10 %."""
    arm = rc.robots.ur5e()
    q_end = np.array([0.3, -0.8, 0.0, -0.8, 1.4, 0.2])
    T_end = arm.fk(q_end)
    d = T_end[:3, 3] - arm.frames(q_end)[1][:3, 3]
    d /= np.linalg.norm(d)
    Ta = T_end.copy()
    Ta[:3, 3] -= 0.1 * d
    q0 = np.array(rc.ik(arm, Ta, np.array([0.27, -1.28, 1.0, -1.33, 1.4, 0.23])).q)
    line = rc.paths.Line(Ta, T_end, speed=0.2, acceleration=1.0)
    plan = Governor().plan(arm, line, q0, dt=DT)
    assert plan.complete and plan.within_limits, plan.message
    assert plan.joint_path.singular_end and "singular pose" in plan.message
    assert line.length - plan.s[-1] < 1e-4
    reference = reachability_profile(joint_path(arm, line, q0), 0.98 * arm.vmax, 0.96 * arm.amax,
                                     line.speed, line.acceleration)
    assert plan.duration <= 1.1 * reference.duration
    assert plan.margins[1] < 0.96  # something was lowered, and only where needed


def test_a_plan_that_cannot_meet_jmax_says_so():
    """A corner with a 1 cm blend at 0.3 m/s, planned in a single round (no local lowering):
    the tight blend needs 4.7× jmax; the plan reports the excess and follow reports the
    smoothed run as not completed, with the reason."""
    arm = rc.robots.ur5e()
    q0 = np.array([0.0, -1.2, 1.4, -1.8, 0.9, 0.3])
    poses = [arm.fk(q0)]
    for dp in ([0.08, 0, 0], [0, 0.08, 0]):
        T = poses[-1].copy()
        T[:3, 3] += dp
        poses.append(T)
    path = rc.paths.Waypoints(poses, blend=0.01, speed=0.3, acceleration=1.5)
    gov = Governor(check_jerk=True, max_iterations=1)
    ctrl = rc.ResolvedRateController(arm, smoothing=True)
    run = rc.follow(arm, path, q0, dt=DT, governor=gov, controller=ctrl)
    plan = run.info["plan"]
    assert not plan.within_limits and plan.jerk_ratio > 1.0
    assert "exceeds the limits" in plan.message and f"{plan.jerk_ratio:.3f}" in plan.message
    assert not run.completed and "jmax" in run.message


def _jerk_ratio(arm, run):
    return float(np.max(np.abs(np.diff(run.qdd, axis=0)) / DT / arm.jmax))


def test_smoothed_waypoints_complete_on_the_path_within_jmax():
    """UR5e, three segments with 3 cm blends and a 0.4 rad turn at 0.3 m/s (the benchmark's
    path): with the Ruckig smoother the run completes on the path within jmax and takes at
    most 1.5× the unsmoothed run. Blends that turned on the spot at the waypoint needed
    1.05× jmax and 1.74× the time."""
    arm = rc.robots.ur5e()
    q0 = np.array([0.0, -1.2, 1.4, -1.8, 0.9, 0.3])
    poses = [arm.fk(q0)]
    for dp in ([0.1, 0, 0], [0.0, 0.1, -0.05], [-0.1, 0.0, 0.1]):
        T = poses[-1].copy()
        T[:3, 3] += dp
        poses.append(T)
    poses[2][:3, :3] = poses[2][:3, :3] @ rc.spatial.rotz(0.4)
    path = rc.paths.Waypoints(poses, blend=0.03, speed=0.3, acceleration=1.5)
    run = rc.follow(arm, path, q0, dt=DT)
    smooth = rc.follow(arm, path, q0, dt=DT, controller=rc.ResolvedRateController(arm, smoothing=True))
    assert run.completed and smooth.completed, smooth.message
    assert smooth.max_position_error <= 5e-5 and smooth.max_orientation_error <= np.radians(0.01)
    assert _jerk_ratio(arm, smooth) <= 1.0
    assert smooth.duration <= 1.5 * run.duration
    assert np.linalg.norm(smooth.poses[-1][:3, 3] - path.end[:3, 3]) < 1e-4


def test_smoothed_plan_next_to_a_singularity_costs_little_time():
    """A UR5e line 1 mm from the wrist singularity: the jerk-limited plan meets jmax by
    lowering the speed only where the discrete check finds the jerk too high, 1.13× the
    unsmoothed plan (a pointwise bound |q‴|ṡ³ ≤ jmax, which ignores that the jerk terms
    cancel on the velocity-limit curve, made it 1.38×)."""
    arm = rc.robots.ur5e()
    line, q0 = crossing_line(arm, UR5E_WRIST_Q, UR5E_WRIST_QD, offset=1e-3)
    plain = Governor().plan(arm, line, q0, dt=DT)
    smooth = Governor(check_jerk=True).plan(arm, line, q0, dt=DT)
    assert plain.within_limits and smooth.within_limits and smooth.jerk_ratio <= 1.0
    assert smooth.duration <= 1.2 * plain.duration
    assert smooth.margins[0] < plain.margins[0]  # lowered, and only locally:
    slower = smooth.x_limit < 0.95 * plain.x_limit
    grid = smooth.joint_path.s
    assert np.sum(np.diff(grid)[slower[:-1]]) < 0.3 * line.length


def test_options_are_checked():
    with pytest.raises(rc.errors.InputError, match="velocity_margin"):
        Governor(velocity_margin=1.5)
    with pytest.raises(TypeError):
        Governor(0.9)  # type: ignore[misc]
