"""Separate controllers and solvers in separate threads give exactly the serial answers.

What is shared here: the chain (immutable; its compiled kernels are pure functions, batched
calls use per-thread buffers). What is not: each thread owns its controller and its solver
(both keep state between calls: the previous command, the smoothing filter, a warm QP).
"""

import threading

import numpy as np
import pytest

import ratectl as rc

STEPS = 150
DT = 2e-3


def _loop(chain, make_controller, q0, target):
    ctrl = make_controller(chain)
    q = q0.copy()
    out = []
    for _ in range(STEPS):
        cmd = ctrl.step(q, target=target, dt=DT)
        out.append(cmd.qd.copy())
        q = np.array(cmd.q_next)
    return np.array(out)


CONTROLLERS = {
    "adaptive-dls": lambda c: rc.ResolvedRateController(c),
    "qp": lambda c: rc.ResolvedRateController(c, solver=rc.solvers.QP()),
    "smoothed": lambda c: rc.ResolvedRateController(c, smoothing=True),
}


@pytest.mark.parametrize("name", list(CONTROLLERS))
def test_controllers_in_threads_equal_the_serial_runs(name):
    arm = rc.robots.ur5e()
    rng = np.random.default_rng(7)
    starts = [np.array([0.3, -1.3, 1.6, -1.9, -1.2, 0.2]) + rng.uniform(-0.1, 0.1, 6) for _ in range(4)]
    targets = []
    for q in starts:
        T = arm.fk(q)
        T[:3, 3] += rng.uniform(-0.03, 0.03, 3)
        targets.append(T)
    serial = [_loop(arm, CONTROLLERS[name], q, T) for q, T in zip(starts, targets, strict=True)]
    results: list = [None] * len(starts)
    errors: list = []

    def work(k):
        try:
            results[k] = _loop(arm, CONTROLLERS[name], starts[k], targets[k])
        except Exception as exc:  # noqa: BLE001 - reported by the assertion below
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(k,)) for k in range(len(starts))]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    assert not errors, errors
    for k in range(len(starts)):
        np.testing.assert_array_equal(results[k], serial[k])


def test_batched_kinematics_in_threads_equal_the_serial_answers():
    arm = rc.robots.iiwa7()
    qs = [arm.random_q(20000, rng=k) for k in range(4)]
    serial = [arm.fk_jacobian(q) for q in qs]
    out: list = [None] * len(qs)

    def work(k):
        out[k] = arm.fk_jacobian(qs[k])

    threads = [threading.Thread(target=work, args=(k,)) for k in range(len(qs))]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    for k in range(len(qs)):
        np.testing.assert_array_equal(out[k][0], serial[k][0])
        np.testing.assert_array_equal(out[k][1], serial[k][1])
