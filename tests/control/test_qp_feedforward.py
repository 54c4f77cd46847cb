"""A QP controller with a joint feed-forward keeps the *total* command within the limits."""

import numpy as np

import ratectl as rc


def test_feedforward_into_a_position_limit_is_braked_within_amax():
    arm = rc.robots.ur5e()
    ctrl = rc.ResolvedRateController(arm, solver=rc.solvers.QP())
    dt = 2e-3
    q = np.array([0.3, -1.3, 1.6, -1.9, -1.2, 0.2])
    q[0] = arm.upper[0] - 0.02  # joint 1 is 2 cm from its upper limit
    qd_ff = np.zeros(6)
    qd_ff[0] = arm.vmax[0]  # and the feed-forward drives it there at full speed
    prev = np.zeros(6)
    worst_acc = 0.0
    for _ in range(400):
        T = arm.fk(q)
        cmd = ctrl.step(q, target=T, qd_ff=qd_ff, dt=dt)
        assert cmd.status != "halted", cmd.reason
        worst_acc = max(worst_acc, float(np.max(np.abs(cmd.qd - prev) / arm.amax)) / dt)
        prev = np.array(cmd.qd)
        q = np.array(cmd.q_next)
        assert np.all(q <= arm.upper + 1e-9) and np.all(q >= arm.lower - 1e-9)
        assert np.all(np.abs(cmd.qd) <= arm.vmax * (1 + 1e-9))
    assert worst_acc <= 1.0 + 1e-6  # was 148× amax with the correction-only box
    assert q[0] > arm.upper[0] - 0.02  # it did move toward the limit, and stopped at it
