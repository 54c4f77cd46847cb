"""GapIntegral: the joints' tracking gap and its anti-windup rules, without a loop."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ratectl.execution.integral import GapIntegral

DT = 0.002


def _cycles(g, q, qd, k, status="regular", move=None):
    """k cycles of command qd; the joints move at ``move`` (default: not at all)."""
    t = getattr(g, "_t_test", 0.0)
    for _ in range(k):
        g.sent(qd + g.correction, DT)  # what the loop sends: the command plus the correction
        t += DT
        if move is not None:
            q = q + move(g, qd) * DT
        g.update(q, t, status)
    g._t_test = t
    return q


def test_a_stuck_joint_accumulates_its_command_until_the_clamp():
    g = GapIntegral(3, gain=10.0, max_gap=5e-3)
    q = np.zeros(3)
    g.update(q, 0.0, "regular")  # the first measured state
    qd = np.array([0.01, 0.0, -0.004])
    _cycles(g, q, qd, 50)  # 0.1 s: 1 mrad and -0.4 mrad of command
    assert np.allclose(g.gap, [1e-3, 0.0, -0.4e-3], atol=1e-12)
    assert np.allclose(g.correction, 10.0 * g.gap)
    _cycles(g, q, qd, 2000)  # 4 s more: clamped
    assert np.allclose(g.gap, [5e-3, 0.0, -5e-3])


def test_a_joint_that_follows_lets_the_gap_go():
    g = GapIntegral(1, gain=10.0)
    q = _cycles(g, np.zeros(1), np.array([0.01]), 100)
    before = float(g.gap[0])
    assert before > 0.0
    # now the joint follows the command and its correction (moving faster than "still")
    _cycles(g, q, np.array([0.05]), 100, move=lambda g, qd: qd + g.correction)
    assert 0.0 <= g.gap[0] <= before * 0.2  # 0.2 s at K_I = 10/s: e^-2 ≈ 0.14


def test_limited_cycles_hold_the_gap_and_the_dead_zone_empties_it():
    g = GapIntegral(2)
    q = _cycles(g, np.zeros(2), np.array([0.01, 0.01]), 50)
    held = g.gap.copy()
    _cycles(g, q, np.array([0.01, 0.01]), 50, status="joint-limit")
    assert np.array_equal(g.gap, held)
    g.update(q, 1.0, "regular", settled=True)
    assert not g.gap.any() and not g.correction.any()


def test_a_robot_slower_than_the_wall_clock_is_not_a_stuck_joint():
    # the robot's clock advanced half as much as the loop's: half the command counts
    g = GapIntegral(1, still_speed=1.0)
    q = np.zeros(1)
    g.update(q, 0.0, "regular")
    for _ in range(10):
        g.sent(np.array([0.01]), DT)
    g.update(q, 10 * DT / 2, "regular")
    assert np.isclose(g.gap[0], 0.01 * 10 * DT / 2)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-2.0, 2.0), min_size=1, max_size=60))
def test_the_correction_never_exceeds_gain_times_clamp(cmds):
    g = GapIntegral(1, gain=10.0, max_gap=5e-3)
    _cycles_q = np.zeros(1)
    t = 0.0
    for c in cmds:
        g.sent(np.array([c]) + g.correction, DT)
        t += DT
        g.update(_cycles_q, t, "regular")
        assert abs(g.correction[0]) <= 10.0 * 5e-3 + 1e-15
