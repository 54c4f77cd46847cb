"""rc.run on an arm that lags its velocity command: a teleop twist stream into a joint limit.

The scripted arm's joints follow their velocity command through a first-order servo
(``ScriptedDriver(lag=τ)``): after the command reaches zero a joint still travels what it
lags behind. The jog measures a joint's room to its limit from where the commands sent it,
so the arm comes to rest inside the limit on its own, without ``limit-recovery`` pulling it
back, whatever τ is. The scripted arm's clock is stepped by the loop (``period=``), so the
runs are deterministic however loaded the machine is; each lasts 0.75 s of wall-clock time.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

import ratectl as rc
from ratectl.drivers import ScriptedDriver

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "drivers"))
from pan_teleop import base_turn, pan_limited  # noqa: E402

LIMIT = 0.6  # the shoulder pan's upper limit [rad]
LAG = 0.05  # the servo's time constant [s]: 25 periods at 500 Hz
MARGIN = 1e-3  # a jog stops this far inside a limit [rad]


@pytest.fixture(scope="module", params=[False, True], ids=["no-smoothing", "smoothing"])
def jog(request):
    """A UR5e turned about its base at 0.12 m/s into a 0.6 rad pan limit, on an arm lagging 50 ms."""
    arm = pan_limited(rc.robots.ur5e(), LIMIT)
    q0 = np.array([0.5, -1.3, 1.6, -1.8, -1.5, 0.2])
    twist = base_turn(arm, q0, speed=0.12, until=1.5)

    drv = ScriptedDriver(arm, q0, lag=LAG, period=0.002)
    ctrl = rc.ResolvedRateController(arm, smoothing=request.param)
    ex = rc.run(drv, twist=twist, controller=ctrl, rate_hz=1000.0)  # twice real time
    return request.param, arm, drv, ex


def test_the_lagging_arm_lags(jog):
    # at full speed the pan is measured well behind the displacement it was commanded (a 50 ms
    # lag at ~0.2 rad/s: ~10 mrad), which it still travels after its command stops
    _, _, _, ex = jog
    commanded = np.concatenate([[0.0], np.cumsum(ex.qd[:-1, 0] * np.diff(ex.t))])
    behind = commanded - (ex.q_measured[:, 0] - ex.q_measured[0, 0])
    k_fast = int(np.argmax(ex.qd[:, 0]))
    assert ex.qd[k_fast, 0] > 0.1 and behind[k_fast] > 5e-3


def test_the_lagging_joint_comes_to_rest_inside_its_limit(jog):
    smoothing, arm, drv, ex = jog
    assert ex.completed and "stream ended" in ex.message, ex.summary()
    assert ex.q_measured[:, 0].max() <= LIMIT and drv.q[0] <= LIMIT
    # and it got there: at the jog's margin (smoothed, one period at vmax sooner at most)
    slack = arm.vmax[0] * np.max(np.diff(ex.t)) if smoothing else 0.0  # (the robot's periods)
    assert ex.q_measured[-1, 0] > LIMIT - MARGIN - slack - 5e-4
    assert abs(ex.qd_measured[-1, 0]) < 1e-3  # at rest


def test_a_fault_free_lagging_loop_never_enters_limit_recovery(jog):
    _, _, _, ex = jog
    assert "limit-recovery" not in ex.statuses
    assert "joint-limit" in ex.statuses


def test_the_commanded_acceleration_stays_within_amax(jog):
    _, arm, _, ex = jog
    acc = np.abs(np.diff(ex.qd, axis=0)) / np.diff(ex.t)[:, None]
    assert np.all(acc <= arm.amax * (1 + 1e-9)), float(np.max(acc / arm.amax))


# ---------------------------------------------------------------------- in your own loop
def _pan_limited_ur5e():
    base = rc.robots.ur5e()
    qlim = np.column_stack([base.lower, base.upper])
    qlim[0] = (-LIMIT, LIMIT)
    return base.with_limits(qlim=qlim, amax=4.0, jmax=40.0)


def _turn(arm, q):
    """The 0.12 m/s twist turning the tool about the base at q (toward +pan)."""
    p = arm.fk(q)[:3, 3]
    r, phi = math.hypot(p[0], p[1]), math.atan2(p[1], p[0])
    return np.array([-0.12 * math.sin(phi), 0.12 * math.cos(phi), 0.0, 0.0, 0.0, 0.12 / r])


@pytest.mark.parametrize("tau", [0.0, 0.01, 0.05, 0.2])
def test_a_lagging_joint_rests_at_the_margin_whatever_its_lag(tau):
    """A user's loop on a first-order servo of any time constant (the scripted arm on a
    stepped clock, 2 ms periods): the pan comes to rest at the jog's margin, never past it,
    with no limit-recovery and the command's change within amax."""
    arm = _pan_limited_ur5e()
    q0 = np.array([0.5, -1.3, 1.6, -1.8, -1.5, 0.2])
    dt = 0.002
    drv = ScriptedDriver(arm, q0, lag=tau, period=dt)
    ctrl = rc.ResolvedRateController(arm)
    peak, statuses, qd_prev = -math.inf, set(), np.zeros(6)
    for _ in range(int((1.2 + 10.0 * tau) / dt)):  # at the limit by 0.8 s, then ten lags to settle
        s = drv.read()
        cmd = ctrl.step(s.q, twist=_turn(arm, s.q), dt=dt)
        assert np.all(np.abs(cmd.qd - qd_prev) <= arm.amax * dt * (1 + 1e-9))
        qd_prev = cmd.qd
        drv.command(cmd.qd)
        statuses.add(cmd.status)
        peak = max(peak, float(s.q[0]))
    assert "joint-limit" in statuses and "limit-recovery" not in statuses
    assert LIMIT - MARGIN - 1e-5 <= peak <= LIMIT - MARGIN + 1e-5, (peak - LIMIT) * 1e3


def test_a_joint_at_rest_that_never_caught_up_owes_nothing():
    """A joint that does not move (held by friction) while its commands run ahead: the jog
    stops as if the joint were where it was sent; once the command is at rest and the joint
    measured not moving, the gap is forgotten and the jog goes on from where the joint is."""
    arm = _pan_limited_ur5e()
    q = np.array([0.58, -1.3, 1.6, -1.8, -1.5, 0.2])  # 20 mrad from the limit, stuck
    ctrl = rc.ResolvedRateController(arm)
    xi = _turn(arm, q)
    pan = []
    for _ in range(400):
        pan.append(float(ctrl.step(q, twist=xi, dt=0.002).qd[0]))
    pan = np.array(pan)
    stopped = np.flatnonzero(np.abs(pan) * 0.002 <= 1e-9)  # held at rest (up to rounding)
    assert stopped.size and pan[: stopped[0]].max() > 0.1  # moved, then stopped for the lead
    assert pan[stopped[0]:].max() > 0.1  # and went on once the gap was forgotten
