"""The tasks stage computes its frame tasks' frames in one pass of the chain: the same
commands as each task computing its own frame, and a task that defines its own frame keeps it."""

import numpy as np

import ratectl as rc


class _Offset(rc.tasks.Position):
    """A Position whose frame is its link's frame moved 5 cm along base z (its own `frame`)."""

    def frame(self, chain, q):
        T, J = super().frame(chain, q)
        T = T.copy()
        T[2, 3] += 0.05
        return T, J


def _run(tasks, steps=50):
    ch = rc.robots.panda()
    q = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    ctrl = rc.ResolvedRateController(ch, tasks=tasks)
    out = []
    for _ in range(steps):
        cmd = ctrl.step(q, dt=1e-3)
        out.append(np.concatenate([cmd.qd, cmd.solve.residuals, cmd.solve.task_errors]))
        q = cmd.q_next
    return np.array(out)


class _OwnPose(rc.tasks.Pose):
    def frame(self, chain, q):  # the same frame, computed by the task itself
        return super().frame(chain, q)


class _OwnPosition(rc.tasks.Position):
    def frame(self, chain, q):
        return super().frame(chain, q)


class _OwnOrientation(rc.tasks.Orientation):
    def frame(self, chain, q):
        return super().frame(chain, q)


def _tasks(position=rc.tasks.Position, pose=rc.tasks.Pose, orientation=rc.tasks.Orientation):
    ch = rc.robots.panda()
    q = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    T = ch.fk(q)
    T[:3, 3] += [0.03, -0.02, 0.02]
    p4 = ch.fk(q, link="link4")[:3, 3] + [0.0, 0.1, 0.05]
    R6 = ch.fk(q, link="link6")
    return [pose(priority=0, target=T), position(link="link4", priority=1, target=p4, gain=2.0),
            orientation(link="link6", priority=1, target=R6, gain=1.0, weight=0.5),
            rc.tasks.Posture(q, priority=2, gain=1.0)]


def test_frames_in_one_pass_give_the_commands_of_one_frame_per_task():
    together = _run(_tasks())
    # tasks with a frame() of their own compute it themselves (no pass for several links)
    alone = _run(_tasks(_OwnPosition, _OwnPose, _OwnOrientation))
    assert np.array_equal(together, alone)


def test_a_task_with_its_own_frame_keeps_it():
    plain = _run(_tasks(), steps=5)
    moved = _run(_tasks(_Offset), steps=5)
    # the offset frame is 5 cm higher: the elbow task's error (and so the command) differs
    assert not np.allclose(plain[:, -3], moved[:, -3])
    tasks = _tasks(_Offset)
    ch = rc.robots.panda()
    q = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    ctrl = rc.ResolvedRateController(ch, tasks=tasks)
    cmd = ctrl.step(q, dt=1e-3)
    want = np.linalg.norm(tasks[1].target[:3, 3] - (ch.fk(q, link="link4")[:3, 3] + [0.0, 0.0, 0.05]))
    assert abs(cmd.solve.task_errors[1] - want) < 1e-12
