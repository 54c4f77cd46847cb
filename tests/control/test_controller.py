"""The resolved-rate controller: control law, statuses, limits, safe halts."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ratectl as rc
from ratectl.control import STATUSES, Command
from ratectl.errors import InputError

Q_REG = np.array([0.0, -1.2, 1.4, -1.8, 0.9, 0.3])   # a regular UR5e configuration
Q_WRIST = np.array([0.0, -1.2, 1.4, -1.8, 0.0, 0.3])  # q5 = 0: wrist singular


@pytest.fixture
def ur5e():
    return rc.robots.ur5e()


def _shifted(T, dp):
    T = T.copy()
    T[:3, 3] += dp
    return T


def test_converges_to_a_target_and_reports_it(ur5e):
    ctrl = rc.ResolvedRateController(ur5e, gain=20.0)
    target = _shifted(ur5e.fk(Q_REG), [0.02, -0.01, 0.015])
    target[:3, :3] = target[:3, :3] @ rc.spatial.rotz(0.05)
    q = Q_REG.copy()
    for _ in range(2000):
        cmd = ctrl.step(q, target=target, dt=1e-3)
        assert isinstance(cmd, Command) and cmd.status in STATUSES
        assert np.allclose(cmd.q_next, q + cmd.qd * 1e-3)
        if cmd.status == "target-reached":
            break
        q = cmd.q_next
    assert cmd.status == "target-reached"
    e = rc.spatial.pose_error(target, ur5e.fk(q))
    assert np.linalg.norm(e[:3]) < 1e-4 and np.linalg.norm(e[3:]) < 1e-3
    assert cmd.position_error == pytest.approx(np.linalg.norm(e[:3]), abs=1e-9)
    with pytest.raises(AttributeError):  # frozen
        cmd.status = "regular"


def test_control_law_feed_forward_plus_feedback(ur5e):
    """ξ = ξ_ff + K e, resolved exactly in a regular configuration."""
    K = np.array([5.0, 5.0, 5.0, 2.0, 2.0, 2.0])
    ctrl = rc.ResolvedRateController(ur5e, gain=K, solver=rc.solvers.Inverse(), limits=None)
    T = ur5e.fk(Q_REG)
    target = _shifted(T, [0.001, 0.0, -0.002])
    xi_ff = np.array([0.01, 0.02, -0.01, 0.0, 0.05, 0.0])
    cmd = ctrl.step(Q_REG, target=target, twist=xi_ff, dt=1e-3)
    e = rc.spatial.pose_error(target, T)
    assert np.allclose(cmd.error, e) and np.allclose(cmd.twist, xi_ff + K * e)
    J = ur5e.jacobian(Q_REG)
    assert np.allclose(J @ cmd.qd, xi_ff + K * e, atol=1e-10)
    assert cmd.status == "regular" and cmd.reason == ""
    # joint feed-forward adds to the resolved rate
    ctrl.reset()
    qd_ff = np.full(6, 0.01)
    cmd2 = ctrl.step(Q_REG, target=target, twist=xi_ff, qd_ff=qd_ff, dt=1e-3)
    assert np.allclose(cmd2.qd, cmd.qd + qd_ff)


def test_damped_near_the_wrist_singularity_names_the_kind(ur5e):
    """A twist resolved with a pose feedback (not a jog) is damped near the wrist
    singularity, and the command names the kind."""
    ctrl = rc.ResolvedRateController(ur5e)
    q = Q_WRIST.copy()
    q[4] = 1e-3
    cmd = ctrl.step(q, target=ur5e.fk(q), twist=np.array([0.0, 0.05, 0.0, 0.0, 0.0, 0.0]), dt=1e-3)
    assert cmd.status == "damped" and cmd.damping > 0 and cmd.sigma_min < 0.05
    assert np.linalg.norm(cmd.task_error) > 0  # damping gave up some task velocity
    assert cmd.kind == "wrist"
    assert "wrist" in str(cmd)
    assert np.all(np.abs(cmd.qd) <= ur5e.vmax * (1 + 1e-12))


def test_a_jog_near_the_wrist_singularity_follows_its_twist_exactly_and_slower(ur5e):
    """A jog at σ_min ≈ 3e-4 (q5 = 1 mrad) along y, which does not lower σ_min: the tool
    moves along y only (the exact direction, |w| ∝ 1/σ_min, never the damped answer,
    which turns it), slowed so that every joint stays within vmax and amax."""
    ctrl = rc.ResolvedRateController(ur5e)
    q = Q_WRIST.copy()
    q[4] = 1e-3
    twist = np.array([0.0, 0.05, 0.0, 0.0, 0.0, 0.0])
    for _ in range(300):
        cmd = ctrl.step(q, twist=twist, dt=1e-3)
        tool = ur5e.jacobian(q) @ cmd.qd
        assert tool[1] >= 0.0 and np.linalg.norm(np.delete(tool, 1)) <= 1e-9 * (1e-3 + tool[1])
        assert np.all(np.abs(cmd.qd) <= ur5e.vmax * (1 + 1e-12))
        assert cmd.damping == 0.0 and cmd.kind == "wrist"
        q = cmd.q_next
    assert 0.0 < tool[1] < 0.05 * twist[1]  # well below the twist: the wrist joints spin instead


def test_exact_inverse_at_a_singularity_halts_instead_of_raising(ur5e):
    ctrl = rc.ResolvedRateController(ur5e, solver=rc.solvers.Inverse())
    for _ in range(100):
        cmd = ctrl.step(Q_REG, twist=np.array([0.05, 0, 0, 0, 0, 0]), dt=1e-3)
    assert cmd.status == "regular"
    cmd = ctrl.step(Q_WRIST, twist=np.array([0.05, 0, 0, 0, 0, 0]), dt=1e-3)
    assert cmd.status == "singular" and "singular" in cmd.reason
    assert np.all(np.abs(cmd.qd) <= np.abs(ctrl.qd) + 1e-12)  # decelerating, not blowing up
    # close to (not at) the singularity the exact inverse needs joint speeds ∝ 1/σ: a jog
    # along y (which does not lower σ_min here) stays within vmax and moves the tool along y only
    ctrl.reset()
    q = Q_WRIST.copy()
    q[4] = 2e-3
    for _ in range(300):
        cmd = ctrl.step(q, twist=np.array([0.0, 0.1, 0.0, 0.0, 0.0, 0.0]), dt=1e-3)
        assert np.all(np.abs(cmd.qd) <= ur5e.vmax * (1 + 1e-12))
        tool = ur5e.jacobian(q) @ cmd.qd
        assert abs(tool[1]) > 0.0 and np.linalg.norm(np.delete(tool, 1)) <= 1e-9 * (1 + abs(tool[1]))
        q = cmd.q_next
    assert cmd.velocity_scale < 0.2


def test_velocity_scaling_keeps_the_direction(ur5e):
    ctrl = rc.ResolvedRateController(ur5e, solver=rc.solvers.Inverse(), limits=None)
    xi = np.array([2.0, 0.0, 0.5, 0.0, 0.0, 1.0])  # far too fast for the arm
    raw = ctrl.step(Q_REG, twist=xi, dt=1e-3).qd
    lim = rc.ResolvedRateController(ur5e, solver=rc.solvers.Inverse())
    lim.reset(qd=raw / np.max(np.abs(raw) / ur5e.vmax))  # already at that velocity: no acceleration limit
    cmd = lim.step(Q_REG, twist=xi, dt=1e-3)
    assert cmd.status == "velocity-scaled" and "velocity" in cmd.limits_active
    assert np.max(np.abs(cmd.qd) / ur5e.vmax) == pytest.approx(1.0)
    assert np.allclose(cmd.qd / np.linalg.norm(cmd.qd), raw / np.linalg.norm(raw))
    assert cmd.velocity_scale == pytest.approx(1.0 / np.max(np.abs(raw) / ur5e.vmax))


def test_acceleration_limit_and_previous_velocity(ur5e):
    ctrl = rc.ResolvedRateController(ur5e)
    dt = 1e-3
    xi = np.array([0.3, 0.0, 0.0, 0.0, 0.0, 0.0])
    q = Q_REG.copy()
    prev = np.zeros(6)
    saw = False
    for _ in range(300):
        cmd = ctrl.step(q, twist=xi, dt=dt)
        assert np.all(np.abs(cmd.qd - prev) <= ur5e.amax * dt * (1 + 1e-9))
        saw |= cmd.status == "acceleration-limited"
        prev = cmd.qd
        q_used, q = q, cmd.q_next
    assert saw
    assert np.allclose(ur5e.jacobian(q_used) @ cmd.qd, xi, atol=1e-6)  # has caught up
    ctrl.reset()
    assert np.all(ctrl.qd == 0)


def test_joint_position_limit_holds(ur5e):
    """Jog the shoulder pan into its upper limit: the jog slows along its twist and stops
    just inside the limit (status joint-limit, the joint named). The elbow's ±π limit is a
    folded, singular arm, but the elbow's own twist stays in the range of J all the way
    there (bounded joint speed, no lost direction): that jog stops at the limit too."""
    ctrl = rc.ResolvedRateController(ur5e, solver=rc.solvers.DLS(damping=0.01))
    q = Q_REG.copy()
    q[0] = ur5e.upper[0] - 0.05
    seen = False
    for _ in range(400):
        J = ur5e.jacobian(q)
        xi = J @ np.array([1.0, 0, 0, 0, 0, 0])  # the twist that the shoulder pan alone would make
        cmd = ctrl.step(q, twist=xi, dt=2e-3)
        seen |= cmd.status == "joint-limit"
        q = cmd.q_next
        assert q[0] <= ur5e.upper[0] + 1e-12
    assert seen and "position" in cmd.limits_active and "'shoulder_pan'" in cmd.reason
    assert q[0] > ur5e.upper[0] - 2e-3
    q2 = Q_REG.copy()
    q2[2] = math.pi - 0.05  # the elbow toward its folded (singular) limit
    ctrl.reset()
    for _ in range(400):
        cmd = ctrl.step(q2, twist=ur5e.jacobian(q2) @ np.array([0, 0, 1.0, 0, 0, 0]), dt=2e-3)
        q2 = cmd.q_next
        assert q2[2] <= ur5e.upper[2] + 1e-12
    assert cmd.status == "joint-limit" and repr(ur5e.joint_names[2]) in cmd.reason
    assert q2[2] > ur5e.upper[2] - 2e-3


@pytest.mark.parametrize("smoothing", [False, True])
@pytest.mark.parametrize("dt", [1e-3, 4e-3])
def test_a_jog_at_rest_at_a_joint_limit_says_it_is_there(ur5e, dt, smoothing):
    """A jog that has come to rest 1 mrad before a joint's limit says the joint is at its
    limit, not that it is braking toward it (its bound there is a creep of ~1e-9 rad per
    period): the same words with and without smoothing, at any period."""
    ctrl = rc.ResolvedRateController(ur5e, smoothing=smoothing)
    q = np.array([0.3, -1.3, 1.6, -1.9, -1.2, ur5e.upper[5] - 0.3])
    for _ in range(int(3.0 / dt)):
        z_tool = ur5e.fk(q)[:3, 2]
        cmd = ctrl.step(q, twist=np.r_[0.0, 0.0, 0.0, 2.0 * z_tool], dt=dt)  # wrist 3 turns alone
        q = cmd.q_next
    assert np.max(np.abs(cmd.qd)) < 1e-6
    assert cmd.status == "joint-limit"
    assert cmd.reason == f"joint {ur5e.joint_names[5]!r} is at its upper limit"
    assert 0.9e-3 < ur5e.upper[5] - q[5] < 1.1e-3


def test_non_finite_input_halts_safely_and_latches(ur5e):
    ctrl = rc.ResolvedRateController(ur5e)
    dt = 2e-3
    q = Q_REG.copy()
    for _ in range(200):  # get moving
        cmd = ctrl.step(q, twist=np.array([0.2, 0, 0, 0, 0, 0]), dt=dt)
        q = cmd.q_next
    v0 = np.abs(cmd.qd).max()
    assert v0 > 0.1
    bad = q.copy()
    bad[1] = np.nan
    prev = cmd.qd
    cmd = ctrl.step(bad, twist=np.array([0.2, 0, 0, 0, 0, 0]), dt=dt)
    assert cmd.status == "halted" and "non-finite q" in cmd.reason and ctrl.halted
    assert np.all(np.isfinite(cmd.q_next)) and np.all(np.isfinite(cmd.qd))
    steps = 0
    while np.abs(cmd.qd).max() > 0:
        assert np.all(np.abs(cmd.qd - prev) <= ur5e.amax * dt * (1 + 1e-9))  # within amax
        assert np.all(np.sign(cmd.qd) * np.sign(prev) >= 0)  # no reversal
        prev = cmd.qd
        cmd = ctrl.step(cmd.q_next, twist=np.array([0.2, 0, 0, 0, 0, 0]), dt=dt)  # good input again
        assert cmd.status == "halted"  # latched
        steps += 1
        assert steps < 1000
    ctrl.reset()
    assert not ctrl.halted
    assert ctrl.step(q, twist=np.zeros(6), dt=dt).status != "halted"
    for kw in ({"target": np.full((4, 4), np.inf)}, {"twist": np.array([0, 0, np.nan, 0, 0, 0])}):
        ctrl.reset()
        assert ctrl.step(q, dt=dt, **kw).status == "halted"
    ctrl.reset()
    assert ctrl.step(q, twist=np.zeros(6), dt=float("nan")).status == "halted"


def test_stale_target_halts_and_resumes(ur5e):
    ctrl = rc.ResolvedRateController(ur5e, timeout=0.05)
    T = ur5e.fk(Q_REG)
    q = Q_REG.copy()
    cmd = ctrl.step(q, target=T, stamp=0.0, dt=0.01)
    assert cmd.status != "halted"
    for _ in range(6):
        cmd = ctrl.step(q, target=T, stamp=0.0, dt=0.01)
    assert cmd.status == "halted" and "stale" in cmd.reason and not ctrl.halted
    cmd = ctrl.step(q, target=T, stamp=ctrl.time, dt=0.01)
    assert cmd.status != "halted"


def test_smoothing_respects_jerk_limits(ur5e):
    ctrl = rc.ResolvedRateController(ur5e, smoothing=True)
    dt = 1e-3
    q = Q_REG.copy()
    prev_a = np.zeros(6)
    for k in range(400):
        xi = np.array([0.2 if k < 200 else -0.2, 0, 0.1, 0, 0, 0])
        cmd = ctrl.step(q, twist=xi, dt=dt)
        assert np.all(np.abs(cmd.qd) <= ur5e.vmax + 1e-9)
        assert np.all(np.abs(cmd.qdd) <= ur5e.amax + 1e-9)
        assert np.all(np.abs(cmd.qdd - prev_a) <= ur5e.jmax * dt * (1 + 1e-6))
        prev_a = cmd.qdd
        q = cmd.q_next


def test_input_shape_errors_raise(ur5e):
    ctrl = rc.ResolvedRateController(ur5e)
    with pytest.raises(InputError, match="shape"):
        ctrl.step(np.zeros(5), dt=1e-3)
    with pytest.raises(InputError, match="4x4"):
        ctrl.step(Q_REG, target=np.eye(3), dt=1e-3)
    with pytest.raises(InputError, match="twist"):
        ctrl.step(Q_REG, twist=np.zeros(3), dt=1e-3)
    with pytest.raises(InputError, match="gain"):
        rc.ResolvedRateController(ur5e, gain=-1.0)
    with pytest.raises(InputError, match="solver"):
        rc.ResolvedRateController(ur5e, solver=object())
    with pytest.raises(InputError, match="limits"):
        rc.ResolvedRateController(ur5e, limits="robot")


class _RowQP:
    """A QP that also keeps q̇_0 + q̇_1 ≤ h (an extra row, like a collision limit)."""

    def __init__(self, h):
        self.qp = rc.solvers.QP()
        self.h = h
        self.enforces_limits = True
        self.adds_rows = True  # (the solver contract: rows of its own shape the servo's path)

    def reset(self):
        self.qp.reset()

    def solve(self, J, xi, **kw):
        G = np.zeros((1, J.shape[1]))
        G[0, :2] = 1.0
        return self.qp.solve(J, xi, extra_inequalities=(G, [self.h]), **kw)


def test_a_limit_enforcing_solver_is_not_limited_again(ur5e):
    """With the QP the controller keeps the solver's q̇ (its bounds and extra rows hold)
    and reports the limits that bound, by kind, instead of clipping again."""
    upper = ur5e.upper.copy()
    upper[0] = Q_REG[0] + 0.02  # joint 1 meets its upper limit on the way
    lim = rc.solvers.Limits(lower=ur5e.lower, upper=upper, vmax=ur5e.vmax, amax=ur5e.amax)
    ctrl = rc.ResolvedRateController(ur5e, solver=_RowQP(0.05), limits=lim, gain=5.0)
    target = ur5e.fk(np.array([0.6, -1.0, 1.2, -1.8, 0.9, 0.3]))
    q, qd_prev, seen = Q_REG.copy(), np.zeros(6), set()
    dt = 1e-3
    for _ in range(1500):
        cmd = ctrl.step(q, target=target, dt=dt)
        assert np.array_equal(cmd.qd, cmd.solve.qd)  # not re-limited by the controller
        assert cmd.qd[0] + cmd.qd[1] <= 0.05 + 1e-7  # the extra row holds
        assert np.all(np.abs(cmd.qd) <= ur5e.vmax + 1e-9)
        assert np.all(np.abs(cmd.qd - qd_prev) <= ur5e.amax * dt + 1e-7)
        assert q[0] <= lim.upper[0] + 1e-9
        seen.update(cmd.flags)
        q, qd_prev = cmd.q_next, cmd.qd
    assert {"joint-limit", "acceleration-limited"} <= seen
    assert "extra constraint" in cmd.reason or "joint-limit" in cmd.flags


def test_a_joint_beyond_its_limit_returns_within_vmax_and_amax(ur5e):
    """Measured q beyond a position limit (a disturbance): the controller brings the joint
    back into its range without exceeding vmax or amax (it used to jump at (limit − q)/dt)."""
    ctrl = rc.ResolvedRateController(ur5e, solver=rc.solvers.DLS(damping=0.01))
    q = Q_REG.copy()
    q[2] = ur5e.upper[2] + 0.2  # 0.2 rad beyond the elbow's upper limit
    target = ur5e.fk(q)
    dt = 1e-3
    qd_prev = np.zeros(6)
    for _ in range(3000):
        cmd = ctrl.step(q, target=target, dt=dt)
        assert np.all(np.abs(cmd.qd) <= ur5e.vmax * (1 + 1e-9))
        assert np.all(np.abs(cmd.qd - qd_prev) <= ur5e.amax * dt * (1 + 1e-9))
        assert cmd.qd[2] <= 1e-12 or q[2] <= ur5e.upper[2]  # never further out
        q, qd_prev = cmd.q_next, cmd.qd
    assert q[2] <= ur5e.upper[2] + 1e-9


@pytest.mark.parametrize("name", ["puma560", "iiwa7", "panda"])
def test_smoothed_joints_stay_inside_their_position_ranges(name):
    """Random far targets with the Ruckig filter on: the filter lags the command, so the
    controller must start braking while the jerk-limited stop still fits. (Without that, a
    PUMA joint with jmax = 100 rad/s³ overran its limit by 1.6 rad.)"""
    arm = rc.robots.BUILTIN[name]()
    rng = np.random.default_rng(7)
    worst = 0.0
    for solver in (rc.solvers.AdaptiveDLS(), rc.solvers.DLS(damping=0.02), rc.solvers.QP()):
        for _ in range(3):
            ctrl = rc.ResolvedRateController(arm, solver=solver, gain=float(rng.uniform(5, 30)),
                                             smoothing=True)
            q = arm.random_q(rng=rng)
            target = arm.fk(arm.random_q(rng=rng))
            dt = float(rng.choice([1e-3, 4e-3]))
            qdd_prev = np.zeros(arm.dof)
            for _ in range(400):
                cmd = ctrl.step(q, target=target, dt=dt)
                worst = max(worst, float(np.max(cmd.q_next - arm.upper)),
                            float(np.max(arm.lower - cmd.q_next)))
                assert np.all(np.abs(cmd.qd) <= arm.vmax * (1 + 1e-9))
                assert np.all(np.abs(cmd.qdd) <= arm.amax * (1 + 1e-9))
                assert np.all(np.abs(cmd.qdd - qdd_prev) <= arm.jmax * dt * (1 + 1e-6))
                q, qdd_prev = cmd.q_next, cmd.qdd
    assert worst <= 1e-9


def test_command_is_immutable_and_cannot_change_the_controller(ur5e):
    import dataclasses
    import inspect

    ctrl = rc.ResolvedRateController(ur5e)
    target = _shifted(ur5e.fk(Q_REG), [0.01, 0.0, 0.0])
    cmd = ctrl.step(Q_REG, target=target, dt=1e-3)
    for name in ("qd", "q_next", "qdd", "error", "twist", "task_error"):
        a = getattr(cmd, name)
        with pytest.raises(ValueError):
            a[0] = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        cmd.qd = np.zeros(6)
    assert np.array_equal(ctrl.qd, cmd.qd) and ctrl.qd is not cmd.qd
    # the next cycle starts from the commanded q̇, whatever the caller does with the command
    qd_before = ctrl.qd.copy()
    ctrl.qd[0] = 99.0  # a copy
    forced = cmd.qd
    forced.setflags(write=True)  # even forced writable, the command shares nothing with the controller
    forced[:] = 99.0
    assert np.array_equal(ctrl.qd, qd_before)
    # keyword-only construction, no private fields in the signature; kind is lazy
    params = inspect.signature(Command).parameters
    assert not any(p.startswith("_") for p in params)
    assert all(p.kind is inspect.Parameter.KEYWORD_ONLY for p in params.values())
    fields = {f.name: getattr(cmd, f.name) for f in dataclasses.fields(Command)}
    with pytest.raises(TypeError):
        Command(*fields.values())
    hand = Command(**fields)
    assert hand.kind is None and cmd.kind == "regular"
    hand_qd = np.ones(6)
    hand = Command(**{**fields, "qd": hand_qd})
    hand_qd[0] = 5.0  # the command copied it
    assert hand.qd[0] == 1.0 and not hand.qd.flags.writeable
    # kind is computed at the cycle's q even when the caller updates q in place
    q = Q_WRIST.copy()
    q[4] = 1e-3
    ctrl.reset()
    cmd = ctrl.step(q, twist=np.zeros(6), dt=1e-3)
    q += 0.5
    assert cmd.kind == "wrist"


def test_the_stages_of_a_cycle_are_separate_objects(ur5e):
    """validate → halt check → error → solve → limit → smooth → command, each callable on
    its own (the gate and the limiter are objects the controller composes)."""
    ctrl = rc.ResolvedRateController(ur5e, solver=rc.solvers.Inverse())
    T = ur5e.fk(Q_REG)
    target = _shifted(T, [0.001, 0.0, 0.0])
    checked = ctrl._gate.validate(list(Q_REG), target, None, np.float32(1e-3), None, None)
    q, tgt, tw, dt, qd_ff, qdd_ff = checked
    assert q.dtype == float and dt == pytest.approx(1e-3)
    dt = 1e-3
    with pytest.raises(InputError):
        ctrl._gate.validate(Q_REG, np.eye(3), None, 1e-3, None, None)
    assert ctrl._halt_reason(q, tgt, tw, dt, qd_ff, qdd_ff, None) is None
    cyc = ctrl._error(q, tgt, tw)
    assert np.allclose(cyc.e, rc.spatial.pose_error(target, T)) and np.allclose(cyc.xi, ctrl.gain * cyc.e)
    assert ctrl._solve(cyc, q, dt, None) is None
    assert np.allclose(ur5e.jacobian(q) @ cyc.qd, cyc.xi)
    near = ctrl._limiter.limit(cyc, q, dt)
    assert np.all(np.abs(cyc.qd) <= ur5e.amax * dt * (1 + 1e-12))  # from rest: acceleration-limited
    assert ctrl._smooth(cyc, q, dt, None, near) is None
    cmd = ctrl._command(cyc, q, dt)
    assert np.allclose(cmd.q_next, q + cmd.qd * dt) and cmd.status == "acceleration-limited"


@pytest.mark.parametrize("bad", ["scaled", "mirrored", "sheared", "last-row", "nan"])
def test_a_target_that_is_not_a_rigid_pose_halts_with_the_reason(ur5e, bad):
    ctrl = rc.ResolvedRateController(ur5e)
    good = _shifted(ur5e.fk(Q_REG), [0.05, 0.0, 0.0])
    q = Q_REG.copy()
    for _ in range(50):  # moving toward a good target
        cmd = ctrl.step(q, target=good, dt=1e-3)
        q = cmd.q_next
    moving = np.abs(cmd.qd).max()
    assert moving > 0.0
    T = good.copy()
    if bad == "scaled":
        T[:3, :3] *= 2.0
    elif bad == "mirrored":
        T[:3, 0] *= -1.0
    elif bad == "sheared":
        T[0, 1] += 0.1
    elif bad == "last-row":
        T[3, 0] = 0.5
    else:
        T[1, 2] = np.nan
    cmd = ctrl.step(q, target=T, dt=1e-3)  # never raises in the loop
    assert cmd.status == "halted" and "target" in cmd.reason
    if bad in ("scaled", "mirrored", "sheared"):
        assert "rigid" in cmd.reason
    assert np.abs(cmd.qd).max() < moving  # decelerating
    assert np.all(np.abs(cmd.qd - ctrl.qd) == 0.0)
    with pytest.raises(InputError):  # a wrong shape is a programming error
        ctrl.step(q, target=T[:3], dt=1e-3)
    if bad != "nan":  # not latched: the next good target resumes
        cmd = ctrl.step(cmd.q_next, target=good, dt=1e-3)
        assert cmd.status != "halted"


def test_sigma_min_is_the_same_quantity_as_analyze_reports(ur5e):
    """Command.sigma_min, follow's per-step σ_min and rc.analyze(...).sigma_min are all σ_min
    of the unscaled J, and the texts say so; analyze's report names its scaled σ_min(J_L)."""
    q = Q_REG.copy()
    rep = rc.analyze(ur5e, q)
    for solver in (None, rc.solvers.DLS(damping=0.01), rc.solvers.QP()):
        cmd = rc.ResolvedRateController(ur5e, solver=solver).step(q, twist=np.zeros(6), dt=1e-3)
        assert cmd.sigma_min == pytest.approx(rep.sigma_min, rel=1e-9)
        assert "σ_min(J) =" in str(cmd)
    assert "σ_min(J_L)" in str(rep) and rep.sigma_min_scaled != pytest.approx(rep.sigma_min)
    T0 = ur5e.fk(q)
    run = rc.follow(ur5e, rc.paths.Line(T0, _shifted(T0, [0.01, 0.0, 0.0]), speed=0.1, acceleration=1.0), q,
                    dt=4e-3)
    k = int(np.nanargmin(run.sigma_min))
    assert run.sigma_min[k] == pytest.approx(rc.analyze(ur5e, run.q[k]).sigma_min, rel=1e-9)
    assert "min σ_min(J)" in run.summary() and "analyze" in run.summary()


def test_reset_refuses_a_velocity_that_is_not_a_finite_vector(ur5e):
    """reset(qd) is the controller's state: a NaN there used to reach the commands (a halt
    that commanded NaN); now it is refused where it is given."""
    ctrl = rc.ResolvedRateController(ur5e, solver=rc.solvers.QP())
    for bad in (np.full(6, np.nan), [0.0, 0.0, np.inf, 0.0, 0.0, 0.0], np.zeros(5), "fast"):
        with pytest.raises(InputError, match="qd"):
            ctrl.reset(bad)
    ctrl.reset([0.01] * 6)  # a list is fine, and copied
    assert np.array_equal(ctrl.qd, np.full(6, 0.01))
    cmd = ctrl.step(Q_REG, twist=np.zeros(6), dt=1e-3)
    assert np.all(np.isfinite(cmd.qd)) and np.all(np.isfinite(cmd.qdd))


class _RowQPSubclass(rc.solvers.QP):
    """A QP subclass whose solve adds a row q̇_0 ≤ h: the controller must call its solve."""

    def __init__(self, h):
        super().__init__()
        self.h = h

    def solve(self, J, xi, **kw):
        G = np.zeros((1, J.shape[1]))
        G[0, 0] = 1.0
        return super().solve(J, xi, extra_inequalities=(G, [self.h]), **kw)


class _ForwardingWrapper(_RowQPSubclass):
    """A wrapper that forwards unknown attributes to a plain QP (as MinkLimitedSolver does)."""

    def __init__(self, h):
        super().__init__(h)
        self.inner = rc.solvers.QP()

    def __getattr__(self, name):
        return getattr(self.__dict__["inner"], name)


@pytest.mark.parametrize("solver_type", [_RowQPSubclass, _ForwardingWrapper])
def test_only_the_plain_qp_takes_the_validated_entry(ur5e, solver_type):
    """The controller's shortcut past the input checks (QP.solve_validated) is for exactly
    the QP: a subclass or a wrapper that adds rows in its own solve keeps them."""
    fast = np.array([0.5, 0.0, 0.0, 0.0, 0.0, 0.0])  # joint 0 alone at 0.5 rad/s
    for solver, bound in ((rc.solvers.QP(), 0.5), (solver_type(0.05), 0.05)):
        ctrl = rc.ResolvedRateController(ur5e, solver=solver)
        q = Q_REG.copy()
        for _ in range(300):
            cmd = ctrl.step(q, twist=ur5e.jacobian(q) @ fast, dt=1e-3)
            assert cmd.qd[0] <= bound + 1e-7
            q = cmd.q_next
        assert cmd.qd[0] == pytest.approx(bound, rel=2e-2)  # the plain QP (damped), or the row
@pytest.mark.parametrize("options", [
    {"gain": [1.0] * 5}, {"gain": "fast"}, {"position_tolerance": -1.0}, {"orientation_tolerance": 0.0},
    {"timeout": 0.0}, {"timeout": float("nan")}, {"timeout": "0.1"}, {"singular_sigma": -0.1},
])
def test_bad_options_are_refused_by_name(ur5e, options):
    (name, value), = options.items()
    with pytest.raises(InputError) as info:
        rc.ResolvedRateController(ur5e, **options)
    assert info.value.argument == name and name in str(info.value)


def test_a_solver_class_instead_of_an_instance_says_so(ur5e):
    with pytest.raises(InputError, match=r"pass QP\(\)") as info:
        rc.ResolvedRateController(ur5e, solver=rc.solvers.QP)
    assert info.value.argument == "solver"


def test_a_timeout_of_inf_means_targets_never_go_stale(ur5e):
    ctrl = rc.ResolvedRateController(ur5e, timeout=float("inf"))
    cmd = ctrl.step(Q_REG, target=ur5e.fk(Q_REG), dt=1e-3, stamp=-1e9)
    assert cmd.status != "halted"


@pytest.mark.parametrize("smoothing", [False, True])
def test_joint_acceleration_feed_forward_is_checked_like_the_other_inputs(ur5e, smoothing):
    ctrl = rc.ResolvedRateController(ur5e, smoothing=smoothing)
    with pytest.raises(InputError, match=r"qdd_ff must have shape \(6,\)"):
        ctrl.step(Q_REG, twist=np.zeros(6), dt=1e-3, qdd_ff=np.zeros(5))
    with pytest.raises(InputError, match="dt must be a number"):
        ctrl.step(Q_REG, twist=np.zeros(6), dt="1e-3")  # type: ignore[arg-type]
    for bad in (np.inf, np.nan):
        ctrl.reset()
        qdd = np.zeros(6)
        qdd[2] = bad
        cmd = ctrl.step(Q_REG, twist=np.zeros(6), dt=1e-3, qdd_ff=qdd)
        assert cmd.status == "halted" and "non-finite qdd_ff" in cmd.reason


@settings(max_examples=200, deadline=None)
@given(st.lists(st.sampled_from([0.0, -0.0, 1.0, -1.0, 1e-300, math.nan, math.inf]), min_size=6, max_size=6),
       st.lists(st.sampled_from([0.0, -0.0, 1.0, -1.0, 1e-300, math.nan, math.inf]), min_size=6, max_size=6))
def test_the_cycle_s_equality_of_targets_is_numpys(a, b):
    """The stages compare a target or twist with the last one through lists (`_same`): the
    answer is np.array_equal's (−0.0 equals 0.0, NaN equals nothing, shapes must agree)."""
    from ratectl.control.cycle import _same
    x, y = np.array(a), np.array(b)
    assert _same(x, y) == np.array_equal(x, y)
    assert not _same(x, y.reshape(2, 3)) and not _same(x, None)


@pytest.mark.parametrize("given", ["target", "twist", "qd_ff"])
def test_a_controller_with_tasks_refuses_a_target_twist_or_feed_forward(ur5e, given):
    """``step(q, target=T)`` on a controller with tasks bypassed every task (a posture,
    collision rows) without a word; it now says what it takes instead."""
    tool = rc.tasks.Pose(priority=0, target=ur5e.fk(Q_REG))
    ctrl = rc.ResolvedRateController(ur5e, tasks=[tool, rc.tasks.Posture(Q_REG, priority=1)])
    value = {"target": ur5e.fk(Q_REG), "twist": np.zeros(6), "qd_ff": np.zeros(6)}[given]
    with pytest.raises(rc.errors.InputError, match="set_target") as err:
        ctrl.step(Q_REG, dt=1e-3, **{given: value})
    assert err.value.argument == given
    assert ctrl.step(Q_REG, dt=1e-3).status in ("regular", "target-reached")
