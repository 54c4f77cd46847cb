"""Fuzz: the controller's closed loop next to position limits under faults.

* **dt changes**: random period sequences (0.1–10 ms, changing every 1–5 cycles) with a
  joint feed-forward driving joints into their limits, for every solver family (adaptive
  DLS, DLS, QP) with and without smoothing: |q̈| ≤ amax for the commanded stream (finite
  difference with the actual dt of each period), |q̇| ≤ vmax, q inside its range, and
  never a ``limit-recovery`` (a fault-free run never needs one).
* **measurement jumps**: the measured q of a joint jumps toward its nearest limit
  (sometimes beyond it) relative to the last command's integral: the command never
  moves a joint further out than it is measured, the jump cycle says ``limit-recovery``
  whenever the position side had to win (braking harder than amax, or a joint measured
  beyond its range), and every other cycle keeps |q̈| ≤ amax.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

import ratectl as rc

ARMS = ("ur5e", "panda", "puma560", "iiwa7", "stanford")
SOLVERS = {
    "adaptive-dls": rc.solvers.AdaptiveDLS,
    "dls": lambda: rc.solvers.DLS(damping=0.02),
    "qp": rc.solvers.QP,
}
TOL = 1e-6


def _start(arm, r):
    """Every joint within 0.01–0.1 of one of its limits, the feed-forward pointing into it."""
    side = r.choice([-1.0, 1.0], arm.dof)
    room = r.uniform(0.01, 0.1, arm.dof)
    q = np.where(side > 0, arm.upper - room, arm.lower + room)
    ff = side * r.uniform(0.2, 1.0, arm.dof) * arm.vmax
    return q, ff


def _controller(arm, solver, smoothing):
    return rc.ResolvedRateController(arm, solver=SOLVERS[solver](), smoothing=smoothing)


case = st.tuples(st.sampled_from(ARMS), st.sampled_from(sorted(SOLVERS)), st.booleans(),
                 st.integers(0, 2**32 - 1))


def test_changing_dt_next_to_position_limits_holds_every_limit(fuzz, capfd):
    @fuzz.settings(10)
    @given(c=case)
    def prop(c):
        name, solver, smoothing, seed = c
        arm = rc.robots.BUILTIN[name]()
        r = np.random.default_rng(seed)
        ctrl = _controller(arm, solver, smoothing)
        q, ff = _start(arm, r)
        qd_prev = np.zeros(arm.dof)
        dt, hold = 1e-3, 0
        steps = 250
        fuzz.count("controller_step", steps)
        for k in range(steps):
            if hold == 0:
                dt, hold = float(10.0 ** r.uniform(-4, -2)), int(r.integers(1, 6))
            hold -= 1
            cmd = ctrl.step(q, qd_ff=ff, dt=dt)
            qd = np.asarray(cmd.qd)
            acc = np.abs(qd - qd_prev) / (arm.amax * dt)
            assert acc.max() <= 1.0 + TOL, (k, dt, acc.max(), cmd.status, cmd.reason)
            assert np.all(np.abs(qd) <= arm.vmax * (1.0 + TOL))
            q = np.asarray(cmd.q_next)
            span = arm.upper - arm.lower
            inside = np.all(q <= arm.upper + TOL * span) and np.all(q >= arm.lower - TOL * span)
            assert inside, (k, cmd.reason)
            assert "limit-recovery" not in cmd.flags, cmd.reason
            qd_prev = qd

    prop()
    assert capfd.readouterr().out == ""  # nothing the step calls writes to stdout


def test_measurement_jumps_never_command_motion_further_out(fuzz, capfd):
    @fuzz.settings(10)
    @given(c=case)
    def prop(c):
        name, solver, smoothing, seed = c
        arm = rc.robots.BUILTIN[name]()
        r = np.random.default_rng(seed)
        ctrl = _controller(arm, solver, smoothing)
        q, ff = _start(arm, r)
        dt = float(r.choice([1e-3, 4e-3]))
        qd_prev = np.zeros(arm.dof)
        steps = 250
        fuzz.count("controller_step", steps)
        jumps = 0
        for k in range(steps):
            meas = q.copy()
            jumped = r.random() < 0.05
            if jumped:
                j = int(r.integers(arm.dof))
                to_hi = (arm.upper[j] - q[j]) < (q[j] - arm.lower[j])
                meas[j] += (1.0 if to_hi else -1.0) * float(r.uniform(1e-3, 2e-2))
                jumps += 1
            cmd = ctrl.step(meas, qd_ff=ff, dt=dt)
            qd, qn = np.asarray(cmd.qd), np.asarray(cmd.q_next)
            # never further out than measured (at the limit, or at the measurement beyond it)
            tol = 1e-9 * (1.0 + np.abs(meas))
            assert np.all(qn <= np.maximum(arm.upper, meas) + tol), (k, cmd.reason)
            assert np.all(qn >= np.minimum(arm.lower, meas) - tol), (k, cmd.reason)
            assert np.all(np.abs(qd) <= arm.vmax * (1.0 + TOL))
            acc = np.abs(qd - qd_prev) / (arm.amax * dt)
            out = (meas > arm.upper) | (meas < arm.lower)
            if acc.max() > 1.0 + TOL or out.any():
                # the position side won over amax (only on a jump cycle), or a joint is measured
                # beyond its range: the status says so
                assert jumped or out.any(), (k, acc.max(), cmd.status, cmd.reason)
                assert "limit-recovery" in cmd.flags, (k, acc.max(), cmd.flags, cmd.reason)
            qd_prev, q = qd, qn
        fuzz.count("fault_measurement_jump", jumps)

    prop()
    assert capfd.readouterr().out == ""


def test_a_jump_inside_the_stopping_distance_brakes_at_once_and_says_so():
    """A joint at 1 rad/s toward its upper limit is measured 5 mm from it (it needs
    v²/(2·amax) = 5 cm at amax = 10): the command stops it at the limit within the
    period — braking harder than amax, status ``limit-recovery`` with the ratio — and the
    next periods keep within amax and inside the range again."""
    arm = rc.robots.ur5e()
    for smoothing in (False, True):
        for solver in sorted(SOLVERS):
            ctrl = _controller(arm, solver, smoothing)
            q = np.array([0.0, -1.2, 1.4, -1.8, 0.9, 0.3])
            ff = np.zeros(6)
            ff[0] = 1.0
            dt = 1e-3
            for _ in range(400):  # reach 1 rad/s, far from the limit
                q = np.array(ctrl.step(q, qd_ff=ff, dt=dt).q_next)
            q[0] = arm.upper[0] - 0.005  # the measurement jumps
            cmd = ctrl.step(q, qd_ff=ff, dt=dt)
            assert cmd.status == "limit-recovery", (solver, smoothing, cmd.status, cmd.reason)
            assert "× amax" in cmd.reason and "stopping distance" in cmd.reason
            assert cmd.q_next[0] <= arm.upper[0] + 1e-12
            prev = np.asarray(cmd.qd)
            q = np.asarray(cmd.q_next)
            for _ in range(300):
                cmd = ctrl.step(q, qd_ff=ff, dt=dt)
                assert np.max(np.abs(cmd.qd - prev) / (arm.amax * dt)) <= 1.0 + TOL, (solver, smoothing)
                assert cmd.q_next[0] <= arm.upper[0] + 1e-12
                assert "limit-recovery" not in cmd.flags
                prev, q = np.asarray(cmd.qd), np.asarray(cmd.q_next)


def test_a_joint_measured_beyond_its_limit_while_moving_out_is_never_commanded_further():
    """Measured 1 cm beyond the upper limit while still moving out at 1 rad/s: the command
    toward the limit is ≤ 0 at once (harder than amax), status ``limit-recovery`` naming the
    joint, and the joint then returns into its range within vmax and amax."""
    arm = rc.robots.ur5e()
    for smoothing in (False, True):
        for solver in sorted(SOLVERS):
            ctrl = _controller(arm, solver, smoothing)
            q = np.array([0.0, -1.2, 1.4, -1.8, 0.9, 0.3])
            ff = np.zeros(6)
            ff[0] = 1.0
            dt = 1e-3
            for _ in range(400):
                q = np.array(ctrl.step(q, qd_ff=ff, dt=dt).q_next)
            q[0] = arm.upper[0] + 0.01
            cmd = ctrl.step(q, qd_ff=ff, dt=dt)
            assert cmd.status == "limit-recovery" and "beyond a position limit" in cmd.reason
            assert cmd.qd[0] <= 0.0 and cmd.q_next[0] <= q[0]
            prev, q = np.asarray(cmd.qd), np.asarray(cmd.q_next)
            for _ in range(1500):
                cmd = ctrl.step(q, qd_ff=ff, dt=dt)
                assert np.max(np.abs(cmd.qd - prev) / (arm.amax * dt)) <= 1.0 + TOL, (solver, smoothing)
                assert cmd.q_next[0] <= q[0] + 1e-12 or q[0] <= arm.upper[0]
                prev, q = np.asarray(cmd.qd), np.asarray(cmd.q_next)
            assert q[0] <= arm.upper[0] + 1e-9, (solver, smoothing, q[0] - arm.upper[0])
