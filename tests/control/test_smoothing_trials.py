"""Smoothed servo and jog in loops a new user writes, beyond the ideal arm
(``q = cmd.q_next``): an arm that applies only part of each command, a held twist into a
boundary singularity, a jittered period. Each test is a case a user's trial found."""

import math

import numpy as np
import pytest

import ratectl as rc
from ratectl.spatial import so3_exp

UR5E_Q0 = np.array([0.3, -1.2, 1.5, -1.9, -1.4, 0.6])


def _ur5e_step_target(chain, q0, length=0.138, turn=0.1):
    """The tool point moved ``length`` [m] along a fixed oblique direction, the tool turned
    ``turn`` [rad] about a fixed axis: (target, start point, unit direction of the step)."""
    T0 = chain.fk(q0)
    d = np.array([1.0, 0.5, -0.3])
    d /= np.linalg.norm(d)
    axis = np.array([0.2, 0.3, 1.0])
    T = T0.copy()
    T[:3, 3] += length * d
    T[:3, :3] = so3_exp(axis / np.linalg.norm(axis) * turn) @ T0[:3, :3]
    return T, T0[:3, 3], d


@pytest.mark.parametrize("smoothing", [True, False], ids=["smooth", "plain"])
@pytest.mark.parametrize("gain", [1.0, 0.5, 0.3])
def test_an_arm_that_applies_part_of_each_command_does_not_overshoot(gain, smoothing):
    """A velocity servo with a gain below 1 moves the arm by ``gain·(cmd.q_next − q)`` each
    cycle. It lags its straight line by more than 20 mm, and the servo restarts the line from
    where the arm is. The new line used to start at the commanded speed, which carries the
    feedback on that very lag (1/gain times the arm's own speed): each restart raised the
    progress (0.44 → 1.07 m/s) and the stop from that speed ran the UR5e 57–97 mm past a
    138 mm step (allowed 1 % + 0.1 mm), smoothed or not. The restarted line is no faster
    than the old reference along it: no overshoot, the target reached, for every gain."""
    chain = rc.robots.ur5e()
    dt = 4e-3
    T, p0, d = _ur5e_step_target(chain, UR5E_Q0)
    L = 0.138
    ctrl = rc.ResolvedRateController(chain, smoothing=smoothing)
    q = UR5E_Q0.copy()
    along = 0.0
    reached = math.inf
    for k in range(int(round(4.0 / dt))):
        cmd = ctrl.step(q, target=T, dt=dt)
        q = q + gain * (cmd.q_next - q)
        along = max(along, float((chain.fk(q)[:3, 3] - p0) @ d))
        if cmd.status == "target-reached":
            reached = (k + 1) * dt
            break
    overshoot = along - L
    assert overshoot <= 0.01 * L + 1e-4, (
        f"gain {gain}: {overshoot * 1e3:.2f} mm past the target along the step "
        f"(allowed {(0.01 * L + 1e-4) * 1e3:.2f} mm)")
    assert reached <= 4.0, f"gain {gain}: not reached in 4 s (last status {cmd.status!r})"


def _uncommanded(P, R, u, forward):
    """Σ‖Δp − max(Δp·u, 0)·u‖ (each leg against its own direction: u, then −u) [m] and the
    integrated rotation Σ∠(R_{k+1}R_kᵀ) [rad] of a jog whose twist is a pure translation."""
    from ratectl.spatial import rotation_angle

    dP = np.diff(P, axis=0)
    uu = np.where(np.arange(len(dP))[:, None] < forward, u, -u)
    along = np.einsum("ij,ij->i", dP, uu)
    side = float(np.sum(np.linalg.norm(dP - np.maximum(along, 0.0)[:, None] * uu, axis=1)))
    return side, float(np.sum(rotation_angle(R[1:] @ np.swapaxes(R[:-1], -1, -2))))


def test_a_smoothed_jog_into_the_ur5e_boundary_singularity_never_slides():
    """The UR5e stretched toward its workspace boundary by a held radial twist of 0.1 m/s
    (3 s), then the reversed twist (0.5 s), smoothed. The filter used to lag each joint on its
    own behind c·J⁺ξ, whose joint direction turns fast near the singularity: the tool slid
    2.54 mm sideways on the way in and 5.9 mm more on the way out (8.45 mm and 1.0° in all;
    allowed 2 mm and 0.5°). The jog's fraction c is now jerk-limited and the command a
    reference with its acceleration, which the filter meets: the tool stays on ξ, the arm
    halts before the singularity and moves away at once."""
    chain = rc.robots.ur5e()
    p = chain.fk(UR5E_Q0)[:3, 3]
    u = np.array([p[0], p[1], 0.0]) / np.hypot(p[0], p[1])
    xi = np.r_[0.1 * u, 0.0, 0.0, 0.0]
    dt, forward, back = 1e-3, 3000, 500
    ctrl = rc.ResolvedRateController(chain, smoothing=True)
    q = UR5E_Q0.copy()
    qs, cmds = [q], []
    for k in range(forward + back):
        cmd = ctrl.step(q, twist=xi if k < forward else -xi, dt=dt)
        q = np.array(cmd.q_next)
        qs.append(q)
        cmds.append(cmd)
    T = chain.fk(np.array(qs))
    P, R = T[:, :3, 3], T[:, :3, :3]
    side, rot = _uncommanded(P, R, u, forward)
    assert side <= 2e-3 and rot <= math.radians(0.5), (
        f"uncommanded motion {side * 1e3:.3f} mm and {math.degrees(rot):.3f}° (allowed 2 mm, 0.5°)")
    halt = cmds[forward - 1]
    assert halt.status == "halted-singularity" and halt.kind == "boundary", halt
    assert float((P[forward] - P[0]) @ u) > 0.15  # (it did stretch out before it halted)
    v_back = float((P[-1] - P[-51]) @ -u) / (50 * dt)
    assert v_back >= 0.05, f"the reversed twist moves the tool at {v_back * 1e3:.1f} mm/s"
    qd = np.array([c.qd for c in cmds])
    assert np.all(np.abs(qd) <= chain.vmax * (1 + 1e-9))
    assert np.all(np.abs(np.array([c.qdd for c in cmds])) <= chain.amax * (1 + 1e-9))


@pytest.mark.parametrize("name, q0, twist", [
    ("ur5e", [0.3, -1.2, 1.5, -1.9, -1.4, 0.4], [0.1, 0.05, -0.05, 0.0, 0.0, 0.0]),
    ("iiwa7", [0.2, 0.5, 0.1, -1.2, 0.1, 0.8, 0.3], [0.08, -0.05, 0.05, 0.0, 0.0, 0.0]),
    ("panda", [0.2, -0.4, 0.1, -2.0, 0.1, 1.8, 0.6], [0.0, 0.1, 0.05, 0.0, 0.0, 0.0]),
])
def test_a_smoothed_jog_reversed_at_full_speed_turns_back_along_its_line(name, q0, twist):
    """A twist held 1 s (the jog at full speed), then reversed for 1 s, smoothed, dt 4 ms, in
    a regular configuration. The reversed jog used to restart from rest: the filter then
    braked each joint on its own and the tool slid 6.8 mm (UR5e) and 17.7 mm (iiwa7) across
    the twist. It must decelerate along its line and come back on it: the tool's motion
    across the twist stays within 1 mm in total, and it moves back at 50 % of the twist's
    speed within 0.5 s."""
    arm = getattr(rc.robots, name)()
    q = np.array(q0)
    xi = np.array(twist)
    dt = 4e-3
    ctrl = rc.ResolvedRateController(arm, smoothing=True)
    p = arm.fk(q)[:3, 3]
    across = 0.0
    away_at = None
    hold = int(round(1.0 / dt))
    for k in range(2 * hold):
        x = xi if k < hold else -xi
        cmd = ctrl.step(q, twist=x, dt=dt)
        q = cmd.q_next
        p_next = arm.fk(q)[:3, 3]
        dp = p_next - p
        along = float(dp @ x[:3]) / float(x[:3] @ x[:3])
        across += float(np.linalg.norm(dp - along * x[:3]))
        if k >= hold and away_at is None and along / dt > 0.5:
            away_at = (k - hold) * dt
        p = p_next
    assert across <= 1e-3, f"{across * 1e3:.2f} mm across the twist"
    assert away_at is not None and away_at <= 0.5, away_at


def _jog_off_twist(arm, q0, xi, *, dt, seconds, **kw):
    """A smoothed jog of the held twist ``xi`` from ``q0``: (motion across the twist [m]
    and rotation off it [rad], each integrated per cycle as Σ‖Δx − max(c, 0)·ξ‖ with c the
    cycle's least-squares multiple of ξ in [m, 0.2 m·rad], the last command, q)."""
    from ratectl.spatial import so3_log

    ctrl = rc.ResolvedRateController(arm, smoothing=True, **kw)
    W = np.array([1.0, 1.0, 1.0, 0.04, 0.04, 0.04])
    q = np.array(q0, dtype=float)
    T = arm.fk(q)
    side = rot = 0.0
    cmd = None
    for _ in range(int(round(seconds / dt))):
        cmd = ctrl.step(q, twist=xi, dt=dt)
        q = cmd.q_next
        Tn = arm.fk(q)
        dx = np.r_[Tn[:3, 3] - T[:3, 3], so3_log(Tn[:3, :3] @ T[:3, :3].T)]
        c = max(float((dx * W) @ xi / ((xi * W) @ xi)), 0.0)
        side += float(np.linalg.norm(dx[:3] - c * xi[:3]))
        rot += float(np.linalg.norm(dx[3:] - c * xi[3:]))
        T = Tn
    return side, rot, cmd, q


@pytest.mark.parametrize("dt", [1e-3, 4e-3])
def test_a_smoothed_jog_into_a_joint_limit_stops_on_its_twist(dt):
    """A trial's iiwa7: from σ_min 2.6e-5 at its boundary singularity, a 0.1 m/s twist away
    from it, held 2.5 s, smoothed, runs joint 2 into its lower limit while its joint
    direction still turns fast. The jog slowed to the limit's braking speed only once it
    bound, which falls faster than a jerk-limited progress can follow: the guard braked
    joint 2 on its own and the tool slid 6.4 mm (dt 1 ms) and 1.7 mm (4 ms) across the twist.
    The stop is now planned before the limit, as before a singularity, and the jog ends at
    rest on its twist, the margin inside the limit kept."""
    arm = rc.robots.iiwa7()
    q0 = [2.3448921398, -1.6981537208, 0.5357912688, -0.0001608148, 2.4825796191, 1.0444315771, -1.5649477908]
    xi = -np.array([0.0693387486, -0.0709294494, -0.0126945324, 0.0076112635, 0.0076787991, -0.0013293697])
    side, rot, cmd, q = _jog_off_twist(arm, q0, xi, dt=dt, seconds=2.5)
    assert side <= 2e-4 and rot <= math.radians(0.05), (
        f"{side * 1e3:.3f} mm and {math.degrees(rot):.3f}° off the twist")
    assert cmd.status == "joint-limit" and "'iiwa_joint_2'" in cmd.reason, (cmd.status, cmd.reason)
    assert np.max(np.abs(cmd.qd)) <= 1e-12  # (at rest)
    assert 0.9e-3 <= q[1] - arm.lower[1] <= 2e-3, q[1] - arm.lower[1]


@pytest.mark.parametrize("name, q0, twist", [
    ("iiwa7", [1.4995148002, 0.0648301345, 1.3505017853, -1.3971311805, 0.6978943110, 1.7030893890,
               -0.4219342797], [-0.0957995500, 0.0220081182, 0.0183871955, 0.0016999481, -0.0100348092,
                                0.0057638441]),
    ("ur5e", [0.3, -1.2, 1.5, -1.9, -1.4, 0.6], [0.0, -0.1, 0.0, 0.0, 0.0, 0.0]),
    ("panda", [0.2, -0.4, 0.1, -2.0, 0.1, 1.8, 0.6], [0.06, 0.0, -0.08, 0.0, 0.0, 0.0]),
])
def test_a_smoothed_jog_whose_joint_direction_turns_stays_on_its_twist(name, q0, twist):
    """A held twist, smoothed, dt 4 ms, 2.5 s (a trial's iiwa7 leaving σ_min 0.054, where
    w = J⁺ξ turns fast, and two regular jogs). The filter meets its reference at the end of
    the period, and the jog gave it w at the start: one period behind the arm, the tool
    drifted across the twist with no feedback to take it back (iiwa7 2.2 mm; UR5e, Panda
    0.1–0.3 mm). The reference is w at the end of the period, w + ẇ·dt."""
    arm = getattr(rc.robots, name)()
    side, rot, _, _ = _jog_off_twist(arm, q0, np.array(twist), dt=4e-3, seconds=2.5)
    assert side <= 5e-5 and rot <= math.radians(0.01), (
        f"{side * 1e3:.3f} mm and {math.degrees(rot):.4f}° off the twist")
