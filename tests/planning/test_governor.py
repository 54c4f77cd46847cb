"""The governor plan: immutable, time-optimal up to its margins, local margin reduction, honest
about limits it cannot meet."""

import dataclasses
import pickle

import numpy as np
import pytest
from singular_paths import UR5E_WRIST_Q, UR5E_WRIST_QD, crossing_line, full_reach_line

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
    arm, line, q0 = full_reach_line()
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


# ---------------------------------------------------------------------- sharp corners
def _sharp_tour(arm_name="ur5e", q0=(0.3, -1.3, 1.6, -1.9, -1.2, 0.2)):
    """The new-user report's tour T0 → T1 → T0 with blend=0: a reversal at T1 (the tangent turns
    by 180°, the rotation too), which the governor could not plan (|q̈|/amax = 6.6)."""
    arm = rc.robots.BUILTIN[arm_name]()
    q0 = np.array(q0)
    T0 = arm.fk(q0)
    T1 = T0.copy()
    T1[:3, 3] += [0.15, -0.1, 0.05]
    T1[:3, :3] = rc.spatial.rotz(0.4) @ T0[:3, :3]
    T2 = T1.copy()
    T2[:3, 3] += [0.0, 0.08, 0.0]  # and a right-angle corner
    return arm, rc.paths.Waypoints([T0, T1, T2, T0], blend=0.0, speed=0.3, acceleration=1.5), q0


def test_joint_path_records_each_corner_with_both_tangents():
    arm, path, q0 = _sharp_tour()
    jp = joint_path(arm, path, q0)
    assert jp.complete
    dup = np.flatnonzero(np.diff(jp.s) == 0.0)
    assert np.allclose(jp.s[dup], path.corners)  # every corner, landed on exactly, twice
    assert np.array_equal(jp.rest_points, np.sort(np.concatenate([dup, dup + 1])))
    for k in dup:
        assert np.array_equal(jp.q[k], jp.q[k + 1])
        J = arm.jacobian(jp.q[k])
        assert np.allclose(J @ jp.dq[k], path.twist_at(jp.s[k], side="before"), atol=1e-9)
        assert np.allclose(J @ jp.dq[k + 1], path.twist_at(jp.s[k]), atol=1e-9)
    # the derivatives are taken piece by piece: q″ stays of its size on the segments
    assert np.max(np.abs(jp.ddq)) < 50.0


def test_profile_comes_to_rest_at_each_corner():
    arm, path, q0 = _sharp_tour()
    jp = joint_path(arm, path, q0)
    prof = reachability_profile(jp, arm.vmax, arm.amax, path.speed, path.acceleration)
    assert np.all(prof.x[jp.rest_points] == 0.0) and np.all(np.isfinite(prof.t))
    assert np.all(np.diff(prof.t) >= 0.0)
    sd = np.sqrt(prof.x)
    assert np.all(np.abs(jp.dq) * sd[:, None] <= arm.vmax * (1 + 1e-9))
    qdd = jp.dq[:-1] * prof.u[:-1, None] + jp.ddq[:-1] * prof.x[:-1, None]
    assert np.all(np.abs(qdd) <= arm.amax * (1 + 1e-6))


@pytest.mark.parametrize("smoothing", [False, True])
def test_sharp_corners_are_followed_stopping_at_each(smoothing):
    """blend=0: the plan stops at every corner and follow completes on the path within every
    limit — with the Ruckig smoother too (within jmax; the progress averaged piece by piece
    between the corners, so it still comes to rest at each)."""
    arm, path, q0 = _sharp_tour()
    ctrl = rc.ResolvedRateController(arm, smoothing=smoothing)
    run = rc.follow(arm, path, q0, dt=DT, controller=ctrl)
    assert run.completed, run.message
    assert run.max_position_error < 1e-5 if not smoothing else run.max_position_error < 5e-5
    qd = np.diff(run.q, axis=0) / DT
    assert np.all(np.abs(qd) <= arm.vmax * (1 + 1e-9))
    assert np.all(np.abs(np.diff(qd, axis=0)) / DT <= arm.amax * (1 + 1e-9))
    if smoothing:
        assert _jerk_ratio(arm, run) <= 1.0
    plan = run.info["plan"]
    for c in path.corners:  # at rest at the corner: ṡ = 0 between two samples, within s̈·dt of it
        k = int(np.argmin(np.abs(plan.s - c)))
        assert abs(plan.s[k] - c) < 1e-6
        assert np.max(np.abs(plan.sd[max(k - 1, 0):k + 2])) <= 1.5 * path.acceleration * DT


# ---------------------------------------------------------------------- the path's own time law
@pytest.mark.parametrize("kw", [{"jerk": 5.0}, {"law": "quintic"}, {}])
def test_the_progress_respects_the_path_speed_acceleration_and_jerk(kw):
    """The governor replaces the path's law by its own progress but never exceeds the path's
    speed, acceleration and jerk: the path's ``jerk``, or for a quintic law the law's own
    largest jerk (the report: 375 m/s³ against a jerk limit of 5). With limits that do not bind
    the jerk-limited progress takes about as long as the path's jerk-limited law."""
    arm = rc.robots.ur5e()
    q0 = np.array([0.3, -1.3, 1.6, -1.9, -1.2, 0.2])
    T0 = arm.fk(q0)
    T1 = T0.copy()
    T1[:3, 3] += [0.0, 0.1, 0.0]
    line = rc.paths.Line(T0, T1, speed=0.2, acceleration=1.0, **kw)
    gov = Governor()
    plan = gov.plan(arm, line, q0, dt=1e-3)
    limit = gov.progress_jerk_limit(line)
    s = np.asarray(plan.s)
    assert np.max(np.diff(s)) / 1e-3 <= line.speed * (1 + 1e-9)
    assert np.max(np.abs(np.diff(s, 2))) / 1e-6 <= line.acceleration * (1 + 1e-6)
    if not kw:
        assert limit is None and plan.info["averaging_window"] == 0.0
        return
    assert limit == pytest.approx(line.law.max_jerk)
    assert plan.info["progress_jerk"] <= limit * (1 + 1e-9) and plan.info["progress_jerk_limit"] == limit
    if "jerk" in kw:
        assert plan.duration == pytest.approx(line.duration, abs=0.02)
    else:  # faster than the quintic, with no more jerk
        assert plan.duration < line.duration
