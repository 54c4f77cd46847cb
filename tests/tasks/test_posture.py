"""The posture task's feedback: linear in the error where a joint can brake from that speed,
bounded by the joint's braking speed beyond; and a high-gain posture with smoothing settles."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ratectl as rc
from ratectl.model.limits import braking_speed

HOME = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])


@settings(max_examples=60, deadline=None)
@given(gain=st.floats(0.0, 300.0), jmax=st.sampled_from([50.0, 200.0, 7500.0, math.inf]),
       amax=st.sampled_from([2.0, 15.0, math.inf]), scale=st.floats(1e-6, 3.0), seed=st.integers(0, 99),
       weight=st.floats(0.01, 4.0))
def test_posture_speed_is_the_linear_law_bounded_by_the_braking_speed(gain, jmax, amax, scale, seed, weight):
    chain = rc.robots.panda().with_limits(amax=amax, jmax=jmax)
    rng = np.random.default_rng(seed)
    q = HOME + rng.uniform(-0.2, 0.2, 7)
    e = scale * rng.uniform(-1.0, 1.0, 7)
    post = rc.tasks.Posture(q + e, gain=gain, weight=weight)
    rows = post.rows(chain, q)
    err = rows.error
    # independently: the array form of the braking speed, joint by joint
    # (fmin: no bound where the braking speed is not a number, without amax and jmax)
    with np.errstate(invalid="ignore", divide="ignore"):  # (inf amax: NaN, no bound, by fmin)
        bound = braking_speed(np.abs(err), chain.amax, chain.jmax)
    want = np.sign(err) * np.fmin(gain * np.abs(err), bound)
    assert np.allclose(rows.b, want, rtol=1e-12, atol=1e-300)
    # with a weight, the rows are scaled by √weight
    A = np.zeros((7, 7))
    b = np.zeros(7)
    post._fill(chain, q, A, b, np.zeros(7), math.sqrt(weight))
    assert np.allclose(b, math.sqrt(weight) * want, rtol=1e-12, atol=1e-300)


def test_posture_is_linear_where_the_joint_can_brake():
    """Small errors: b = K e exactly (the bound never touches a gentle posture)."""
    chain = rc.robots.panda()
    post = rc.tasks.Posture(HOME + 1e-4, gain=10.0)
    rows = post.rows(chain, HOME)
    assert np.array_equal(rows.b, 10.0 * rows.error)


@pytest.mark.parametrize("jmax", [200.0, 500.0])
def test_high_gain_posture_with_smoothing_settles(jmax):
    """A posture (gain 50, priority 1) whose reference the tool task leaves out of reach,
    with smoothing, on a Panda with a low jerk limit. Before: the null-space motion swung
    between ±vmax, the filter (joint by joint) left the null space while reversing, and the
    tool error cycled between 1 and 26 mm for ever."""
    chain = rc.robots.panda().with_limits(jmax=jmax)
    q = HOME.copy()
    T = chain.fk(q)
    T[:3, 3] += [0.03, -0.02, 0.02]
    tasks = [rc.tasks.Pose(priority=0, target=T), rc.tasks.Posture(np.zeros(7), priority=1, gain=50.0)]
    ctrl = rc.ResolvedRateController(chain, tasks=tasks, smoothing=True)
    err, speed = [], []
    for _ in range(3000):
        cmd = ctrl.step(q, dt=1e-3)
        q = cmd.q_next
        err.append(cmd.position_error)
        speed.append(float(np.abs(cmd.qd).max()))
    assert max(err[-500:]) < 1e-4, (min(err[-500:]), max(err[-500:]))
    assert max(speed[-500:]) < 1e-3  # at rest: the posture is as close as the tool allows
