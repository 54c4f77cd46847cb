"""Path following through singular neighbourhoods: governor, time law, exact inverse, other arms.

The UR5e wrist line: constant orientation, 0.2 m/s, passing the
wrist singularity (q5 = 0) at a closest approach of |q5| = 0.01 rad, where the exact
inverse would need ~20 rad/s (vmax = π rad/s).
"""

import math

import numpy as np
import pytest

import ratectl as rc
from ratectl.errors import InputError
from ratectl.planning import joint_path

DT = 2e-3
@pytest.fixture(scope="module")
def ur5e():
    return rc.robots.ur5e()


@pytest.fixture(scope="module")
def scenario(ur5e_wrist_line):
    """(line, q0) of the acceptance line (tests/conftest.py)."""
    return ur5e_wrist_line[1:]


@pytest.fixture(scope="module")
def governed(ur5e, scenario):
    line, q0 = scenario
    return rc.follow(ur5e, line, q0, dt=DT)


def test_scenario_passes_close_to_the_wrist_singularity(ur5e, scenario):
    line, q0 = scenario
    jp = joint_path(ur5e, line, q0)
    assert jp.complete
    q5 = np.abs(jp.q[:, 4])
    assert 0.0095 < q5.min() < 0.0105  # the closest approach is the intended 0.01 rad
    assert 0.4 * line.length < jp.s[np.argmin(q5)] < 0.6 * line.length
    need = np.max(np.abs(jp.dq), axis=0) * line.speed  # exact-inverse joint speeds at 0.2 m/s
    assert 35.0 < need.max() < 50.0 and need.max() > 10 * ur5e.vmax.max()  # the demo's 42 rad/s


def test_governor_completes_within_limits_and_on_the_line(ur5e, governed):
    run = governed
    assert run.completed, run.message
    assert np.all(np.isfinite(run.qd))
    assert np.all(np.abs(run.qd) <= ur5e.vmax * (1 + 1e-9))
    assert np.all(np.abs(run.qdd) <= ur5e.amax * (1 + 1e-9))
    # q̈ is the difference of q̇ (not just a reported number)
    assert np.allclose(run.qdd[1:-1], np.diff(run.qd, axis=0)[:-1] / DT, atol=1e-6)
    assert run.max_position_error < 1e-3
    assert run.max_orientation_error < math.radians(0.5)
    # the recorded path error is the distance from the line (checked independently here)
    line = rc.paths.Line(run.poses[0], run.poses[-1], speed=1, acceleration=1)
    p = run.poses[:, :3, 3]
    d = line.end[:3, 3] - line.start[:3, 3]
    off = (p - line.start[:3, 3]) - np.outer((p - line.start[:3, 3]) @ d / (d @ d), d)
    assert np.max(np.linalg.norm(off, axis=1)) < 1e-3
    assert run.statuses[0] in rc.control.STATUSES


def test_governor_final_pose_and_timing(ur5e, scenario, governed):
    line, _ = scenario
    run = governed
    e = rc.spatial.pose_error(line.end, ur5e.fk(run.q[-1]))
    assert np.linalg.norm(e[:3]) < 1e-4 and math.degrees(np.linalg.norm(e[3:])) < 0.01
    # it took longer than the nominal time law, and says so
    # the nominal duration is measured like the run's: arrival of the path's own law within the
    # same tolerance of the end pose (a few ms before the law's end), the law's end is in info
    assert line.duration - 0.05 < run.nominal_duration <= line.duration
    assert run.info["law_duration"] == line.duration
    assert run.duration > run.nominal_duration + 0.2
    assert run.extra_time == pytest.approx(run.duration - run.nominal_duration)
    assert "nominal" in run.message and f"{run.nominal_duration:.3f}" in run.message
    # it slowed down where the wrist is near-singular: the slowest progress is there
    plan = run.info["plan"]
    inner = (plan.s > 0.05) & (plan.s < line.length - 0.05)  # away from the start and end ramps
    mid = plan.s[np.argmin(np.where(inner, plan.sd, np.inf))]
    assert abs(mid - line.length / 2) < 0.03
    assert min(run.sigma_min) < 0.005  # and passed close to the singularity
    assert "wrist" in set(run.kinds)  # the feedback solver reports its damping near the wrist


def test_time_law_with_adaptive_dls_completes_with_bounded_velocity(ur5e, scenario, governed):
    line, q0 = scenario
    ctrl = rc.ResolvedRateController(ur5e, solver=rc.solvers.AdaptiveDLS())
    run = rc.follow(ur5e, line, q0, dt=DT, controller=ctrl, governor=False)
    assert run.completed, run.message
    assert np.all(np.abs(run.qd) <= ur5e.vmax * (1 + 1e-9))
    assert np.all(np.abs(run.qdd) <= ur5e.amax * (1 + 1e-9))
    assert "damped" in run.statuses and "wrist" in set(run.kinds)
    # the price of keeping to the schedule: the tool leaves the line (~1 mm here), reported
    assert 5e-4 < run.max_position_error < 2e-2
    assert run.max_position_error > 100 * governed.max_position_error
    assert len(run.position_error) == run.steps


def test_exact_inverse_reports_the_singularity_instead_of_blowing_up(ur5e, scenario):
    line, q0 = scenario
    ctrl = rc.ResolvedRateController(ur5e, solver=rc.solvers.Inverse())
    run = rc.follow(ur5e, line, q0, dt=DT, controller=ctrl, governor=False)
    assert "singular" in run.statuses
    assert "wrist" in {k for k, s in zip(run.kinds, run.statuses, strict=True) if s == "singular"}
    assert np.all(np.isfinite(run.q))
    assert np.all(np.abs(run.qd) <= ur5e.vmax * (1 + 1e-9))  # not the ~20 rad/s it asked for
    assert run.max_position_error > 5e-3  # and the path error that costs is on record


def _elbow_line(arm):
    q_end = np.array([0.3, -0.8, 0.0, -0.8, 1.4, 0.2])  # elbow straight: full reach
    T_end = arm.fk(q_end)
    shoulder = arm.frames(q_end)[1][:3, 3]
    d = T_end[:3, 3] - shoulder
    d /= np.linalg.norm(d)
    T_start = T_end.copy()
    T_start[:3, 3] -= 0.1 * d
    res = rc.ik(arm, T_start, np.array([0.27, -1.28, 1.0, -1.33, 1.4, 0.23]))
    assert res.converged and res.position_error < 1e-9
    return rc.paths.Line(T_start, T_end, speed=0.2, acceleration=1.0), np.array(res.q)


def test_path_ending_at_the_elbow_boundary_is_reached(ur5e):
    """A line that ends at full reach (elbow straight, q′ ~ 1/√(L − s) unbounded at the end):
    the governor reaches the end pose within 0.1 mm on the path, the joint speed coming to
    rest there; the time law runs into the boundary bounded and reported."""
    line, q0 = _elbow_line(ur5e)
    run = rc.follow(ur5e, line, q0, dt=DT)
    assert run.completed, run.message
    plan = run.info["plan"]
    assert plan.joint_path.singular_end and "singular pose" in plan.message
    assert np.all(np.isfinite(run.q)) and np.all(np.isfinite(run.qd))
    assert np.all(np.abs(run.qd) <= ur5e.vmax * (1 + 1e-9))
    assert np.all(np.abs(np.diff(run.qd, axis=0)) / DT <= ur5e.amax * (1 + 1e-9))
    assert run.max_position_error < 1e-5  # stayed on the line
    assert np.linalg.norm(run.poses[-1][:3, 3] - line.end[:3, 3]) < 1e-4  # reached the singular end
    assert np.max(np.abs(run.qd[-1])) < 1e-3  # (practically) at rest
    assert min(run.sigma_min) < 0.01
    # any margin reduction stays local: the plan is within 10 % of its own time-optimal profile
    assert plan.duration < 1.1 * plan.optimal_duration + 0.01
    # the time law (no governor) runs toward the boundary too: bounded, and the servo that
    # settles on the end pose slows down before the singularity and says which one
    run2 = rc.follow(ur5e, line, q0, dt=DT, governor=False)
    assert np.all(np.isfinite(run2.q))
    assert np.all(np.abs(run2.qd) <= ur5e.vmax * (1 + 1e-9))
    near = [r for s, r in zip(run2.statuses, run2.reasons, strict=True)
            if s in ("approaching-singularity", "halted-singularity")]
    assert near and all(("boundary" in r or "elbow" in r) for r in near), near[:3]


def test_path_leaving_the_reachable_set_stops_with_the_reason(ur5e):
    """The elbow line continued 2 cm past full reach: the plan stops short of the boundary,
    on the line and at rest, and says that the path leaves the reachable set."""
    line, q0 = _elbow_line(ur5e)
    T_out = line.end.copy()
    T_out[:3, 3] += 0.2 * (line.end[:3, 3] - line.start[:3, 3])
    longer = rc.paths.Line(line.start, T_out, speed=0.2, acceleration=1.0)
    run = rc.follow(ur5e, longer, q0, dt=DT)
    assert not run.completed
    assert "leaves the reachable set" in run.message and "elbow" in run.message
    assert np.all(np.abs(run.qd) <= ur5e.vmax * (1 + 1e-9))
    assert run.max_position_error < 1e-5
    assert np.linalg.norm(run.poses[-1][:3, 3] - line.end[:3, 3]) < 2e-3  # stopped at the boundary
    assert np.max(np.abs(run.qd[-1])) < 1e-3


def _within(arm, q):
    return bool(np.all((q >= arm.lower - 1e-12) & (q <= arm.upper + 1e-12)))


def test_panda_circle_with_qp_and_joint_limits():
    arm = rc.robots.panda()
    q0 = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 0.8])
    T0 = arm.fk(q0)
    circle = rc.paths.Arc(T0, centre=T0[:3, 3] + [0.0, 0.08, 0.0], axis=[1, 0, 0], angle=2 * math.pi,
                          speed=0.15, acceleration=0.8)
    ctrl = rc.ResolvedRateController(arm, solver=rc.solvers.QP(), limits=arm)
    run = rc.follow(arm, circle, q0, dt=DT, controller=ctrl)
    assert run.completed, run.message
    assert _within(arm, run.q)
    assert np.all(np.abs(run.qd) <= arm.vmax * (1 + 1e-9))
    assert np.all(np.abs(run.qdd) <= arm.amax * (1 + 1e-9))
    assert run.max_position_error < 1e-4 and run.max_orientation_error < 1e-3
    assert np.linalg.norm(run.poses[-1][:3, 3] - T0[:3, 3]) < 1e-4  # a closed circle


def test_iiwa_waypoints_with_joint_limits():
    arm = rc.robots.iiwa7()
    q0 = np.array([0.0, 0.6, 0.0, -1.2, 0.0, 0.9, 0.0])
    T0 = arm.fk(q0)
    poses = [T0]
    for dp in ([0.1, 0, 0], [0.1, 0.1, -0.05], [0, 0.1, 0.05]):
        T = T0.copy()
        T[:3, 3] += dp
        poses.append(T)
    poses[2][:3, :3] = poses[2][:3, :3] @ rc.spatial.rotz(0.4)
    path = rc.paths.Waypoints(poses, blend=0.03, speed=0.15, acceleration=0.8)
    run = rc.follow(arm, path, q0, dt=DT)
    assert run.completed, run.message
    assert _within(arm, run.q)
    assert np.all(np.abs(run.qd) <= arm.vmax * (1 + 1e-9))
    assert np.all(np.abs(run.qdd) <= arm.amax * (1 + 1e-9))
    assert run.max_position_error < 1e-4 and run.max_orientation_error < 1e-3
    for T, cut in zip(poses, path.corner_distances, strict=True):  # each corner, cut as documented
        assert np.min(np.linalg.norm(run.poses[:, :3, 3] - T[:3, 3], axis=1)) < cut + 1e-4


def test_joint_limit_on_a_path_is_held_and_reported():
    """A Panda rotation about the flange axis that needs joint 7 beyond its limit (2.8973 rad):
    the controller holds the limit, reports it, and the orientation error at the end is on record."""
    arm = rc.robots.panda()
    q0 = np.array([0.0, -0.3, 0.0, -2.0, 0.0, 1.8, 2.6])
    T0 = arm.fk(q0)
    T1 = T0.copy()
    T1[:3, :3] = T0[:3, :3] @ rc.spatial.rotz(0.8)
    path = rc.paths.Line(T0, T1, speed=0.15, acceleration=0.8)
    run = rc.follow(arm, path, q0, dt=DT, governor=False)
    assert _within(arm, run.q)
    assert "joint-limit" in run.statuses
    assert run.q[-1, 6] == pytest.approx(arm.upper[6], abs=1e-3)
    assert np.all(np.abs(run.qd) <= arm.vmax * (1 + 1e-9))
    assert np.all(np.abs(run.qdd) <= arm.amax * (1 + 1e-6))
    # the tool stops turning at the limit: it stays on the path (the pose metric finds the point
    # of the rotation it reached), short of the end by more than 10° — on record as the end error
    assert not run.completed and run.max_orientation_error < math.radians(0.1)
    assert run.info["end_orientation_error"] > math.radians(10) and "end pose not reached" in run.message
    # the governor sees it coming and says so
    plan = rc.planning.plan(arm, path, q0, dt=DT)
    assert not plan.complete and "position limit of joint 6" in plan.message


def test_approach_move_to_the_path_start(ur5e, scenario):
    line, q0 = scenario
    q_off = q0 + np.array([0.05, -0.04, 0.03, 0.02, 0.0, -0.05])
    run = rc.follow(ur5e, line, q_off, dt=DT, settle=0.2)
    approach = run.info["approach"]
    assert approach.source == "approach" and approach.duration > 0
    assert np.allclose(approach.q[0], q_off)
    assert np.all(np.abs(approach.qd) <= ur5e.vmax * (1 + 1e-9))
    assert np.allclose(ur5e.fk(approach.q[-1]), line.start, atol=1e-9)
    assert run.completed
    with pytest.raises(InputError, match="start of the path"):
        rc.follow(ur5e, line, q_off, dt=DT, approach=False)


def test_execution_record_and_plot(governed, tmp_path):
    run = governed
    K = run.steps
    assert run.t.shape == (K,) and run.q.shape == (K, 6) and run.qd.shape == (K, 6)
    assert run.poses.shape == (K, 4, 4) and len(run.statuses) == K and run.sigma_min.shape == (K,)
    assert np.allclose(np.diff(run.t), DT)
    assert "completed" in run.summary()
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    fig = run.plot(file=tmp_path / "run.png")
    assert (tmp_path / "run.png").stat().st_size > 10_000
    assert len(fig.axes) >= 3
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_follow_input_errors(ur5e, scenario):
    line, q0 = scenario
    with pytest.raises(InputError, match="dt"):
        rc.follow(ur5e, line, q0, dt=0.0)
    with pytest.raises(InputError, match="Path"):
        rc.follow(ur5e, "line", q0, dt=DT)
    with pytest.raises(InputError):
        rc.follow(ur5e, line, q0[:5], dt=DT)
    outside = q0.copy()
    outside[2] = ur5e.upper[2] + 0.1
    with pytest.raises(InputError, match=r"outside the joint position limits.*joint 'elbow'"):
        rc.follow(ur5e, line, outside, dt=DT)


@pytest.mark.parametrize(("options", "argument"), [
    ({"controller": "ctrl"}, "controller"),
    ({"governor": "yes"}, "governor"),
    ({"settle": -1.0}, "settle"),
    ({"tolerance": 1e-4}, "tolerance"),
    ({"tolerance": (0.0, 0.0)}, "tolerance[0] (position)"),
    ({"path_tolerance": (1e-4, float("nan"))}, "path_tolerance[1] (orientation)"),
])
def test_follow_options_are_checked_before_any_work(ur5e, scenario, options, argument):
    line, q0 = scenario
    with pytest.raises(InputError) as info:
        rc.follow(ur5e, line, q0, dt=DT, **options)
    assert info.value.argument == argument


def test_follow_refuses_a_controller_of_another_arm_with_the_same_joint_count(ur5e, scenario):
    line, q0 = scenario
    with pytest.raises(InputError, match=r"another arm \('PUMA 560'.*forward kinematics differ"):
        rc.follow(ur5e, line, q0, dt=DT, controller=rc.ResolvedRateController(rc.robots.puma560()))
    # the same arm built twice is the same arm
    run = rc.follow(ur5e, line, q0, dt=DT, controller=rc.ResolvedRateController(rc.robots.ur5e()))
    assert run.completed


def test_chain_without_limits():
    """Absent limits (inf) must not break the governor, the controller or the record."""
    rows = [rc.DH(a=r.a, alpha=r.alpha, d=r.d) for r in rc.robots.ur5e().table]
    arm = rc.Chain.from_dh(rows, name="UR5e without limits")
    q0 = np.array([0.0, -1.2, 1.4, -1.8, 0.9, 0.3])
    T0 = arm.fk(q0)
    T1 = T0.copy()
    T1[0, 3] += 0.1
    line = rc.paths.Line(T0, T1, speed=0.2, acceleration=1.0)
    for governor in (True, False):
        run = rc.follow(arm, line, q0, dt=DT, governor=governor)
        assert run.completed, run.message
        assert run.max_position_error < 1e-3


def test_governor_bounds_the_progress_acceleration_where_q_prime_is_large():
    """A UR5e line (0.16 m, with a turn of the tool) that stays near-singular (σ_min ≈ 0.008,
    |q'| up to ~18 rad/m) at a path acceleration of 2.4 m/s²: q̈ = q' s̈ would be ~4× amax if
    the progress accelerated at the path's rate. The governor holds s̈ inside what the joint
    accelerations allow; the run stays on the path and completes."""
    arm = rc.robots.ur5e()
    q0 = np.array([-5.983185307179586, -1.695879997441331, -2.64754555936766,
                   1.9178113273996082, -2.8418960417693633, 2.546601025678177])
    T0 = arm.fk(q0)
    T1 = T0.copy()
    T1[:3, 3] += [-0.05106224678981267, -0.00115330616865868, -0.14853751842635451]
    T1[:3, :3] = T0[:3, :3] @ np.array([[0.6948634920946448, 0.6499245106765188, -0.3078357642898606],
                                        [-0.6392006892815677, 0.7543214955375963, 0.14973830569327498],
                                        [0.3295257291563194, 0.09272115072523275, 0.9395826637567259]])
    line = rc.paths.Line(T0, T1, speed=0.48940804487122, acceleration=2.4392279702545707)
    plan = rc.planning.plan(arm, line, q0, dt=DT)
    assert plan.acceleration_ratio <= 1.0 and plan.velocity_ratio <= 1.0, plan.message
    run = rc.follow(arm, line, q0, dt=DT)
    assert run.completed, run.message
    assert run.max_position_error < 1e-6
    assert np.all(np.abs(run.qdd) <= arm.amax * (1 + 1e-9))


def test_near_singular_start_is_planned_and_the_boundary_reported():
    """A start 6e-4 from the elbow singularity (σ_min) is not a reason to refuse: the path
    can be followed from there until it leaves the reachable set 17 mm later, where the plan
    stops, on the line, and says why. (The old σ_min < 1e-3 threshold refused the start.)"""
    arm = rc.robots.ur5e()
    q0 = np.array([0.9357736107507408, 1.4736851325763833, 0.04116423580508854,
                   5.840369137727672, -3.435318204135431, 2.375385061580211])
    T0 = arm.fk(q0)
    T1 = T0.copy()
    T1[:3, 3] += [0.03543505953235257, 0.04163865350301778, -0.0276551718321012]
    line = rc.paths.Line(T0, T1, speed=0.4, acceleration=0.5)
    run = rc.follow(arm, line, q0, dt=DT)
    assert not run.completed and "leaves the reachable set" in run.message
    assert 0.015 < run.info["plan"].s[-1] < 0.0173
    assert run.max_position_error < 1e-5
    assert np.all(np.abs(run.qd) <= arm.vmax * (1 + 1e-9))
    run = rc.follow(arm, line, q0, dt=DT, governor=False)  # the time law damps through it
    assert np.all(np.abs(run.qd) <= arm.vmax * (1 + 1e-9))


def test_governor_refuses_a_path_that_cannot_leave_its_start(ur5e):
    """At the exact wrist singularity (q5 = 0) a line whose tangent is outside the range of J
    cannot be started: InputError, saying so."""
    q = np.array([0.0, -2.0, -1.6, -1.2, 0.0, 0.0])
    T0 = ur5e.fk(q)
    T1 = T0.copy()
    T1[:3, 3] += 0.1 * np.array([math.cos(math.radians(30)), math.sin(math.radians(30)), 0.0])
    line = rc.paths.Line(T0, T1, speed=0.2, acceleration=1.0)
    with pytest.raises(InputError, match="cannot plan this path from q0.*reachable set"):
        rc.follow(ur5e, line, q, dt=DT)


def test_start_rotated_half_a_turn_about_the_tool_axis(ur5e, scenario):
    """Issue #11: a start whose tool orientation differs from the path start by π about the
    tool z axis; the approach move (rc.ik on the exact pose error) brings it to the start and
    the run completes on the path."""
    line, q0 = scenario
    q_flip = q0.copy()
    q_flip[5] -= math.pi  # the last joint turns the tool about its z axis (−π keeps the path
    # inside the joint range: the path itself turns q6 by about +π near the wrist singularity)
    e = rc.spatial.pose_error(line.start, ur5e.fk(q_flip))
    assert np.linalg.norm(e[:3]) < 1e-9 and abs(np.linalg.norm(e[3:]) - math.pi) < 1e-9
    run = rc.follow(ur5e, line, q_flip, dt=DT, settle=0.2)
    assert "approach" in run.info
    assert np.allclose(ur5e.fk(run.info["approach"].q[-1]), line.start, atol=1e-9)
    assert run.completed, run.message
    assert run.max_position_error < 1e-5
    assert np.linalg.norm(run.poses[-1][:3, 3] - line.end[:3, 3]) < 1e-4


def _exact_wrist_line(arm):
    """A UR5e line through the wrist singularity q5 = 0 itself: its tangent twist is J(q*)·q̇*
    at the singular q*, so it lies in the range of J."""
    q_star = np.array([0.0, -2.0, -1.6, -1.2, 0.0, 0.0])
    qd_star = np.array([0.1, -0.2, 0.15, 0.05, 1.0, -0.1])
    Tc, J = arm.fk_jacobian(q_star)
    xi = J @ qd_star
    scale = 1.0 / math.hypot(np.linalg.norm(xi[:3]), 0.1 * np.linalg.norm(xi[3:]))
    Ta, Tb = Tc.copy(), Tc.copy()
    Ta[:3, 3] -= 0.1 * scale * xi[:3]
    Tb[:3, 3] += 0.1 * scale * xi[:3]
    Ta[:3, :3] = rc.spatial.so3_exp(-0.1 * scale * xi[3:]) @ Tc[:3, :3]
    Tb[:3, :3] = rc.spatial.so3_exp(0.1 * scale * xi[3:]) @ Tc[:3, :3]
    q0 = rc.ik(arm, Ta, q_star - 0.1 * scale * qd_star, max_step=0.05).q
    return rc.paths.Line(Ta, Tb, speed=0.25, acceleration=1.0), np.array(q0)


def _check_run(arm, run, line, *, path_error, jerk=False):
    assert run.max_position_error <= path_error and run.max_orientation_error <= math.radians(0.01)
    assert np.linalg.norm(run.poses[-1][:3, 3] - line.end[:3, 3]) <= 1e-4
    qd = np.diff(run.q, axis=0) / DT
    assert np.all(np.abs(qd) <= arm.vmax * (1 + 1e-9))
    assert np.all(np.abs(np.diff(qd, axis=0)) / DT <= arm.amax * (1 + 1e-9))
    assert _within(arm, run.q)
    if jerk:
        assert np.all(np.abs(np.diff(run.qdd, axis=0)) / DT <= arm.jmax * (1 + 1e-6))


def test_follow_crosses_the_exact_wrist_singularity_time_optimally(ur5e):
    """Issue #13: the exact wrist crossing completes on the path within every limit in the time
    of the time-optimal profile (at the governor's margins); smoothed, it stays within 0.05 mm and jmax
    and takes at most 1.5× as long."""
    line, q0 = _exact_wrist_line(ur5e)
    run = rc.follow(ur5e, line, q0, dt=DT)
    assert run.completed, run.message
    _check_run(ur5e, run, line, path_error=1e-5)
    assert np.min(np.abs(run.q[:, 4])) < 2e-3 and run.q[0, 4] * run.q[-1, 4] < 0  # through q5 = 0
    smoothed = rc.follow(ur5e, line, q0, dt=DT, controller=rc.ResolvedRateController(ur5e, smoothing=True))
    assert smoothed.completed, smoothed.message
    _check_run(ur5e, smoothed, line, path_error=5e-5, jerk=True)
    assert smoothed.duration <= 1.5 * run.duration
    # the run takes the time of the reachability profile (which tests/planning/test_topp.py
    # checks against toppra), plus the settling steps
    plan = run.info["plan"]
    assert run.duration <= plan.optimal_duration / 0.96 + 0.01


def test_a_tiny_period_is_refused_at_once_on_the_time_law(ur5e, scenario):
    import time

    line, q0 = scenario
    t0 = time.perf_counter()
    with pytest.raises(rc.InputError, match="steps"):
        rc.follow(ur5e, line, q0, dt=1e-9, governor=False)
    assert time.perf_counter() - t0 < 2.0


# ---------------------------------------------------------------------- departures and end errors
def _tours(ur5e):
    """The new-user report's three paths (UR5e, q0 of the report): a 0.6 rad rotation on the spot,
    a tour that rotates on the spot, moves 10 cm and returns to its start, and an out-and-back
    tour whose last waypoint is 0.1 mm above its first."""
    q0 = np.array([0.3, -1.3, 1.6, -1.9, -1.2, 0.2])
    T0 = ur5e.fk(q0)
    Tr = T0.copy()
    Tr[:3, :3] = rc.spatial.rotx(0.6) @ T0[:3, :3]
    Tm = T0.copy()
    Tm[:3, 3] += [0.0, 0.1, 0.0]
    return q0, {
        "rotation on the spot": rc.paths.Line(T0, Tr, speed=0.1, acceleration=0.5),
        "rotate, move, return": rc.paths.Waypoints([T0, Tr, Tm, T0], blend=0.02, speed=0.15,
                                                   acceleration=1.0),
        "out and back": rc.paths.Waypoints(
            [T0, Tm, T0 @ rc.spatial.transform(None, np.array([0, 0, 1e-4]))], blend=0.03, speed=0.1,
            acceleration=1.0),
    }


@pytest.mark.parametrize("name", ["rotation on the spot", "rotate, move, return", "out and back"])
def test_no_false_departure_where_the_path_revisits_a_position(ur5e, name):
    """follow measures the distance from the path near the commanded s in the pose metric: a
    tool that tracks the path (tracking error ~1e-8 m) is not reported as having left it (it
    was: 34.4°, 94.2 mm / 31.9° and 0.1 mm from a position-only, global-looking search)."""
    q0, paths = _tours(ur5e)
    path = paths[name]
    run = rc.follow(ur5e, path, q0, dt=DT)
    assert run.completed, run.message
    assert np.max(run.tracking_error) < 1e-5
    assert run.max_position_error < 1e-6 and run.max_orientation_error < 1e-6
    assert run.info["end_position_error"] < 1e-6


def test_end_errors_measure_the_path_end_and_the_stop_separately(ur5e):
    """A governed run that stops short (the path leaves the reachable set 256 mm before its end):
    end_position_error is the distance to the path's end pose (it was 1e-11, measured against
    the planned stop), stop_position_error the distance to where the plan stopped."""
    q0 = np.array([0.3, -1.3, 1.6, -1.9, -1.2, 0.2])
    T = ur5e.fk(q0)
    T1 = T.copy()
    T1[:3, 3] += [0.6, 0.4, 0.2]
    line = rc.paths.Line(T, T1, speed=0.3, acceleration=1.0)
    run = rc.follow(ur5e, line, q0, dt=DT)
    assert not run.completed and "leaves the reachable set" in run.message
    to_end = float(np.linalg.norm(run.poses[-1][:3, 3] - T1[:3, 3]))
    assert to_end > 0.2 and run.info["end_position_error"] == pytest.approx(to_end, rel=1e-9)
    assert run.info["stop_position_error"] < 1e-6 and run.info["stop_s"] < line.length - 0.2
    # a run that reaches the end has no separate stop
    q0_, paths = _tours(ur5e)
    done = rc.follow(ur5e, paths["rotation on the spot"], q0_, dt=DT, governor=False)
    assert "stop_position_error" not in done.info and done.info["end_orientation_error"] < 1e-4


def test_nominal_time_is_like_for_like_and_the_law_replacement_is_stated(ur5e):
    """A plain trapezoid line in free space: the governed run and the path's own law arrive within
    the same tolerance of the end at the same time (it read −0.010 s: the run's arrival within
    0.1 mm against the law's full duration), and the message says the governor replaced the
    law, with the limits it kept."""
    q0 = np.array([0.3, -1.3, 1.6, -1.9, -1.2, 0.2])
    T0 = ur5e.fk(q0)
    T1 = T0.copy()
    T1[:3, 3] += [0.15, -0.1, 0.05]
    T1[:3, :3] = rc.spatial.rotz(0.4) @ T0[:3, :3]
    line = rc.paths.Line(T0, T1, speed=0.25, acceleration=1.5)
    run = rc.follow(ur5e, line, q0, dt=DT)
    assert run.completed
    assert abs(run.extra_time) <= DT + 1e-12 and run.nominal_duration < line.duration
    assert "replaced the path's trapezoidal law" in run.message and "acceleration 1.5 m/s²" in run.message
    jl = rc.paths.Line(T0, T1, speed=0.25, acceleration=1.5, jerk=5.0)
    run = rc.follow(ur5e, jl, q0, dt=DT)
    assert run.completed and "jerk-limited law" in run.message and "jerk 5 m/s³" in run.message
    assert run.info["plan"].info["progress_jerk"] <= 5.0 * (1 + 1e-9)
