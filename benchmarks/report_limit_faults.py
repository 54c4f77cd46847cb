"""Limits under faults: changing dt and measurement jumps next to a position limit.

Closed loops of ``ResolvedRateController`` on the built-in arms, a joint feed-forward
driving joints into their position limits (at random speeds up to vmax, either sign),
for every solver family (default adaptive DLS, DLS, QP; smoothing off and on):

* **dt changes**: every period is drawn at random from 0.1–10 ms (log-uniform, a new
  value every 1–5 periods). Reported: the worst |Δq̇/dt|/amax of the commanded stream
  (finite difference with the actual dt of each period), the worst |q̇|/vmax, the
  worst excursion of ``q_next`` beyond a position limit [rad] and the number of cycles
  with status ``limit-recovery`` (a fault recovery: must be 0 without faults).
* **measurement jumps**: the same loop at a fixed dt; at random cycles the measured q of
  one joint jumps 0.001–0.02 rad (toward its nearest limit, sometimes beyond it)
  relative to the last command's integral. Reported: the worst excursion of ``q_next``
  beyond a limit that the jump itself did not cause (a joint measured beyond its limit
  must be commanded back or held, never further out), the worst |q̈|/amax on the cycles
  after the jump cycles (the recovery takes one period), and the statuses seen on the
  jump cycles.

Run:  python benchmarks/report_limit_faults.py [--runs N] [--steps N] [--seed S]
"""

from __future__ import annotations

import argparse
import collections

import numpy as np

import ratectl as rc

ARMS = ("ur5e", "panda", "puma560", "iiwa7")
SOLVERS = {
    "adaptive-dls": lambda: rc.solvers.AdaptiveDLS(),
    "dls": lambda: rc.solvers.DLS(damping=0.02),
    "qp": lambda: rc.solvers.QP(),
}


def _start(arm, rng):
    """A start near the limits: every joint within 0.1 rad of one of them, the feed-forward
    pointing into that limit."""
    lo, hi = arm.lower, arm.upper
    side = rng.choice([-1.0, 1.0], arm.dof)
    room = rng.uniform(0.01, 0.1, arm.dof)
    q = np.where(side > 0, hi - room, lo + room)
    ff = side * rng.uniform(0.2, 1.0, arm.dof) * arm.vmax
    return q, ff


def dt_change_run(arm, solver, smoothing, rng, steps):
    """(worst |q̈|/amax, worst |q̇|/vmax, worst excursion [rad], limit-recovery cycles) of one run
    with random dts."""
    ctrl = rc.ResolvedRateController(arm, solver=SOLVERS[solver](), smoothing=smoothing)
    q, ff = _start(arm, rng)
    qd_prev = np.zeros(arm.dof)
    wa = wv = wq = 0.0
    recoveries = 0
    dt, hold = 1e-3, 0
    for _ in range(steps):
        if hold == 0:
            dt, hold = float(10.0 ** rng.uniform(-4, -2)), int(rng.integers(1, 6))
        hold -= 1
        cmd = ctrl.step(q, qd_ff=ff, dt=dt)
        qd = np.asarray(cmd.qd)
        wa = max(wa, float(np.max(np.abs(qd - qd_prev) / (arm.amax * dt))))
        wv = max(wv, float(np.max(np.abs(qd) / arm.vmax)))
        q = np.asarray(cmd.q_next)
        wq = max(wq, float(np.max(np.maximum(q - arm.upper, arm.lower - q))))
        qd_prev = qd
        recoveries += "limit-recovery" in cmd.flags
    return wa, wv, wq, recoveries


def jump_run(arm, solver, smoothing, rng, steps, statuses):
    """(worst excursion beyond a limit not caused by the jump itself, worst |q̈|/amax on the
    cycles that are not jump cycles); the statuses of the jump cycles are added to
    ``statuses``."""
    ctrl = rc.ResolvedRateController(arm, solver=SOLVERS[solver](), smoothing=smoothing)
    q, ff = _start(arm, rng)
    dt = float(rng.choice([1e-3, 4e-3]))
    wq = wa = 0.0
    qd_prev = np.zeros(arm.dof)
    for _ in range(steps):
        meas = q.copy()
        if rng.random() < 0.05:
            j = int(rng.integers(arm.dof))
            to_hi = (arm.upper[j] - q[j]) < (q[j] - arm.lower[j])
            meas[j] += (1.0 if to_hi else -1.0) * float(rng.uniform(1e-3, 2e-2))
            jumped = True
        else:
            jumped = False
        cmd = ctrl.step(meas, qd_ff=ff, dt=dt)
        qd = np.asarray(cmd.qd)
        if jumped:
            statuses[cmd.status] += 1
        else:
            wa = max(wa, float(np.max(np.abs(qd - qd_prev) / (arm.amax * dt))))
        qd_prev = qd
        qn = np.asarray(cmd.q_next)
        # beyond a limit by more than the measurement already was: commanded further out
        over_hi = qn - np.maximum(arm.upper, meas)
        over_lo = np.minimum(arm.lower, meas) - qn
        wq = max(wq, float(np.max(np.maximum(over_hi, over_lo))))
        q = qn
    return wq, wa


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=6, help="runs per arm, solver and smoothing setting")
    ap.add_argument("--steps", type=int, default=800)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    print(f"{'solver':13s} {'smoothing':9s} {'runs':>4s} {'dt: |qdd|/amax':>15s} {'|qd|/vmax':>9s} "
          f"{'beyond rad':>10s} {'recoveries':>10s} {'jump: beyond rad':>16s} {'|qdd|/amax':>10s}"
          "  jump-cycle statuses")
    for solver in SOLVERS:
        for smoothing in (False, True):
            wa = wv = wq = wj = wja = 0.0
            rec = 0
            statuses: collections.Counter = collections.Counter()
            runs = 0
            for name in ARMS:
                arm = rc.robots.BUILTIN[name]()
                for _ in range(args.runs):
                    a, v, x, r = dt_change_run(arm, solver, smoothing, rng, args.steps)
                    wa, wv, wq, rec = max(wa, a), max(wv, v), max(wq, x), rec + r
                    jx, ja = jump_run(arm, solver, smoothing, rng, args.steps, statuses)
                    wj, wja = max(wj, jx), max(wja, ja)
                    runs += 1
            st = ", ".join(f"{k} {v}" for k, v in statuses.most_common())
            print(f"{solver:13s} {str(smoothing):9s} {runs:4d} {wa:15.9f} {wv:9.6f} {wq:10.2e} {rec:10d} "
                  f"{wj:16.2e} {wja:10.3f}  {st}")


if __name__ == "__main__":
    main()
