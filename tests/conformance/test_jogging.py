"""Jogging: a held twist is followed in its own direction or scaled down, never rotated.

The loop is the teleoperator's, ``cmd = ctrl.step(q, twist=xi, dt=1e-3); q = cmd.q_next``,
held for 3 s into a singularity, then the reversed twist for 0.5 s:

* **Panda boundary**: the built-in Panda from q = [0, 0.334, 0, −1.177, 0, 1.510, 0.785]
  (MoveIt Servo's "approaching singularity" test state), a +x base twist of 0.1 m/s: the
  arm stretches out toward its workspace boundary.
* **UR5e wrist**: the line of ``ratectl demo`` (`ratectl.cli.demo.wrist_line`), a
  constant-orientation translation whose joint path passes |q5| = 0.01 rad, where the wrist
  flips (q5 → 0: joints 4 and 6 align); from its start, the twist 0.1 m/s along the line
  (the direction that makes the exact inverse fastest at the closest point). At 0.1 m/s
  the line's exact inverse needs 6.7× vmax there (21 rad/s at joint 4), so the arm must
  slow down and stop before it.

Uncommanded motion, over both legs: the tool point's displacement per cycle Δp minus its
part along the commanded direction u when that part is positive, Σ‖Δp − max(Δp·u, 0)u‖
(motion sideways or backwards, integrated), and the integrated rotation Σ∠(R_{k+1}R_kᵀ)
(the twists are pure translations). Allowed: 2 mm and 0.5° in total. The reversed twist
must move the tool along −u at ≥ 50 % of its speed (mean over the last 50 ms) within 0.5 s.
The statuses: ``approaching-singularity`` while decelerating, then ``halted-singularity``
once stopped, with ``cmd.kind`` the singularity's kind.

Tool axes: ``ctrl.step(q, twist=xi, frame="tool", dt=...)`` with a pure rotation about the
tool z axis keeps the tool point within 0.1 mm. Reasons name joints by ``chain.joint_names``.
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass

import numpy as np
import pytest

import ratectl as rc
from ratectl.spatial import rotation_angle, so3_log

DT = 1e-3
HOLD = 3.0          # s into the singularity
BACK = 0.5          # s of the reversed twist
SPEED = 0.1         # m/s
PANDA_Q0 = np.array([0.0, 0.334, 0.0, -1.177, 0.0, 1.510, 0.785])


@dataclass(frozen=True)
class Jog:
    name: str
    chain: rc.Chain
    P: np.ndarray            # tool points of every state (N+1, 3)
    R: np.ndarray            # tool rotations (N+1, 3, 3)
    u: np.ndarray            # the commanded direction of the first leg
    cmds: tuple              # every command
    forward: int             # cycles of the first leg
    expected_kind: str

    def uncommanded(self) -> tuple[float, float]:
        """(integrated sideways-or-backward displacement [m], integrated rotation [rad]),
        each leg judged against its own commanded direction."""
        dP = np.diff(self.P, axis=0)
        u = np.where(np.arange(len(dP))[:, None] < self.forward, self.u, -self.u)
        along = np.einsum("ij,ij->i", dP, u)
        off = dP - np.maximum(along, 0.0)[:, None] * u
        rot = rotation_angle(self.R[1:] @ np.swapaxes(self.R[:-1], -1, -2))
        return float(np.sum(np.linalg.norm(off, axis=1))), float(np.sum(rot))

    def describe(self) -> str:
        f = self.forward
        d = self.P[f] - self.P[0]
        along = float(d @ self.u)
        side = float(np.linalg.norm(d - along * self.u))
        statuses: dict[str, int] = {}
        for c in self.cmds[:f]:
            statuses[c.status] = statuses.get(c.status, 0) + 1
        back = float((self.P[-1] - self.P[f]) @ -self.u)
        return (f"{self.name}: after {HOLD:g} s {along * 1e3:.1f} mm along the twist, "
                f"{side * 1e3:.1f} mm sideways (net), turned "
                f"{math.degrees(rotation_angle(self.R[f] @ self.R[0].T)):.2f}° (net); last "
                f"{self.cmds[f - 1]}; statuses {statuses}; reversed: {back * 1e3:.1f} mm in {BACK:g} s")


def _jog(name, chain, q0, xi, expected_kind) -> Jog:
    ctrl = rc.ResolvedRateController(chain)
    q = np.array(q0, dtype=float)
    qs, cmds = [q], []
    n = int(round(HOLD / DT))
    for k in range(n + int(round(BACK / DT))):
        cmd = ctrl.step(q, twist=xi if k < n else -xi, dt=DT)
        q = np.array(cmd.q_next)
        qs.append(q)
        cmds.append(cmd)
    T = chain.fk(np.array(qs))
    u = xi[:3] / np.linalg.norm(xi[:3])
    return Jog(name, chain, T[:, :3, 3], T[:, :3, :3], u, tuple(cmds), n, expected_kind)


def ur5e_wrist_twist():
    """(chain, q0, ξ) of the UR5e wrist case (module docstring)."""
    from ratectl.cli.demo import wrist_line

    sc = wrist_line("ur5e")
    d = sc.path.end[:3, 3] - sc.path.start[:3, 3]
    xi = np.concatenate([SPEED * d / np.linalg.norm(d), np.zeros(3)])
    return sc.chain, np.array(sc.q0, dtype=float), xi, sc.min_q5


@functools.cache
def jog(case: str) -> Jog:
    if case == "panda-boundary":
        xi = np.array([SPEED, 0.0, 0.0, 0.0, 0.0, 0.0])
        return _jog(case, rc.robots.panda(), PANDA_Q0, xi, "boundary")
    chain, q0, xi, _ = ur5e_wrist_twist()
    return _jog(case, chain, q0, xi, "wrist")


CASES = ["panda-boundary", "ur5e-wrist"]


def test_the_ur5e_line_drives_q5_to_zero():
    """The UR5e case is what it claims: the line's joint path starts at |q5| ≈ 0.24 rad and
    passes |q5| ≤ 0.01 rad, a wrist singularity by `rc.analyze`, where the exact inverse of
    the held twist needs several times vmax (21 rad/s at joint 4)."""
    from ratectl.cli.demo import wrist_line

    sc = wrist_line("ur5e")
    assert abs(sc.q0[4]) >= 0.2 and sc.min_q5 <= 0.0101
    assert rc.analyze(sc.chain, sc.q_closest).kind == "wrist"
    _, _, xi, _ = ur5e_wrist_twist()
    need = np.linalg.solve(sc.chain.jacobian(sc.q_closest), xi)
    assert float(np.max(np.abs(need) / sc.chain.vmax)) > 3.0


@pytest.mark.parametrize("case", CASES)
def test_jogging_into_a_singularity_never_slides(case):
    run = jog(case)
    side, rot = run.uncommanded()
    assert side <= 2e-3 and rot <= math.radians(0.5), (
        f"uncommanded motion {side * 1e3:.2f} mm (allowed 2 mm) and {math.degrees(rot):.3f}° "
        f"(allowed 0.5°) in total. {run.describe()}")


@pytest.mark.parametrize("case", CASES)
def test_the_reversed_twist_moves_away_at_once(case):
    run = jog(case)
    f = run.forward
    last = int(round(0.05 / DT))
    v = float((run.P[-1] - run.P[-1 - last]) @ -run.u) / (last * DT)
    assert v >= 0.5 * SPEED, (
        f"reversed twist: {v * 1e3:.1f} mm/s along it over the last 50 ms of {BACK:g} s "
        f"(allowed ≥ {0.5 * SPEED * 1e3:.0f} mm/s); moved "
        f"{float((run.P[-1] - run.P[f]) @ -run.u) * 1e3:.1f} mm. {run.describe()}")


@pytest.mark.parametrize("case", CASES)
def test_statuses_tell_approaching_from_halted_with_the_kind(case):
    run = jog(case)
    statuses = [c.status for c in run.cmds[:run.forward]]
    assert "approaching-singularity" in statuses, (
        f"never 'approaching-singularity' while slowing down. {run.describe()}")
    assert "halted-singularity" in statuses, f"never 'halted-singularity'. {run.describe()}"
    first_halt = statuses.index("halted-singularity")
    assert "approaching-singularity" in statuses[:first_halt], (
        f"'halted-singularity' at cycle {first_halt} before any 'approaching-singularity'. "
        f"{run.describe()}")
    last = run.cmds[run.forward - 1]
    assert last.status == "halted-singularity", (
        f"still {last.status!r} after {HOLD:g} s of the held twist. {run.describe()}")
    assert last.kind == run.expected_kind, (
        f"kind {last.kind!r} at the halt (expected {run.expected_kind!r}). {run.describe()}")
    assert last.reason, f"a halt without a reason. {run.describe()}"
    assert float(np.max(np.abs(last.qd))) <= 1e-6, f"halted but moving: {last}"


def _tool_z(chain, q0, seconds=1.0, rate=0.5):
    ctrl = rc.ResolvedRateController(chain)
    xi = np.array([0.0, 0.0, 0.0, 0.0, 0.0, rate])
    q = np.array(q0, dtype=float)
    T0 = chain.fk(q)
    worst = 0.0
    for _ in range(int(round(seconds / DT))):
        cmd = ctrl.step(q, twist=xi, frame="tool", dt=DT)
        q = np.array(cmd.q_next)
        T = chain.fk(q)
        worst = max(worst, float(np.linalg.norm(T[:3, 3] - T0[:3, 3])))
    r = so3_log(T0[:3, :3].T @ T[:3, :3])   # the turn in the start's tool axes
    return worst, r


TOOLS = {
    "flange": np.eye(4),
    # a tilted, offset tool: its z axis is not any joint's axis
    "tilted": rc.spatial.transform(rc.spatial.rotx(math.radians(30.0)), [0.05, 0.0, 0.12]),
}
TOOL_ARMS = {
    "ur5e": (rc.robots.ur5e, [0.3, -1.2, 1.5, -1.9, -1.4, 0.6]),
    "panda": (rc.robots.panda, [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]),
}


@pytest.mark.parametrize("tool", sorted(TOOLS))
@pytest.mark.parametrize("arm", sorted(TOOL_ARMS))
def test_a_rotation_about_tool_z_in_tool_axes_keeps_the_tool_point(arm, tool):
    factory, q0 = TOOL_ARMS[arm]
    chain = factory().with_tool(TOOLS[tool])
    worst, r = _tool_z(chain, q0)
    where = f"{arm} with the {tool} tool, 0.5 rad/s about tool z for 1 s"
    assert worst <= 1e-4, f"{where}: the tool point moved {worst * 1e3:.3f} mm (allowed 0.1 mm)"
    assert r[2] >= 0.45, f"{where}: turned only {r[2]:.3f} rad about tool z (expected ≥ 0.45)"
    off = float(np.linalg.norm(r[:2]))
    assert off <= math.radians(0.5), f"{where}: turned {math.degrees(off):.3f}° about other axes"


def test_reasons_name_joints_by_the_chains_joint_names():
    """The Panda's joint 1 runs into its upper limit under a base twist about z: a reason
    names it ``panda_joint1`` (``chain.joint_names[0]``), and no reason lists joint indices."""
    chain = rc.robots.panda()
    assert chain.joint_names[0] == "panda_joint1"
    ctrl = rc.ResolvedRateController(chain)
    q = np.array([2.7, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    xi = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.5])
    reasons = set()
    for _ in range(1500):
        cmd = ctrl.step(q, twist=xi, dt=DT)
        q = np.array(cmd.q_next)
        if cmd.reason:
            reasons.add(cmd.reason)
    assert q[0] > 2.85, f"joint 1 did not reach its limit (q1 = {q[0]:.3f})"
    indexed = [r for r in reasons if re.search(r"joint\(?s?\)? ?\[\d", r)]
    assert not indexed, f"reasons list joints by index: {sorted(indexed)[:3]}"
    assert any(chain.joint_names[0] in r for r in reasons), (
        f"no reason names {chain.joint_names[0]!r}: {sorted(reasons)[:5]}")


def test_a_smoothed_jog_in_tool_axes_follows_the_same_line_as_in_base_axes():
    """UR5e, smoothed, a 0.15 m/s translation out toward the workspace boundary, held 1.5 s
    (accelerating, cruising, stopping before the elbow singularity), given once in base
    axes and once in the tool axes at the start (the same line, the tool does not turn):
    the two tool paths agree within 0.05 mm and the tool turns less than 0.01°. The
    tool-axes twist turns with the tool every period by rounding; the jog then dropped
    ẇ from the filter's reference, the tool slid up to 4.9 mm across the twist and
    turned, and the turn rotated the commanded direction further."""
    arm = rc.robots.ur5e()
    q0 = np.array([0.3, -1.3, 1.6, -1.9, -1.2, 0.2])
    T0 = arm.fk(q0)
    radial = np.array([T0[0, 3], T0[1, 3], 0.0])
    xi_base = np.r_[0.15 * radial / np.linalg.norm(radial), 0.0, 0.0, 0.0]
    R0 = T0[:3, :3]
    xi_tool = np.r_[R0.T @ xi_base[:3], 0.0, 0.0, 0.0]
    paths, turns = [], []
    for frame, xi in (("base", xi_base), ("tool", xi_tool)):
        ctrl = rc.ResolvedRateController(arm, smoothing=True)
        q = q0.copy()
        p = []
        for _ in range(1500):
            cmd = ctrl.step(q, twist=xi, frame=frame, dt=1e-3)
            q = cmd.q_next
            p.append(arm.fk(q)[:3, 3])
        paths.append(np.array(p))
        turns.append(math.degrees(rotation_angle(arm.fk(q)[:3, :3] @ R0.T)))
    assert np.linalg.norm(paths[1][-1] - paths[1][0]) > 0.1  # it moved
    assert np.max(np.linalg.norm(paths[0] - paths[1], axis=1)) <= 0.05e-3
    assert max(turns) <= 0.01, turns


@pytest.mark.parametrize("dt", [1e-3, 2e-3, 4e-3])
def test_a_smoothed_jog_keeps_its_stop_before_a_singularity_with_a_joint_limit_far_ahead(dt):
    """example-robot-data's UR10 (its URDF, amax and jmax added), smoothed, a twist that
    drives wrist 2 toward 0 (its wrist singularity), its lower limit −2π far beyond: the jog
    plans its stop before the singularity and keeps it when a period's look-ahead sees only
    that far limit. It took the limit for the block instead, said "joint 'wrist_2_joint'
    braking toward its lower limit" with every joint more than 0.5 rad from its limits,
    and planned the stop anew a few periods later."""
    from . import servo_arms

    if servo_arms.robots_dir() is None:
        pytest.skip("example-robot-data is not installed")
    arm = servo_arms.urdf_arm("ur10")
    q = np.array([0.3, -1.3, 1.6, -1.9, 0.25, 0.2])
    J = arm.jacobian(q)
    xi = -J[:, 4] / np.linalg.norm(J[:3, 4]) * 0.08
    ctrl = rc.ResolvedRateController(arm, smoothing=True)
    statuses = set()
    for _ in range(int(3.0 / dt)):
        cmd = ctrl.step(q, twist=xi, dt=dt)
        q = cmd.q_next
        assert np.min(np.minimum(q - arm.lower, arm.upper - q)) > 0.5  # no limit near
        statuses.add(cmd.status)
    assert "joint-limit" not in statuses, statuses
    assert cmd.status == "halted-singularity" and np.max(np.abs(cmd.qd)) < 1e-9


def _smoothed_qp_jog(name, arm, q, xi, dt, seconds, *, check=None):
    """A smoothed QP jog along ``xi`` (a pure translation) for ``seconds``: (the `Jog` of its
    tool path, its last command); ``check(arm, q, cmd, u)`` is called every cycle."""
    u = xi[:3] / np.linalg.norm(xi[:3])
    ctrl = rc.ResolvedRateController(arm, smoothing=True, solver=rc.solvers.QP())
    qs, cmd = [q], None
    for _ in range(int(round(seconds / dt))):
        cmd = ctrl.step(q, twist=xi, dt=dt)
        if check is not None:
            check(arm, q, cmd, u)
        q = cmd.q_next
        qs.append(q)
    T = arm.fk(np.array(qs))
    return Jog(name, arm, T[:, :3, 3], T[:, :3, :3], u, (), len(qs) - 1, "boundary"), cmd


@pytest.mark.parametrize("dt", [1e-3, 2e-3, 4e-3])
def test_a_smoothed_stop_before_a_singularity_that_ends_still_braking_stays_on_the_twist(dt):
    """The built-in PUMA 560 (its own limits), smoothed, the QP, a 0.14 m/s twist into its
    boundary singularity: the planned stop reaches rest still braking (its block estimate
    kept coming nearer) harder than the filter's jerk can ramp out at rest. Cut to rest
    there, each joint of the filter ramped its own braking out: the tool slid 4.7 mm across
    the twist and turned 0.64° at 4 ms, then started again with the tool velocity 93° off
    the twist under "accelerating along the commanded twist". The stop now ends on the
    twist's line (with a motion back along it where it must): within the jogging allowance
    of 2 mm and 0.5°, every commanded tool velocity along ±the twist."""
    arm = rc.robots.puma560()
    q = np.array([-1.975416533871512, 1.5442872321370555, -0.8731810011017753, -0.11563858364151658,
                  -0.9268344384742346, 0.5563191829761509])
    xi = np.array([-0.019153878880145005, 0.051574200495809484, 0.12704490509104277, 0.0, 0.0, 0.0])
    statuses = set()

    def along_the_twist(arm, q, cmd, u):
        v = (arm.jacobian(q) @ cmd.qd)[:3]
        side = np.linalg.norm(v - (v @ u) * u)
        assert side <= 0.02 * SPEED + 0.05 * np.linalg.norm(v), (cmd.status, cmd.reason, v)
        statuses.add(cmd.status)

    run, cmd = _smoothed_qp_jog("puma560-boundary", arm, q, xi, dt, 2.0, check=along_the_twist)
    off, turn = run.uncommanded()
    assert off <= 2e-3 and math.degrees(turn) <= 0.5, (off, math.degrees(turn))
    assert "approaching-singularity" in statuses and cmd.status == "halted-singularity"


@pytest.mark.parametrize("dt", [1e-3, 4e-3])
def test_a_smoothed_jog_plans_its_stop_for_a_joint_limit_behind_a_nearer_singularity_block(dt):
    """The built-in iiwa7, smoothed, the QP, a 0.15 m/s twist that stretches the arm toward
    its boundary singularity while joint 1 runs toward its upper limit just beyond that block:
    the stop a limit needs is due earlier than a singularity's (at half the room, not once a
    braking speed binds), and the nearer singularity block hid the limit from that rule. The
    stop began late, braked past its share, and the position guard braked joint 1 on its own:
    the tool slid 12.4 mm across the twist and turned 1.8° (4 ms). Now it plans that stop in
    time: within the jogging allowance, and it ends at rest inside the limit."""
    arm = rc.robots.iiwa7()
    q = np.array([2.548764587553665, 1.4052780105520966, 2.318118479818223, -1.3733245837062868,
                  2.020616675727101, -1.2917588236488537, 1.3836334139325799])
    xi = np.array([-0.13005983625173695, -0.02576764200158198, 0.06800715289929332, 0.0, 0.0, 0.0])
    run, cmd = _smoothed_qp_jog("iiwa7-limit-behind-boundary", arm, q, xi, dt, 2.0)
    off, turn = run.uncommanded()
    assert off <= 2e-3 and math.degrees(turn) <= 0.5, (off, math.degrees(turn))
    q = cmd.q_next
    assert np.max(np.abs(cmd.qd)) < 1e-9 and np.all(q <= arm.upper) and np.all(q >= arm.lower)


def test_a_smoothed_stop_that_ran_past_its_singularity_block_is_not_driven_back_along_the_lost_direction():
    """example-robot-data's UR10 (amax 8, jmax 80 added), smoothed, the QP, 4 ms, a 0.15 m/s
    twist into its boundary singularity that the look-ahead sees only from σ_min ≈ 0.1 at
    full speed: the stop comes late and runs on to σ_min ≈ 0.02, past its block. There, a
    motion back along the twist to end the stop at the whole jmax asks the joints for more
    than the filter's bounds (|J⁺ξ| grows like 1/σ_min): the tool went 5.6 mm across the
    twist. Past the block the stop is cut to rest, as before (1.6 mm)."""
    import os

    from . import servo_arms

    root = servo_arms.robots_dir()
    if root is None:
        pytest.skip("example-robot-data is not installed")
    arm = rc.Chain.from_urdf(os.path.join(root, servo_arms.URDF_FILES["ur10"][0]),
                             tip="tool0").with_limits(amax=8.0, jmax=80.0)
    q = np.array([2.5347830579194746, -1.8064855410967464, -0.6121271864187396, -1.9780937186235006,
                  1.4157736311094213, -4.378941242063196])
    xi = np.array([0.052221694942490675, -0.053660222900113644, 0.1271260611501704, 0.0, 0.0, 0.0])
    run, cmd = _smoothed_qp_jog("ur10-late-stop", arm, q, xi, 4e-3, 2.0)
    off, turn = run.uncommanded()
    assert off <= 2e-3 and math.degrees(turn) <= 0.5, (off, math.degrees(turn))
    assert cmd.status == "halted-singularity"
