"""The tasks stage follows every change of a task's place in its levels — a priority or a
weight set between cycles, a first target, a posture's new reference — as a stage built
with the tasks in their new state would."""

import numpy as np
import pytest

import ratectl as rc
from ratectl.control.tasks_stage import TasksStage


def _tasks(ch, q):
    tool = rc.tasks.Pose(target=ch.fk(q) @ _shift(0.02))
    post = rc.tasks.Posture(q + 0.2, priority=1, gain=2.0)
    return tool, post


def _shift(d):
    T = np.eye(4)
    T[:3, 3] = d
    return T


def _same(a, b):
    assert a.qd.tolist() == b.qd.tolist()
    assert a.priorities == b.priorities
    assert a.residuals.tolist() == b.residuals.tolist()
    assert a.task_errors.tolist() == b.task_errors.tolist()


@pytest.mark.parametrize("change", ["priority", "weight", "both"])
def test_a_priority_or_weight_set_between_cycles_is_solved_as_a_new_stage_would(change):
    ch = rc.robots.panda()
    q = 0.5 * (ch.qlim[:, 0] + ch.qlim[:, 1])
    tool, post = _tasks(ch, q)
    stage = TasksStage(ch, [tool, post])
    before = stage.solve(q, dt=1e-3, qd_prev=None, limits=ch)
    assert before.priorities == (0, 1)
    if change in ("priority", "both"):
        post.priority = 0
    if change in ("weight", "both"):
        post.weight = 0.25
    after = stage.solve(q, dt=1e-3, qd_prev=None, limits=ch)
    fresh = TasksStage(ch, _tasks(ch, q))
    t2, p2 = fresh.tasks
    p2.priority, p2.weight = post.priority, post.weight
    _same(after, fresh.solve(q, dt=1e-3, qd_prev=None, limits=ch))
    # (the change shows: another answer, or the level's residual scaled by √weight)
    assert (after.qd.tolist(), after.residuals.tolist()) != (before.qd.tolist(), before.residuals.tolist())


@pytest.mark.parametrize("late", ["posture", "position"])
def test_a_task_that_gains_its_target_joins_its_level(late):
    ch = rc.robots.panda()
    q = 0.5 * (ch.qlim[:, 0] + ch.qlim[:, 1])
    p4 = ch.fk(q, link="link4")[:3, 3] + 0.05

    def tasks(with_target):
        tool = rc.tasks.Pose(target=ch.fk(q) @ _shift(0.02))
        if late == "posture":
            t = rc.tasks.Posture(q + 0.2 if with_target else None, priority=1, gain=2.0)
        else:
            t = rc.tasks.Position(link="link4", priority=1, target=p4 if with_target else None)
        return tool, t

    tool, t = tasks(False)
    stage = TasksStage(ch, [tool, t])
    assert stage.solve(q, dt=1e-3, qd_prev=None, limits=ch).priorities == (0,)
    t.set_target(q + 0.2 if late == "posture" else p4)
    res = stage.solve(q, dt=1e-3, qd_prev=None, limits=ch)
    assert res.priorities == (0, 1)
    _same(res, TasksStage(ch, tasks(True)).solve(q, dt=1e-3, qd_prev=None, limits=ch))


def test_a_posture_reference_of_the_wrong_size_is_refused_at_the_next_cycle():
    ch = rc.robots.panda()
    q = 0.5 * (ch.qlim[:, 0] + ch.qlim[:, 1])
    tool, post = _tasks(ch, q)
    ctrl = rc.ResolvedRateController(ch, tasks=[tool, post])
    assert ctrl.step(q, dt=1e-3).status != "halted"
    post.set_target(np.zeros(6))
    cmd = ctrl.step(q, dt=1e-3)
    assert cmd.status == "halted" and "q_ref has 6 values" in cmd.reason


@pytest.mark.parametrize(("name", "value"), [("priority", -1), ("priority", 1.5), ("priority", True),
                                             ("weight", 0.0), ("weight", float("nan"))])
def test_a_priority_or_weight_out_of_range_is_refused_when_set(name, value):
    task = rc.tasks.Posture(np.zeros(7))
    with pytest.raises(rc.errors.InputError, match=name):
        setattr(task, name, value)
    assert (task.priority, task.weight) == (0, 1.0)


def test_the_period_row_is_dt_for_every_joint_and_follows_dt():
    ch = rc.robots.panda()
    stage = TasksStage(ch, [rc.tasks.Posture(np.zeros(7))])
    p = stage.period(1e-3)
    assert p.tolist() == [1e-3] * 7 and not p.flags.writeable
    assert stage.period(1e-3) is p
    assert stage.period(2e-3).tolist() == [2e-3] * 7


def test_a_tasks_cycle_commands_q_plus_qd_dt_and_its_acceleration():
    ch = rc.robots.panda()
    q = 0.5 * (ch.qlim[:, 0] + ch.qlim[:, 1])
    tool, post = _tasks(ch, q)
    ctrl = rc.ResolvedRateController(ch, tasks=[tool, post])
    prev = np.zeros(7)
    for dt in (1e-3, 1e-3, 4e-3):
        cmd = ctrl.step(q, dt=dt)
        assert cmd.q_next.tolist() == [a + v * dt for a, v in zip(q.tolist(), cmd.qd.tolist(), strict=True)]
        assert cmd.qdd.tolist() == [(v - p) / dt for v, p in zip(cmd.qd.tolist(), prev.tolist(), strict=True)]
        prev = cmd.qd
        q = cmd.q_next
