"""Benchmark: cost of ``ResolvedRateController.step`` in a 1 kHz user loop (UR5e).

The loop tracks a moving target (a 5 cm circle at 0.2 m/s) with feed-forward twist and
feedback, exactly as a user's control loop would, and times each ``step`` call:
default solver (AdaptiveDLS) with and without Ruckig smoothing, plus the fixed-λ DLS and
the exact inverse for reference. Also times the governor's planning of the demo's line
(``ratectl.cli.demo.wrist_line``: UR5e, past the wrist singularity) and a whole ``follow`` run.

Run:  python benchmarks/bench_controller.py [--steps N]
Prints median / 90th-percentile µs per step. Target: ≤ 60 µs median with smoothing.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

import ratectl as rc


def loop(ctrl, arm, q0, steps: int, dt: float = 1e-3):
    T0 = arm.fk(q0)
    r, w = 0.05, 0.2 / 0.05  # circle radius [m], angular rate [rad/s]
    q = q0.copy()
    times = np.empty(steps)
    statuses = {}
    clock = time.perf_counter
    for k in range(steps):
        t = k * dt
        target = T0.copy()
        target[0, 3] += r * (math.cos(w * t) - 1.0)
        target[1, 3] += r * math.sin(w * t)
        twist = np.array([-r * w * math.sin(w * t), r * w * math.cos(w * t), 0.0, 0.0, 0.0, 0.0])
        t0 = clock()
        cmd = ctrl.step(q, target=target, twist=twist, dt=dt)
        times[k] = clock() - t0
        statuses[cmd.status] = statuses.get(cmd.status, 0) + 1
        q = cmd.q_next
    return times * 1e6, statuses


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=5000)
    args = ap.parse_args()
    arm = rc.robots.ur5e()
    q0 = np.array([0.0, -1.2, 1.4, -1.8, -1.2, 0.3])
    T, J = arm.fk_jacobian(q0)
    n = 20000
    t0 = time.perf_counter()
    for _ in range(n):
        arm.fk_jacobian(q0)
    fkj = (time.perf_counter() - t0) / n * 1e6
    print(f"UR5e fk_jacobian: {fkj:.2f} µs per call (reference)")
    print(f"controller.step, 1 kHz loop, {args.steps} steps (median / p90 µs):")
    cases = [
        ("default (AdaptiveDLS), no smoothing", dict()),
        ("default (AdaptiveDLS) + Ruckig smoothing", dict(smoothing=True)),
        ("DLS λ=0.05 + Ruckig smoothing", dict(solver=rc.solvers.DLS(damping=0.05), smoothing=True)),
        ("exact inverse, no smoothing", dict(solver=rc.solvers.Inverse())),
    ]
    for name, kw in cases:
        ctrl = rc.ResolvedRateController(arm, **kw)
        loop(ctrl, arm, q0, 500)  # warm-up
        ctrl.reset()
        us, st = loop(ctrl, arm, q0, args.steps)
        print(f"  {name:45s} {np.median(us):7.1f} / {np.percentile(us, 90):7.1f}   statuses {st}")

    # governor planning and a whole follow run on the demo's line past the wrist singularity
    from ratectl.cli.demo import wrist_line
    from ratectl.planning import Governor

    scenario = wrist_line("ur5e")
    line, qs = scenario.path, scenario.q0
    t0 = time.perf_counter()
    plan = Governor().plan(arm, line, qs, dt=2e-3)
    tp = time.perf_counter() - t0
    print(f"governor plan, UR5e demo line (0.3 m past |q5| = 0.01 rad, dt 2 ms): {tp * 1e3:.0f} ms, "
          f"{plan.info['grid_points']} path points, motion {plan.duration:.2f} s "
          f"(nominal {plan.nominal_duration:.2f} s)")
    t0 = time.perf_counter()
    run = rc.follow(arm, line, qs, dt=2e-3)
    tf = time.perf_counter() - t0
    print(f"follow (plan + {run.steps} controller steps + error evaluation): {tf * 1e3:.0f} ms; "
          f"max path error {run.max_position_error * 1e3:.2g} mm")


if __name__ == "__main__":
    main()
