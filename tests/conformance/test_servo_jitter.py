"""The smoothed servo with a jittered period: ``dt_k = dt·U(0.5, 1.5)`` passed to ``step``
every cycle, ``q = cmd.q_next``, on the xArm7 of ``example-robot-data`` (step targets of the
straight-approach sweep, `servo_sweep.make_cases`). Overshoot along the step within 1 % of
the step + 0.1 mm, the target reached within 4 s, |q̇| ≤ vmax."""

from __future__ import annotations

import numpy as np
import pytest

import ratectl as rc

from . import servo_arms, servo_sweep


@pytest.mark.parametrize("seed", [0, 1])
def test_a_smoothed_step_with_a_jittered_period_does_not_overshoot(seed):
    if servo_arms.robots_dir() is None:
        pytest.skip("example-robot-data is not installed")
    chain = servo_arms.urdf_arm("xarm7")
    dt = 4e-3
    for case in servo_sweep.make_cases("erd:xarm7", chain, steps=2, turns=0, seed=0):
        rng = np.random.default_rng(seed)
        ctrl = rc.ResolvedRateController(chain, smoothing=True)
        q, T = case.q0.copy(), case.target
        p0 = chain.fk(q)[:3, 3]
        u = (T[:3, 3] - p0) / case.step
        along, t, reached, vr = 0.0, 0.0, False, 0.0
        while t < servo_sweep.DURATION and not reached:
            h = dt * float(rng.uniform(0.5, 1.5))
            cmd = ctrl.step(q, target=T, dt=h)
            vr = max(vr, float(np.max(np.abs(cmd.qd) / chain.vmax)))
            q = np.array(cmd.q_next)
            t += h
            along = max(along, float((chain.fk(q)[:3, 3] - p0) @ u))
            reached = cmd.status == "target-reached"
        over = along - case.step
        assert over <= servo_sweep.overshoot_allowed(case.step), (
            f"{case.label}: {over * 1e3:.3f} mm past the target "
            f"(allowed {servo_sweep.overshoot_allowed(case.step) * 1e3:.3f} mm)")
        assert reached, f"{case.label}: not reached in {servo_sweep.DURATION:g} s ({cmd.status!r})"
        assert vr <= 1.0 + 1e-9
