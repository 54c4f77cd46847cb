"""Limits from every model source: chains without acceleration limits are controllable,
and ``Chain.with_limits`` / the importers' limit keywords give an imported chain the
limits its file lacks."""

import math
import os

import numpy as np
import pytest

import ratectl as rc
from ratectl.errors import InputError, ModelError

DATA = os.path.join(os.path.dirname(__file__), "..", "data")


def _no_amax_arm():
    """UR5e kinematics with position and velocity limits only (as a URDF would give)."""
    rows = [rc.DH(a=r.a, alpha=r.alpha, d=r.d, qlim=r.qlim, vmax=r.vmax) for r in rc.robots.ur5e().table]
    return rc.Chain.from_dh(rows, name="ur5e-no-amax")


def test_with_limits_scalar_per_joint_and_kept():
    arm = rc.robots.panda()
    new = arm.with_limits(amax=3.0, jmax=[100.0 + k for k in range(7)])
    assert new is not arm and isinstance(new, rc.Chain)
    assert np.all(new.amax == 3.0) and np.array_equal(new.jmax, 100.0 + np.arange(7))
    assert np.array_equal(new.vmax, arm.vmax) and np.array_equal(new.qlim, arm.qlim)  # kept
    assert np.array_equal(arm.amax, rc.robots.panda().amax)  # the original is unchanged
    assert np.allclose(new.fk(np.zeros(7)), arm.fk(np.zeros(7)))
    assert "3" in new.describe()
    one = arm.with_limits(qlim=(-1.0, 1.0))
    assert np.all(one.lower == -1.0) and np.all(one.upper == 1.0)
    per = arm.with_limits(qlim=np.column_stack([-np.arange(1, 8), np.arange(1, 8)]))
    assert np.array_equal(per.upper, np.arange(1, 8))
    assert arm.with_limits() is arm
    with pytest.raises(InputError):
        arm.with_limits(amax=[1.0, 2.0])
    with pytest.raises(InputError):
        arm.with_limits(qlim=[(0, 1)] * 3)
    with pytest.raises(ModelError, match="amax"):
        arm.with_limits(amax=-1.0)
    with pytest.raises(ModelError, match="qlim"):
        arm.with_limits(qlim=(1.0, -1.0))


def test_importers_accept_the_limit_keywords():
    path = os.path.join(DATA, "ur5e_like.urdf")
    plain = rc.Chain.from_urdf(path)
    assert np.all(np.isinf(plain.amax))  # URDF has no acceleration limits
    arm = rc.Chain.from_urdf(path, amax=8.0, jmax=80.0)
    assert np.all(arm.amax == 8.0) and np.all(arm.jmax == 80.0)
    assert np.array_equal(arm.vmax, plain.vmax)
    mj = rc.Chain.from_mjcf(os.path.join(DATA, "ur5e_like.xml"), vmax=1.0, amax=5.0)
    assert np.all(mj.vmax == 1.0) and np.all(mj.amax == 5.0)
    # smoothing then works on the imported arm
    rc.ResolvedRateController(arm, smoothing=True)
    with pytest.raises(InputError, match="with_limits"):
        rc.ResolvedRateController(plain, smoothing=True)


@pytest.mark.parametrize("arm", [_no_amax_arm(), rc.Chain.from_urdf(os.path.join(DATA, "ur5e_like.urdf"))],
                         ids=["dh", "urdf"])
def test_a_chain_without_acceleration_limits_moves_and_reaches_a_target(arm):
    q0 = np.array([0.3, -1.3, 1.6, -1.9, -1.2, 0.2])
    ctrl = rc.ResolvedRateController(arm)
    target = arm.fk(q0)
    target[:3, 3] += [0.0, 0.05, 0.0]
    q = q0.copy()
    for _ in range(2000):
        cmd = ctrl.step(q, target=target, dt=1e-3)
        assert cmd.status != "joint-limit" and np.all(np.abs(cmd.qd) <= arm.vmax * (1 + 1e-12))
        q = cmd.q_next
    assert cmd.status == "target-reached" and cmd.position_error < 1e-4


def test_without_acceleration_limits_the_velocity_limit_enforces_the_position_limit():
    """A joint driven at its limit arrives at vmax and stops exactly on it: never beyond it,
    and never held at zero while inside its range."""
    arm = _no_amax_arm()
    ctrl = rc.ResolvedRateController(arm)
    q = np.array([0.3, -1.3, math.pi - 0.2, -1.9, -1.2, 0.2])
    ff = np.zeros(6)
    ff[2] = 10.0  # far beyond vmax: the velocity limit scales it
    qs = []
    for _ in range(200):
        cmd = ctrl.step(q, qd_ff=ff, dt=1e-3)
        q = cmd.q_next
        qs.append(q[2])
    qs = np.array(qs)
    assert qs.max() <= arm.upper[2] + 1e-12
    assert qs[-1] == pytest.approx(arm.upper[2], abs=1e-12)
    moving = qs < arm.upper[2] - arm.vmax[2] * 1e-3
    speeds = np.diff(np.concatenate([[math.pi - 0.2], qs])) / 1e-3
    assert np.allclose(speeds[moving], arm.vmax[2])  # full speed until the last period
