"""Limits that hold under faults: one-sided position limits, safe halts that keep the joint
path and a joint braking for its limit, halts on a non-finite measurement, acceleration
feed-forward at the velocity limit."""

import math
import os

import numpy as np
import pytest

import ratectl as rc

Q_REG = np.array([0.0, -1.2, 1.4, -1.8, 0.9, 0.3])


@pytest.fixture
def ur5e():
    return rc.robots.ur5e()


@pytest.mark.parametrize("smoothing", [False, True], ids=["plain", "smooth"])
def test_one_sided_position_limits_hold(ur5e, smoothing):
    """qlim = (−inf, 0.5): the joint driven by qd_ff stops at 0.5 (it ran on to 2.95 rad)."""
    arm = ur5e.with_limits(qlim=(-math.inf, 0.5))
    ctrl = rc.ResolvedRateController(arm, smoothing=smoothing)
    q = np.zeros(6)
    ff = np.zeros(6)
    ff[0] = 1.0
    top = -math.inf
    for _ in range(1500):
        cmd = ctrl.step(q, qd_ff=ff, dt=1e-3)
        q = cmd.q_next
        top = max(top, q[0])
    assert top <= 0.5 + 1e-9 and q[0] > 0.49
    assert cmd.status == "joint-limit"


@pytest.mark.parametrize("smoothing", [False, True], ids=["plain", "smooth"])
def test_a_halt_brakes_each_joint_within_its_own_limits(ur5e, smoothing):
    """A joint braking hard for its position limit keeps braking when a halt comes (the
    halt used to slow all joints together, stretching that joint past its limit)."""
    ctrl = rc.ResolvedRateController(ur5e, smoothing=smoothing)
    q = np.array([0.0, -1.2, math.pi - 0.6, -1.8, 0.9, 0.3])
    ff = np.zeros(6)
    ff[0] = ff[2] = 3.0
    worst = -math.inf
    qd_prev = np.zeros(6)
    for k in range(1500):
        bad = k >= 230  # a non-finite twist from here on: a latched halt
        cmd = ctrl.step(q, qd_ff=ff, twist=np.full(6, np.nan) if bad else None, dt=1e-3)
        assert np.all(np.abs(cmd.qd - qd_prev) <= ur5e.amax * 1e-3 * (1 + 1e-9))
        qd_prev = cmd.qd
        q = cmd.q_next
        worst = max(worst, q[2] - ur5e.upper[2])
    assert cmd.status == "halted" and np.all(np.abs(cmd.qd) < 1e-9)
    assert worst <= 1e-9


@pytest.mark.parametrize("smoothing", [False, True], ids=["plain", "smooth"])
def test_a_halt_on_a_nan_measurement_keeps_the_commanded_stream_continuous(ur5e, smoothing):
    """With q = NaN the halt continues from the last commanded position: the q_next stream
    never stalls for a period (which implied |q̈| of 200× amax)."""
    ctrl = rc.ResolvedRateController(ur5e, smoothing=smoothing)
    q = Q_REG.copy()
    ff = np.zeros(6)
    ff[0] = 2.0
    qs = []
    for k in range(1000):
        meas = q.copy()
        if k == 500:
            meas[2] = math.nan
        cmd = ctrl.step(meas, qd_ff=ff, dt=1e-3)
        q = cmd.q_next
        qs.append(q)
    acc = np.diff(np.array(qs), 2, axis=0) / 1e-6
    assert np.max(np.abs(acc) / ur5e.amax) <= 1.0 + 1e-6
    assert cmd.status == "halted" and np.all(np.abs(cmd.qd) < 1e-9)


def _halt_mid_approach(arm, smoothing: bool, at: int = 300):
    """A servo to a 17 cm step with a 30° turn from Q_REG, a NaN measurement at period
    ``at`` (a latched halt): the commanded (q, q̇) from the period before the halt on."""
    from scipy.spatial.transform import Rotation

    T0 = arm.fk(Q_REG)
    target = T0.copy()
    target[:3, 3] += [0.12, -0.08, 0.1]
    turn = Rotation.from_rotvec(math.radians(30) * np.array([0.6, 0.0, 0.8])).as_matrix()
    target[:3, :3] = turn @ T0[:3, :3]
    ctrl = rc.ResolvedRateController(arm, smoothing=smoothing)
    q, qs, qds = Q_REG.copy(), [], []
    for k in range(at + 600):
        meas = q.copy()
        if k == at:
            meas[2] = math.nan
        cmd = ctrl.step(meas, target=target, dt=1e-3)
        q = cmd.q_next
        qs.append(q)
        qds.append(cmd.qd)
    assert cmd.status == "halted" and np.all(np.abs(cmd.qd) < 1e-9)
    return np.array(qs[at - 1:]), np.array(qds[at - 1:])


def test_a_halt_keeps_the_joint_path_and_stops_in_the_slowest_joints_time(ur5e):
    """Without smoothing the joints slow down together: every commanded q̇ of the halt is
    q̇ at the halt scaled by one factor (the joint path goes on straight; each joint on its
    own bent it by 6.5 mrad and the tool 0.65 mm off its line), every joint comes to rest in
    the same period, no later than the slowest joint's own stop at amax, and no joint
    changes speed by more than amax·dt."""
    qs, qds = _halt_mid_approach(ur5e, smoothing=False)
    v0 = qds[0]
    assert np.max(np.abs(v0)) > 0.5  # moving fast when the halt came
    scale = qds @ v0 / (v0 @ v0)
    assert np.allclose(qds, scale[:, None] * v0, rtol=0.0, atol=1e-12)
    assert np.all(np.diff(scale) <= 0.0)
    at_rest = np.all(np.abs(qds) == 0.0, axis=1)
    first = int(np.argmax(at_rest))
    assert np.all(at_rest[first:])
    assert first <= math.ceil(np.max(np.abs(v0) / (ur5e.amax * 1e-3))) + 1
    assert np.max(np.abs(np.diff(qds, axis=0)) / (ur5e.amax * 1e-3)) <= 1.0 + 1e-9


def test_a_smoothed_halt_stops_the_joints_together_near_their_path(ur5e):
    """With smoothing the joints stop on the filter's time-synchronised jerk-limited stop:
    the joint path of the stop stays within 3 % of its length of its chord (each joint on
    its own: 10 %), within amax."""
    qs, qds = _halt_mid_approach(ur5e, smoothing=True)
    chord = qs[-1] - qs[0]
    u = chord / np.linalg.norm(chord)
    rel = qs - qs[0]
    off = np.linalg.norm(rel - np.outer(rel @ u, u), axis=1)
    assert np.max(off) <= 0.03 * np.linalg.norm(chord)
    assert np.max(np.abs(np.diff(qds, axis=0)) / (ur5e.amax * 1e-3)) <= 1.0 + 1e-9


def test_a_smoothed_halt_mid_approach_ramps_out_and_comes_to_rest():
    """URDF arm (no amax in the file, given with_limits), servoing to a step target with
    smoothing; a NaN measurement mid-approach. The joints stop together on the filter's
    jerk-limited stop: a joint's speed grows at most by a²/(2·jmax) while its acceleration
    ramps out, |q̈| ≤ amax, and the arm comes to rest."""
    path = os.path.join(os.path.dirname(__file__), "..", "data", "irb_like.urdf")
    arm = rc.Chain.from_urdf(path).with_limits(amax=10.0, jmax=100.0)
    q0 = np.array([0.2, 0.3, -0.2, 0.1, 0.6, 0.1])
    target = arm.fk(q0)
    target[:3, 3] += [0.04, -0.03, 0.02]
    ctrl = rc.ResolvedRateController(arm, smoothing=True)
    q, qds = q0.copy(), []
    for k in range(200):
        meas = q.copy()
        if k == 50:
            meas[1] = math.nan
            v0, a0 = ctrl.qd, np.array(ctrl._m.qdd)
        cmd = ctrl.step(meas, target=target, dt=2e-3)
        qds.append(np.array(cmd.qd))
        q = np.array(cmd.q_next)
    qd = np.array(qds)
    assert np.max(np.abs(v0)) > 0.1  # it was moving
    ramp = np.where(a0 * v0 > 0.0, a0**2 / (2.0 * arm.jmax), 0.0)
    assert np.all(np.abs(qd[50:]).max(axis=0) <= np.abs(v0) + ramp + 1e-9)
    assert np.max(np.abs(np.diff(qd, axis=0)) / (2e-3 * arm.amax)) <= 1.0 + 1e-9
    assert cmd.status == "halted" and np.all(np.abs(cmd.qd) < 1e-9) and np.all(np.isfinite(q))


def test_smoothing_with_acceleration_feed_forward_at_the_velocity_limit(ur5e):
    """A planned q̇ at vmax with a non-zero q̈ feed-forward pushing outward stays ≤ vmax
    (it reached 1.69× vmax)."""
    ctrl = rc.ResolvedRateController(ur5e, smoothing=True)
    q = Q_REG.copy()
    worst = 0.0
    for k in range(1500):
        ff = np.zeros(6)
        ff[0] = ur5e.vmax[0] * min(1.0, k / 500)
        acc = np.zeros(6)
        acc[0] = 8.0
        cmd = ctrl.step(q, qd_ff=ff, qdd_ff=acc, dt=1e-3)
        q = cmd.q_next
        worst = max(worst, float(np.max(np.abs(cmd.qd) / ur5e.vmax)))
    assert worst <= 1.0 + 1e-9


def test_a_stamp_must_be_a_time_and_a_target_from_the_future_halts():
    """stamp='now' is a programming error (InputError, nothing moves); a target stamped far
    ahead of ctrl.time means two clocks disagree: the cycle halts instead of trusting it
    forever (it was never stale)."""
    arm = rc.robots.ur5e()
    q = np.array([0.3, -1.3, 1.6, -1.9, -1.2, 0.2])
    T = arm.fk(q)
    T[0, 3] += 0.05
    ctrl = rc.ResolvedRateController(arm)
    for bad in ("now", b"1", True, [1.0], object()):
        with pytest.raises(rc.errors.InputError, match="stamp"):
            ctrl.step(q, target=T, dt=1e-3, stamp=bad)
    assert ctrl.time == 0.0
    cmd = ctrl.step(q, target=T, dt=1e-3, stamp=1e9)
    assert cmd.status == "halted" and "ahead of the controller clock" in cmd.reason
    cmd = ctrl.step(q, target=T, dt=1e-3, stamp=ctrl.time + 0.5 * ctrl.timeout)  # within timeout: fine
    assert cmd.status != "halted"
    cmd = ctrl.step(q, target=T, dt=1e-3, stamp=float("nan"))
    assert cmd.status == "halted" and "stale" in cmd.reason


@pytest.mark.parametrize("smoothing", [False, True], ids=["plain", "smooth"])
def test_a_jog_on_a_stale_twist_halts(smoothing):
    """A teleoperator's twist stamped on ctrl.time: while fresh the arm jogs; once the
    stream stops (the same twist, its stamp older than the timeout) the cycle halts and the
    arm comes to rest — the stamp used to be read for targets only, and the arm jogged on
    the last twist (230 mm in a second); a fresh twist resumes."""
    arm = rc.robots.ur5e()
    ctrl = rc.ResolvedRateController(arm, smoothing=smoothing)
    q = Q_REG.copy()
    xi = np.array([0.1, 0.0, 0.0, 0.0, 0.0, 0.0])
    dt = 1e-3
    for _ in range(200):
        cmd = ctrl.step(q, twist=xi, stamp=ctrl.time, dt=dt)
        q = cmd.q_next
    assert cmd.status != "halted" and np.max(np.abs(cmd.qd)) > 0.05
    stamp = ctrl.time  # the stream stops: the last twist keeps its stamp
    p_stale = arm.fk(q)[:3, 3]
    statuses = []
    for _ in range(600):
        cmd = ctrl.step(q, twist=xi, stamp=stamp, dt=dt)
        q = cmd.q_next
        statuses.append(cmd.status)
    assert statuses[-1] == "halted" and "stale twist" in cmd.reason, cmd.reason
    assert np.all(np.abs(cmd.qd) < 1e-9)
    # it ran on for one timeout, then braked: well short of 600 ms of jogging at 0.1 m/s
    assert np.linalg.norm(arm.fk(q)[:3, 3] - p_stale) < 0.03
    cmd = ctrl.step(q, twist=xi, stamp=ctrl.time, dt=dt)  # fresh again: it jogs
    assert cmd.status != "halted"
