"""``benchmarks/breakdown_servo.py`` counts and times what it says it does.

The breakdown wraps module globals and stage objects by name: a renamed primitive or stage
would leave it counting nothing, and a wrapper that changed a command would time another
loop than the users'. These checks run a few hundred steps of its loop.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pytest

import ratectl as rc

pytest.importorskip("mink")
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
breakdown = pytest.importorskip("breakdown_servo")
from bench_controller import DT, Q0  # noqa: E402
from bench_servo import circle_targets  # noqa: E402

STEPS = 1500  # (the watch starts on bench_servo's circle after ~500 steps)
WRAPPED = (("thin_svd", breakdown._stage, "thin_svd"), ("dposv", breakdown._qp, "_dposv"),
           ("fk_jacobian", breakdown.Chain, "fk_jacobian"))  # (name, owner, attribute)


def test_the_counter_sees_every_primitive_of_a_servo_step_and_puts_them_back():
    arm = rc.robots.ur5e()
    originals = {name: getattr(obj, attr) for name, obj, attr in WRAPPED}
    ctrl = rc.ResolvedRateController(arm, solver=rc.solvers.QP())
    q = Q0.copy()
    with breakdown.Counter() as c:
        for T in circle_targets(arm, STEPS):
            q = ctrl.step(q, target=T, dt=DT).q_next
    n = c.snapshot()
    assert n["fk_jacobian"] == STEPS
    assert n["dposv"] >= STEPS  # the direction and the feedback, each a Cholesky solve
    assert n["thin_svd"] > 0 and n["svd_values"] >= n["thin_svd"] and n["jacobian"] > 0  # the watch ran
    for name, obj, attr in WRAPPED:
        assert getattr(obj, attr) is originals[name]


def test_the_stage_timer_times_every_stage_without_changing_a_command():
    arm = rc.robots.ur5e()
    plain = rc.ResolvedRateController(arm, solver=rc.solvers.QP())
    staged = rc.ResolvedRateController(rc.robots.ur5e(), solver=rc.solvers.QP())
    timer = breakdown.StageTimer(staged, time.perf_counter)
    q1 = q2 = Q0.copy()
    for T in circle_targets(arm, 300):
        c1 = plain.step(q1, target=T, dt=DT)
        c2 = staged.step(q2, target=T, dt=DT)
        assert np.array_equal(c1.qd, c2.qd) and c1.status == c2.status and c1.reason == c2.reason
        q1, q2 = c1.q_next, c2.q_next
    spent = timer.snapshot()
    assert set(spent) == set(breakdown.STAGES)
    assert all(v > 0.0 for v in spent.values()), spent
