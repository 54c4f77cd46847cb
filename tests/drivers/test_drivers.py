"""The driver protocol and the drivers that need no network: RobotState, ScriptedDriver,
MujocoDriver, the FR3 chain from its URDF text, and the lazy imports."""

from __future__ import annotations

import importlib.util
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import ratectl as rc
from ratectl.drivers import Driver, RobotState, ScriptedDriver, franky_chain
from ratectl.errors import DriverError, InputError

Q0 = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])


def test_robot_state_is_frozen_with_read_only_copies():
    q = np.arange(3.0)
    s = RobotState(stamp=1, q=q, qd=[0.0, 0.0, 0.0])
    q[0] = 99.0
    assert s.q[0] == 0.0 and s.stamp == 1.0 and isinstance(s.stamp, float)
    with pytest.raises(ValueError):
        s.q[1] = 5.0
    with pytest.raises(AttributeError):
        s.stamp = 2.0
    with pytest.raises(TypeError):
        RobotState(0.0, q, q)  # keyword-only
    assert s.finite and not RobotState(stamp=0.0, q=[np.nan], qd=[0.0]).finite
    assert not RobotState(stamp=math.inf, q=[0.0], qd=[0.0]).finite


def test_scripted_arm_integrates_the_commanded_velocity():
    arm = rc.robots.panda()
    drv = ScriptedDriver(arm, Q0)
    assert isinstance(drv, Driver) and drv.chain is arm
    s0 = drv.read()
    qd = np.array([0.2, -0.1, 0.0, 0.05, 0.0, 0.0, 0.3])
    drv.command(qd)
    time.sleep(0.05)
    s1 = drv.read()
    elapsed = s1.stamp - s0.stamp
    assert elapsed >= 0.05
    assert np.allclose(s1.q, Q0 + qd * elapsed, atol=1e-3)  # within the time of the calls
    assert np.array_equal(s1.qd, qd)
    drv.stop()
    q_stop = drv.read().q
    time.sleep(0.01)
    assert np.allclose(drv.read().q, q_stop) and drv.stops == 1
    # refused like a real robot: too fast, not finite, wrong shape
    with pytest.raises(DriverError, match="exceeds vmax"):
        drv.command(arm.vmax * 1.01)
    with pytest.raises(DriverError, match="non-finite"):
        drv.command(np.full(7, np.nan))
    with pytest.raises(InputError):
        drv.command(np.zeros(6))
    with pytest.raises(InputError):
        ScriptedDriver(arm, Q0[:3])


def test_scripted_lag_is_a_first_order_velocity_servo():
    """lag=τ: v follows the command as v̇ = (q̇ − v)/τ; after a zero command the arm still covers
    the commanded displacement (a unit-gain servo), later."""
    arm = rc.robots.panda()
    tau = 0.05
    drv = ScriptedDriver(arm, Q0, lag=tau, period=0.1)  # each read 0.1 s later
    qd = np.array([0.2, -0.1, 0.0, 0.05, 0.0, 0.0, 0.3])
    drv.read()
    drv.command(qd)
    s = drv.read()
    decay = math.exp(-0.1 / tau)
    assert np.allclose(s.qd, qd * (1.0 - decay), rtol=1e-12)
    assert np.allclose(s.q, Q0 + qd * (0.1 - tau * (1.0 - decay)), rtol=1e-12)
    drv.command(np.zeros(7))
    for _ in range(40):  # 4 s = 80 τ later: at rest, the whole commanded displacement covered
        s = drv.read()
    assert np.allclose(s.q, Q0 + qd * 0.1, atol=1e-12) and np.max(np.abs(s.qd)) < 1e-12
    with pytest.raises(InputError, match="lag"):
        ScriptedDriver(arm, Q0, lag=-0.01)


def test_scripted_stepped_clock_moves_only_when_read():
    """period=h: each read() after the first advances the arm's clock by h, whatever the wall clock."""
    arm = rc.robots.panda()
    drv = ScriptedDriver(arm, Q0, period=0.002)
    assert drv.read().stamp == 0.0
    qd = np.array([0.2, -0.1, 0.0, 0.05, 0.0, 0.0, 0.3])
    drv.command(qd)
    time.sleep(0.01)  # wall-clock time does not move the arm
    assert np.array_equal(drv.q, Q0)
    s = drv.read()
    assert s.stamp == 0.002 and np.allclose(s.q, Q0 + qd * 0.002, rtol=0, atol=1e-15)
    with pytest.raises(InputError, match="period"):
        ScriptedDriver(arm, Q0, period=0.0)


def test_scripted_faults():
    arm = rc.robots.panda()
    d = ScriptedDriver(arm, Q0, drop=1.0)
    a, b = d.read(), d.read()
    assert b is a  # every later sample dropped: the same sample, same stamp
    d = ScriptedDriver(arm, Q0, stale_after=0.02)
    d.read()
    time.sleep(0.03)
    a, b = d.read(), d.read()
    assert a.stamp == b.stamp <= 0.03
    d = ScriptedDriver(arm, Q0, nan_after=0.0)
    assert not d.read().finite
    d = ScriptedDriver(arm, Q0, fail_after=0.0)
    with pytest.raises(ConnectionResetError):
        d.read()
    d = ScriptedDriver(arm, Q0, read_delay=0.01)
    t0 = time.perf_counter()
    d.read()
    assert time.perf_counter() - t0 >= 0.01


def test_fr3_chain_from_its_urdf_text_with_the_robots_limits():
    spec = importlib.util.find_spec("franky_sim")
    if spec is None or spec.origin is None:
        pytest.skip("franky-sim is not installed (pip install 'ratectl[franka]')")
    urdf = (Path(spec.origin).parent / "assets" / "fr3_clean.urdf").read_text()
    plain = rc.Chain.from_urdf(urdf, tip="link8")
    assert plain.dof == 7 and np.allclose(plain.vmax[:4], 2.62)  # what the URDF says
    vmax = [2.175] * 4 + [2.61] * 3
    tool = np.eye(4)
    tool[2, 3] = 0.1034
    chain = franky_chain(urdf, tool=tool, vmax=vmax, amax=[15.0, 7.5, 10, 12.5, 15, 20, 20], jmax=5000.0)
    assert np.allclose(chain.vmax, vmax) and chain.amax[1] == 7.5 and np.all(chain.jmax == 5000.0)
    assert np.allclose(chain.lower, plain.lower) and np.allclose(chain.upper, plain.upper)
    q = np.array([0.1, -0.4, 0.2, -2.0, 0.1, 1.8, 0.7])
    assert np.allclose(chain.fk(q), plain.fk(q) @ tool)
    with pytest.raises(rc.errors.ImportModelError, match="tip"):
        franky_chain(urdf, flange="no_such_link")


def test_importing_drivers_loads_neither_franky_nor_mujoco():
    code = ("import sys, ratectl as rc; rc.drivers.ScriptedDriver; rc.run; "
            "bad = [m for m in ('franky', 'franky_sim', 'mujoco') if m in sys.modules]; "
            "assert not bad, bad; print('ok')")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and "ok" in out.stdout, out.stderr


def test_mujoco_driver_follows_a_line_with_physics():
    pytest.importorskip("mujoco")
    from ratectl.interop.mujoco import MujocoDriver

    assert rc.drivers.MujocoDriver is MujocoDriver  # the lazy re-export
    arm = rc.robots.panda()
    for actuation in ("position",):  # (velocity servos: the same code path minus the ramp)
        drv = MujocoDriver(arm, q0=Q0, period=0.002, actuation=actuation)
        assert isinstance(drv, Driver)
        T0 = arm.fk(Q0)
        T1 = T0.copy()
        T1[:3, 3] += [0.02, 0.0, -0.01]
        ex = rc.run(drv, path=rc.paths.Line(T0, T1, speed=0.1, acceleration=0.5), rate_hz=500.0)
        assert ex.completed, ex.message
        assert ex.max_position_error < 1e-3, actuation
        # the stamps are the physics time: one period per command
        assert np.allclose(np.diff(ex.stamps), 0.002, atol=1e-9)
        assert abs(drv.data.time - ex.stamps[-1] - 0.002) < 0.5  # (stop() steps the physics too)
        assert np.max(np.abs(drv.read().qd)) < 1e-3  # stop() brought it to rest
    with pytest.raises(InputError, match="multiple"):
        MujocoDriver(arm, q0=Q0, period=0.0015)
    with pytest.raises(DriverError, match="non-finite"):
        drv.command(np.full(7, np.nan))
