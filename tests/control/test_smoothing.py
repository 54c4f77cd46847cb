"""Ruckig smoothing: the online velocity filter, state-to-state moves, stops, and the smoothed
path example (UR5e line past the wrist singularity)."""

import math

import numpy as np
import pytest

import ratectl as rc
from ratectl.control.smoothing import VelocityFilter, move, stop
from ratectl.errors import InputError


def _check_limits(qd, qdd, dt, vmax, amax, jmax, *, rel=1e-6):
    assert np.all(np.abs(qd) <= vmax * (1 + rel) + 1e-12)
    assert np.all(np.abs(qdd) <= amax * (1 + rel) + 1e-12)
    jerk = np.diff(qdd, axis=0) / dt
    assert np.all(np.abs(jerk) <= jmax * (1 + rel) + 1e-9)


def test_velocity_filter_respects_limits_on_random_targets():
    rng = np.random.default_rng(7)
    vmax, amax, jmax = np.array([1.0, 2.0, 0.5]), np.array([5.0, 3.0, 2.0]), np.array([50.0, 20.0, 40.0])
    dt = 1e-3
    f = VelocityFilter(3, dt=dt, vmax=vmax, amax=amax, jmax=jmax)
    q = np.zeros(3)
    QD, QDD = [], []
    target = np.zeros(3)
    for k in range(3000):
        if k % 1000 == 0:
            target = rng.uniform(-2, 2, 3)  # some beyond vmax: clipped
        q_next, qd, qdd = f.update(q, target)
        # the position is the integral of the velocity (trapezoid is exact to O(j dt³))
        assert np.allclose(q_next - q, dt * 0.5 * (qd + (QD[-1] if QD else 0)), atol=1e-6)
        q = q_next
        QD.append(qd)
        QDD.append(qdd)
    QD, QDD = np.array(QD), np.array(QDD)
    _check_limits(QD, QDD, dt, vmax, amax, jmax)
    # it gets there: after a hold the velocity equals the (clipped) target
    assert np.allclose(QD[-1], np.clip(target, -vmax, vmax), atol=1e-9)
    # only the velocity interface, never intermediate waypoints
    assert not f._inp.intermediate_positions
    f.reset()
    assert np.all(f.velocity == 0) and np.all(f.acceleration == 0)


def test_velocity_filter_tracks_a_feasible_reference_with_acceleration_feed_forward():
    dt = 1e-3
    f = VelocityFilter(1, dt=dt, vmax=10.0, amax=10.0, jmax=100.0)
    t = np.arange(0, 2, dt)
    v = np.sin(2 * t)  # |a| ≤ 2, |j| ≤ 4: feasible
    a = 2 * np.cos(2 * t)
    f.reset(qd=[v[0]], qdd=[a[0]])
    err = []
    q = np.zeros(1)
    for k in range(1, len(t)):
        q, qd, _ = f.update(q, [v[k]], [a[k]])
        err.append(abs(qd[0] - v[k]))
    assert max(err) < 1e-6
    with pytest.raises(InputError, match="vmax"):
        VelocityFilter(2, dt=dt, vmax=[1.0, math.inf], amax=1.0, jmax=1.0)


def test_move_is_synchronised_and_within_limits():
    arm = rc.robots.ur5e()
    q0 = np.array([0.0, -1.2, 1.4, -1.8, 0.9, 0.3])
    q1 = q0 + np.array([0.8, -0.3, 0.2, 0.5, -0.4, 1.5])
    traj = move(q0, q1, vmax=arm.vmax, amax=arm.amax, jmax=arm.jmax)
    dt = 1e-3
    t, q, qd, qdd = traj.sample(dt)
    assert np.allclose(q[0], q0) and np.allclose(q[-1], q1, atol=1e-9)
    assert np.allclose(qd[-1], 0, atol=1e-9) and np.allclose(qdd[-1], 0, atol=1e-9)
    _check_limits(qd, qdd[:-1], dt, arm.vmax, arm.amax, arm.jmax, rel=1e-3)
    # synchronised: every joint is still moving until near the end
    moving = np.abs(qd[int(0.9 * len(t))]) > 1e-6
    assert np.all(moving)
    # from a moving start
    traj2 = move(q0, q1, vmax=arm.vmax, amax=arm.amax, jmax=arm.jmax, qd_start=np.full(6, 0.5))
    assert np.allclose(traj2.at(0)[1], 0.5) and np.allclose(traj2.at(traj2.duration)[0], q1, atol=1e-9)
    with pytest.raises(InputError):
        move(q0, q1[:5], vmax=arm.vmax, amax=arm.amax, jmax=arm.jmax)


def test_stop_comes_to_rest_within_limits():
    arm = rc.robots.ur5e()
    q = np.zeros(6)
    qd = np.array([1.0, -2.0, 0.5, 3.0, 0.0, -1.0])
    traj = stop(q, qd, amax=arm.amax, jmax=arm.jmax)
    t, Q, QD, QDD = traj.sample(1e-3)
    assert np.allclose(QD[0], qd) and np.allclose(QD[-1], 0, atol=1e-9)
    assert np.all(np.abs(QDD) <= arm.amax * (1 + 1e-6))
    # shortest possible: the fastest joint needs at least |v|/a + a/j
    assert traj.duration >= 3.0 / 10.0


def test_smoothed_line_near_the_wrist_singularity(ur5e_wrist_line):
    """The acceptance line (tests/conftest.py) with a Ruckig-smoothed controller: jerk limits
    respected, the tool within 2 mm of the line."""
    arm, line, q0 = ur5e_wrist_line
    dt = 2e-3
    ctrl = rc.ResolvedRateController(arm, smoothing=True)
    run = rc.follow(arm, line, q0, dt=dt, controller=ctrl)
    assert run.completed, run.message
    _check_limits(run.qd, run.qdd, dt, arm.vmax, arm.amax, arm.jmax)
    assert run.max_position_error < 2e-3
    assert run.max_orientation_error < math.radians(0.5)
    assert run.info["plan"].info["jerk_ratio"] <= 0.95  # the plan itself was made jerk-feasible


def test_stopping_distance_is_ruckigs_stop():
    """The closed form equals the end of Ruckig's time-optimal stop, and braking_speed inverts it."""
    from ratectl.model.limits import braking_speed, stopping_distance

    rng = np.random.default_rng(3)
    for _ in range(100):
        A, J = rng.uniform(1, 20), rng.uniform(10, 5000)
        v, a = rng.uniform(0, 4), rng.uniform(0, A)
        traj = stop([0.0], [v], qdd=[a], amax=A, jmax=J)
        assert stopping_distance(v, a, A, J) == pytest.approx(traj.goal[0], rel=1e-9, abs=1e-12)
    d = np.linspace(0.0, 3.0, 61)
    assert np.allclose(stopping_distance(braking_speed(d, 10.0, 100.0), 0.0, 10.0, 100.0), d, atol=1e-12)
    # already braking (a < 0) is counted as not braking: an upper bound
    assert stopping_distance(1.0, -5.0, 10.0, 100.0) >= stop([0.0], [1.0], qdd=[-5.0], amax=10.0,
                                                             jmax=100.0).goal[0]


def test_velocity_filter_recovers_when_ruckig_cannot_synchronise():
    """A state Ruckig's time synchronisation rejects (RuckigError in its step 2, met on an
    iiwa7 path): the filter falls back to per-joint motion at rest acceleration instead of
    raising in the user's loop."""
    f = VelocityFilter(7, dt=2e-3, vmax=[1.71, 1.71, 1.745, 2.269, 2.443, 3.142, 3.142], amax=10.0,
                       jmax=100.0)
    f.reset(qd=[-0.05971649383830478, -0.1309192623430496, -0.01776901275928095, -0.09123812916814403,
                -0.0645469463746311, 0.1863866460653286, 0.02585491503439401],
            qdd=[0.6559873238200018, 1.453979502924527, -0.06743863867464162, 1.901289305619291,
                 0.1886920668585949, -3.334979174657568, -0.9202237525438611])
    q = np.array([-0.8255628818929327, 0.2930138494979546, 0.01055071203163725, -2.092736463619235,
                  1.967363485251749, -1.354263458469058, 2.122630406070826])
    target_v = np.array([-0.03492209222939317, -0.07787573730150685, -0.02008939487198102, 0.0,
                         -0.05674084556935555, 0.1244640283164932, -0.007660046111202121])
    target_a = np.array([0.2839640561025369, 0.6338189802723715, 0.004277038877578687, 1.085692223790069,
                         0.1530498126567359, -1.334530973895465, -0.2844689377390353])
    braking = np.array([False, False, False, True, False, False, False])  # joint 4 brakes alone
    q1, qd1, qdd1 = f.update(q, target_v, target_a, independent=braking)
    assert np.all(np.isfinite(q1)) and np.all(np.abs(qdd1) <= 10.0 + 1e-9)


class _FailingOTG:
    """Stands in for ruckig.Ruckig: every update and calculation raises, as the binding does
    on some inputs."""

    def __init__(self, real):
        self.delta_time = real.delta_time

    def update(self, inp, out):
        import ruckig

        raise ruckig.RuckigError("[ruckig] error in step 2 (test double)")

    def calculate(self, inp, trajectory):
        return self.update(inp, None)


def test_a_failing_filter_raises_a_ratectl_error_and_the_controller_halts():
    from ratectl.errors import SolverError

    arm = rc.robots.ur5e()
    f = VelocityFilter(6, dt=1e-3, vmax=arm.vmax, amax=arm.amax, jmax=arm.jmax)
    f._otg = _FailingOTG(f._otg)
    with pytest.raises(SolverError, match="Ruckig velocity filter failed"):
        f.update(np.zeros(6), np.full(6, 0.1))
    ctrl = rc.ResolvedRateController(arm, smoothing=f)
    q = np.array([0.0, -1.2, 1.4, -1.8, 0.9, 0.3])
    cmd = ctrl.step(q, twist=np.array([0.05, 0, 0, 0, 0, 0]), dt=1e-3)  # must not raise
    assert cmd.status == "halted" and "smoothing failed" in cmd.reason
    assert np.all(np.isfinite(cmd.qd))


def test_a_joint_braking_on_its_own_does_not_stretch_the_others():
    """Joint 0 brakes for a position limit on its own (a long stop); the other joints still
    meet their feasible (q̇, q̈) reference within the period. Ruckig stretches synchronised
    joints to the whole motion's duration, unsynchronised joints included, so a single
    update used to drag the others along the stop and lose their reference."""
    dt = 1e-3
    f = VelocityFilter(3, dt=dt, vmax=3.0, amax=10.0, jmax=100.0)
    f.reset(qd=[2.5, 0.5, -0.4], qdd=[0.0, 1.0, -0.5])
    q = np.zeros(3)
    v_ref, a_ref = np.array([0.5, -0.4]), np.array([1.0, -0.5])
    brake = np.array([True, False, False])
    for _ in range(200):
        a_next = a_ref + np.array([0.02, 0.03])  # a constant-jerk reference (|j| ≤ 30)
        v_next = v_ref + 0.5 * (a_ref + a_next) * dt
        q, qd, qdd = f.update(q, np.r_[0.0, v_next], np.r_[0.0, a_next], independent=brake)
        assert np.allclose(qd[1:], v_next, atol=1e-9) and np.allclose(qdd[1:], a_next, atol=1e-9)
        v_ref, a_ref = v_next, a_next
    # the braking joint brakes as hard as it can meanwhile: at full deceleration by now
    assert qdd[0] == pytest.approx(-10.0)


@pytest.mark.parametrize("arm", ["ur5e", "rpr", "iiwa7"])
def test_a_smoothed_step_says_target_reached_when_within_tolerance(arm):
    """The status tells the truth: a cycle within the position and orientation tolerance
    reports target-reached once the command is at rest (the tool speed within K·tolerance),
    never a limit (the approach's last braking is not one), and the reference the filter
    meets has no lag to undo (no overshoot)."""
    chain = rc.robots.BUILTIN[arm]()
    rng = np.random.default_rng(1)
    while True:  # a regular start and goal (near a singularity "damped" would be the truth)
        q = np.clip(chain.random_q(rng=rng), chain.lower + 0.4, chain.upper - 0.4)
        if min(np.linalg.svd(chain.jacobian(x), compute_uv=False)[-1] for x in (q, q + 0.05)) > 0.1:
            break
    T = chain.fk(q + 0.05)
    ctrl = rc.ResolvedRateController(chain, smoothing=True)
    reached = 0
    for _ in range(3000):
        cmd = ctrl.step(q, target=T, dt=1e-3)
        ep, eo = cmd.position_error, cmd.orientation_error
        speed = chain.jacobian(q) @ cmd.qd
        at_rest = (np.linalg.norm(speed[:3]) <= 10.0 * ctrl.position_tolerance
                   and np.linalg.norm(speed[3:]) <= 10.0 * ctrl.orientation_tolerance)
        if ep <= ctrl.position_tolerance and eo <= ctrl.orientation_tolerance:
            assert cmd.status == ("target-reached" if at_rest else "regular"), cmd
            reached += cmd.status == "target-reached"
        else:
            assert cmd.status != "target-reached", cmd
        q = cmd.q_next
    assert reached > 100


def test_with_smoothing_the_qp_gets_no_acceleration_box_around_the_filter():
    """The filter bounds q̈ and q⃛ with smoothing on; a QP acceleration box around its
    lagging output throttled the arm (about 13 % of amax: the 5 cm circle shrank to 4.0 cm,
    4935 of 5000 cycles 'acceleration-limited'). The smoothed circle now has the unsmoothed
    radius and, after the start, no acceleration-limited cycle."""
    arm = rc.robots.ur5e()
    q0 = np.array([0.3, -1.2, 1.5, -1.9, -1.4, 0.6])

    def circle(**kw):
        ctrl = rc.ResolvedRateController(arm, solver=rc.solvers.QP(), **kw)
        q, tool, statuses = q0.copy(), [], []
        for k in range(2000):
            t = k * 1e-3
            xi = np.array([-0.2 * math.sin(4 * t), 0.2 * math.cos(4 * t), 0.0, 0.0, 0.0, 0.0])
            cmd = ctrl.step(q, twist=xi, dt=1e-3)
            statuses.append(cmd.status)
            q = cmd.q_next
            tool.append(arm.fk(q)[:3, 3])
        xy = np.array(tool)[500:, :2]
        return np.linalg.norm(xy - xy.mean(axis=0), axis=1).mean(), statuses

    r_plain, _ = circle()
    r_smooth, statuses = circle(smoothing=True)
    assert abs(r_smooth - r_plain) < 1e-3
    assert "acceleration-limited" not in statuses[200:]


def test_a_reference_just_out_of_one_periods_reach_is_joined_not_detoured():
    """A velocity target with its acceleration is a moving reference line. A joint 2e-4 rad/s
    off it (8× the J·dt²/4 it can correct within one period at its acceleration) used to be
    sent on Ruckig's time-optimal way to the fixed state (v̄, ā), a detour many periods long
    that starts off the wrong way, and drifted further every period (9e-4 rad/s off after
    40 ms; the smoothed servo then overshot its target). It joins the line in a few periods,
    its acceleration swinging by no more than the time-optimal join needs, 2·√(jmax·e)."""
    dt, jmax, err0 = 1e-3, 100.0, 2e-4
    f = VelocityFilter(2, dt=dt, vmax=3.0, amax=10.0, jmax=jmax)
    f.reset([0.5 + err0, -0.3], [4.0, -1.0])
    q = np.zeros(2)
    swing = 0.0
    for k in range(1, 41):
        vt = np.array([0.5 + 4.0 * k * dt, -0.3 - 1.0 * k * dt])
        q, v, a = f.update(q, vt, np.array([4.0, -1.0]))
        swing = max(swing, abs(a[0] - 4.0))
    assert abs(v[0] - vt[0]) < 1e-9 and abs(a[0] - 4.0) < 1e-9
    assert abs(v[1] - vt[1]) < 1e-12 and abs(a[1] + 1.0) < 1e-12  # (on its line: met exactly)
    assert swing <= 2.0 * np.sqrt(jmax * err0) + 1e-9
