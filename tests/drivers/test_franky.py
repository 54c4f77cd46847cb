"""FrankyDriver against franky-sim: a simulated FR3 behind the libfranka protocol, on loopback.

The server runs in a process of its own (ratectl.drivers.FrankySim), as a real robot runs on
its own computer. All tests share one xdist worker ("franky" group); the healthy-robot tests
share one server, the fault tests (a server that dies, a server that freezes) get their own.
Every run is bounded by its path, duration or watchdog.
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pytest

import ratectl as rc

pytest.importorskip("franky", reason="franky is not installed (pip install 'ratectl[franka]')")
pytest.importorskip("franky_sim", reason="franky-sim is not installed (pip install 'ratectl[franka]')")

from ratectl.drivers import FrankyDriver, FrankySim, RobotState  # noqa: E402

pytestmark = pytest.mark.xdist_group("franky")

RATE = 500.0
TOL = (1e-4, math.radians(0.2))  # end pose: 0.1 mm, 0.2°
# the watchdog of the healthy-robot runs: generous, because on a loaded machine the simulator (a
# Python loop at 1 kHz in its own process) can stall for ~0.1 s; the fault tests use 50 ms
HEALTHY_TIMEOUT = 0.5


@pytest.fixture(scope="module")
def sim():
    with FrankySim(nice=-5) as s:
        yield s


@pytest.fixture(scope="module")
def fr3(sim):
    return FrankyDriver(sim.hostname)


def test_model_and_limits_come_from_the_robot(fr3):
    chain = fr3.chain
    assert chain.dof == 7 and chain.name == "fr3"
    # the limits franky enforces, not the URDF's 2.62 rad/s
    assert np.allclose(chain.vmax, [2.175] * 4 + [2.61] * 3)
    assert np.all(np.isfinite(chain.amax)) and np.all(np.isfinite(chain.jmax))
    # the chain from the robot's URDF agrees with the robot's own flange pose
    s = fr3.robot.state
    O_T_F = s.O_T_EE.matrix @ np.linalg.inv(s.F_T_EE.matrix)
    T = chain.fk(fr3.read().q)
    assert np.allclose(T[:3, 3], O_T_F[:3, 3], atol=1e-4) and np.allclose(T[:3, :3], O_T_F[:3, :3], atol=1e-4)
    st = fr3.read()
    assert isinstance(st, RobotState) and st.q.shape == (7,) and not st.q.flags.writeable


def test_follows_a_15cm_line_at_01_m_per_s(fr3):
    chain = fr3.chain
    T0 = chain.fk(fr3.read().q)
    T1 = T0.copy()
    T1[:3, 3] += [0.0, 0.15, 0.0]
    line = rc.paths.Line(T0, T1, speed=0.1, acceleration=0.5)
    ex = rc.run(fr3, path=line, rate_hz=RATE, tolerance=TOL, timeout=HEALTHY_TIMEOUT)
    assert ex.completed, ex.summary()
    # the robot's *measured* joint positions, through the chain, stay on the line
    assert ex.max_position_error <= 0.5e-3, ex.summary()
    assert math.degrees(ex.max_orientation_error) <= 0.2, ex.summary()
    assert ex.info["end_position_error"] <= 1e-4, ex.summary()
    assert ex.achieved_rate_hz >= 0.9 * RATE, ex.summary()
    assert np.all(np.abs(ex.qd_measured) <= chain.vmax), ex.summary()
    assert ex.duration >= line.duration


def test_servo_to_a_target_and_a_twist_stream(fr3):
    chain = fr3.chain
    q_start = fr3.read().q
    T = chain.fk(q_start)
    T[:3, 3] += [0.03, 0.0, -0.03]
    ex = rc.run(fr3, target=T, rate_hz=RATE, tolerance=TOL, duration=5.0, timeout=HEALTHY_TIMEOUT)
    assert ex.completed, ex.summary()
    assert ex.info["end_position_error"] <= 1e-4

    p0 = chain.fk(fr3.read().q)[:3, 3]
    v = np.array([0.0, 0.0, 0.05, 0.0, 0.0, 0.0])
    ex2 = rc.run(fr3, twist=lambda t: v if t < 0.4 else None, rate_hz=RATE, timeout=HEALTHY_TIMEOUT)
    assert ex2.completed, ex2.summary()
    moved = chain.fk(fr3.read().q)[:3, 3] - p0
    assert 0.012 < moved[2] < 0.024 and np.linalg.norm(moved[:2]) < 1e-3, moved
    assert np.all(np.abs(ex2.qd_measured) <= chain.vmax)


class _NaNAfter:
    """A driver wrapper whose measurements turn NaN after ``t`` seconds of robot time."""

    def __init__(self, driver, t):
        self.driver, self.t, self.t0 = driver, t, None
        self.chain = driver.chain

    def read(self):
        s = self.driver.read()
        self.t0 = s.stamp if self.t0 is None else self.t0
        if s.stamp - self.t0 < self.t:
            return s
        return RobotState(stamp=s.stamp, q=np.full(7, np.nan), qd=s.qd)

    def command(self, qd):
        self.driver.command(qd)

    def stop(self):
        self.driver.stop()


def test_nan_in_the_measured_state_halts_safely(fr3):
    drv = _NaNAfter(fr3, 0.2)
    ex = rc.run(drv, twist=np.array([0.0, -0.05, 0.0, 0.0, 0.0, 0.0]), rate_hz=RATE, duration=3.0,
                timeout=HEALTHY_TIMEOUT)
    assert not ex.completed and "non-finite measured state" in ex.message
    assert ex.statuses[-1] == "halted" and ex.t[-1] < 1.0
    assert np.max(np.abs(ex.qd[-1])) <= 1e-3  # the command came to rest before the stop
    assert not fr3.robot.is_in_control
    # at rest: the position no longer changes (franky-sim's idle wrist chatters, so its measured
    # q̇ is noisy at ±0.1 rad/s while the joint stays put)
    q1 = fr3.read().q
    threading.Event().wait(0.1)
    assert np.max(np.abs(fr3.read().q - q1)) < 3e-3


class _FaultAt:
    """A driver wrapper that injects a fault into the server after ``n`` commands."""

    def __init__(self, driver, n, action):
        self.driver, self.n, self.action = driver, n, action
        self.chain = driver.chain
        self.count = 0
        self.fired_at = None

    def read(self):
        self.last_read_at = time.perf_counter()  # the last one is the cycle that halted
        return self.driver.read()

    def command(self, qd):
        self.driver.command(qd)
        self.count += 1
        if self.count == self.n:
            self.fired_at = time.perf_counter()
            self.action()

    def stop(self):
        self.driver.stop()


@pytest.mark.parametrize("fault", ["server stops", "server freezes"])
def test_a_lost_robot_halts_within_timeout_plus_one_period(fault):
    # 0.25 s: long enough that franky-sim's own stalls on a loaded machine (up to ~0.15 s seen)
    # do not trip it before the fault
    timeout = 0.25
    with FrankySim(nice=-5) as sim:
        drv = _FaultAt(FrankyDriver(sim.hostname, stop_timeout=0.2), 150,
                       sim.kill if fault == "server stops" else sim.pause)
        try:
            ex = rc.run(drv, twist=np.array([0.0, 0.03, 0.0, 0.0, 0.0, 0.0]), rate_hz=RATE, timeout=timeout,
                        duration=10.0)
        finally:
            if fault == "server freezes":
                sim.resume()
    assert drv.fired_at is not None, ex.summary()
    assert not ex.completed and ex.info["outcome"] == "halted", ex.summary()
    assert "watchdog" in ex.message, ex.message
    # the decision came at the first cycle after the timeout: within timeout + that cycle's period
    delay = ex.info["halt_delay"]
    assert timeout < delay <= timeout + ex.periods[-1] + 1e-4
    assert delay <= timeout + 1.0 / RATE + 0.05  # one period, plus what a busy OS may add
    # ... and it came after the fault (counted from the last fresh state, which on a loaded
    # machine may predate the fault by a stall of the simulator)
    assert len(ex.t) > 150
    assert drv.last_read_at > drv.fired_at


def test_a_line_with_a_drop_and_a_turn_about_the_tool_axis_converges(fr3):
    # 15 cm along y, 5 cm down, 20° about the tool axis: joint 7 carries the turn and franky-sim's
    # joint friction holds it near the end; the integral action on the end pose closes the gap
    chain = fr3.chain
    T0 = chain.fk(fr3.read().q)
    T1 = T0.copy()
    T1[:3, 3] += [0.0, 0.15, -0.05]
    c, s = math.cos(math.radians(20.0)), math.sin(math.radians(20.0))
    T1[:3, :3] = T0[:3, :3] @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    line = rc.paths.Line(T0, T1, speed=0.1, acceleration=0.5)
    ex = rc.run(fr3, path=line, rate_hz=RATE, timeout=HEALTHY_TIMEOUT)
    assert ex.completed, ex.summary()
    # the measured joint positions, through the chain, within 0.5 mm of the line
    assert ex.max_position_error <= 0.5e-3, ex.summary()
    assert ex.info["end_position_error"] <= 1e-4 and ex.info["end_orientation_error"] <= 1e-3, ex.summary()
    assert np.all(np.abs(ex.qd) <= chain.vmax * (1 + 1e-9))
