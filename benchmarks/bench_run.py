"""Benchmark: the real-time loop's own overhead per period (``rc.run`` on the scripted arm).

``rc.run`` drives a Panda (ScriptedDriver: a kinematic arm, no network) at 1 kHz along a
line and with a twist stream. Each cycle's work is split into the driver's ``read()`` and
``command()``, the controller's ``step`` (timed by a wrapper) and the rest — the loop's own
code: stamp and watchdog bookkeeping, the reference (path pose and twist), the recording,
the deadline arithmetic. That rest is the overhead a driver loop adds to a bare
``controller.step``. Also printed: the loop periods (sleep accuracy) and the cost of
building the record after the run.

Then ``follow`` against ``rc.run`` on the demo's UR5e wrist line (0.01 rad from the wrist
singularity): the path error, the limit ratios (|q̇|/vmax; |q̈|/amax over the robot's own
periods) and the duration, on the scripted arm and on the MuJoCo driver, governed (the
default) and on the path's time law.

Run:  python benchmarks/bench_run.py [--seconds S] [--rate HZ] [--skip-overhead]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

import ratectl as rc
from ratectl.drivers import ScriptedDriver

sys.path.insert(0, os.path.dirname(__file__))
from _timing import median_us  # noqa: E402


class TimedController(rc.ResolvedRateController):
    """The default controller, with the time of every step recorded."""

    def __init__(self, chain) -> None:
        super().__init__(chain)
        self.times: list[float] = []

    def step(self, q, **kw):
        t0 = time.perf_counter()
        cmd = super().step(q, **kw)
        self.times.append(time.perf_counter() - t0)
        return cmd


def one(arm, q0, mode: str, seconds: float, rate: float) -> dict:
    drv = ScriptedDriver(arm, q0)
    ctrl = TimedController(arm)
    T0 = arm.fk(q0)
    t_build = time.perf_counter()
    if mode == "path":
        T1 = T0.copy()
        T1[:3, 3] += [0.0, 0.1 * seconds, 0.0]
        ex = rc.run(drv, path=rc.paths.Line(T0, T1, speed=0.1, acceleration=10.0), controller=ctrl,
                    rate_hz=rate, settle=0.0)
    else:
        v = np.array([0.0, 0.02, 0.0, 0.0, 0.0, 0.0])
        ex = rc.run(drv, twist=lambda t: v, controller=ctrl, rate_hz=rate, duration=seconds)
    total = time.perf_counter() - t_build
    tm = ex.info["timing"]
    step = np.array(ctrl.times[1:])  # the first step is the warm-up before the loop
    k = min(len(step), len(tm["work"]))
    fresh = ex.fresh[:k]
    overhead = (tm["work"][:k] - tm["read"][:k] - tm["command"][:k] - step[:k])[fresh]
    loop_time = float(np.sum(ex.periods[1:]))
    return {
        "mode": mode, "cycles": len(ex.t), "rate": ex.achieved_rate_hz, "overruns": ex.overruns,
        "overhead": overhead, "step": step, "read": tm["read"], "command": tm["command"],
        "period_p50": ex.period_p50, "period_p99": ex.period_p99, "period_max": ex.period_max,
        "record": total - loop_time, "completed": ex.completed,
    }


def _row(name: str, ex, amax: np.ndarray, dt: float | None = None) -> str:
    t = ex.t
    gaps = np.diff(t) if dt is None else np.full(len(t) - 1, dt)
    acc = float(np.max(np.abs(np.diff(ex.qd, axis=0)) / gaps[:, None] / amax))
    return (f"| {name} | {'yes' if ex.completed else 'no'} | {ex.max_position_error * 1e3:.4f} | "
            f"{math.degrees(ex.max_orientation_error):.4f} | {ex.velocity_ratio:.3f} | {acc:.3f} | "
            f"{ex.duration:.3f} |")


def compare(rate: float) -> None:
    """follow against rc.run on the demo wrist line, scripted and MuJoCo drivers."""
    from ratectl.cli import demo

    sc = demo.wrist_line("ur5e")
    arm, line, q0 = sc.chain, sc.path, sc.q0
    print(f"\nfollow vs rc.run: the demo's UR5e wrist line ({line.length:.2f} m, closest |q5| = "
          f"{sc.min_q5:.3f} rad), {rate:g} Hz\n")
    print("| how | completed | path error [mm] | orientation error [°] | max \\|q̇\\|/vmax "
          "| max \\|q̈\\|/amax (real periods) | duration [s] |")
    print("|---|---|---|---|---|---|---|")
    f = rc.follow(arm, line, q0, dt=1.0 / rate)
    print(_row("rc.follow (governor)", f, arm.amax, dt=1.0 / rate))
    for gov in (True, False):
        ex = rc.run(ScriptedDriver(arm, q0), path=line, rate_hz=rate, governor=gov)
        print(_row(f"rc.run, scripted ({'governor' if gov else 'time law'})", ex, arm.amax)
              + f" ×{ex.duration / f.duration:.2f} of follow; longest period {ex.period_max * 1e3:.1f} ms; "
              f"{ex.message[:60]}")
    try:
        from ratectl.interop.mujoco import MujocoDriver
    except ImportError:
        print("(MuJoCo not installed: no MuJoCo rows)")
        return
    for gov in (True, False):
        drv = MujocoDriver(arm, q0=q0, period=1.0 / rate)
        ex = rc.run(drv, path=line, rate_hz=rate, governor=gov)
        print(_row(f"rc.run, MuJoCo position servos ({'governor' if gov else 'time law'})", ex, arm.amax)
              + f" ×{ex.duration / f.duration:.2f} of follow")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=3.0)
    ap.add_argument("--rate", type=float, default=1000.0)
    ap.add_argument("--compare-rate", type=float, default=500.0, help="rate of the follow/run comparison")
    ap.add_argument("--skip-overhead", action="store_true", help="only the follow/run comparison")
    args = ap.parse_args()
    if args.skip_overhead:
        compare(args.compare_rate)
        return
    arm = rc.robots.panda()
    q0 = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
    ur5e, qr = rc.robots.ur5e(), np.array([0.1, -1.2, 1.4, -1.6, 0.3, 0.2])
    ref = median_us(lambda: ur5e.fk_jacobian(qr), number=500, repeat=7)
    print(f"machine speed reference: UR5e fk_jacobian {ref:.2f} µs per call (see docs/benchmarks.md)")
    print(f"rc.run on ScriptedDriver(panda) at {args.rate:g} Hz for ~{args.seconds:g} s per mode\n")
    print(f"{'mode':6} {'cycles':>7} {'rate Hz':>8} {'overruns':>8} | {'loop overhead µs':>18} | "
          f"{'ctrl.step µs':>14} | {'read µs':>7} {'cmd µs':>7} | {'period ms p50/p99/max':>22} | record ms")
    for mode in ("path", "twist"):
        r = one(arm, q0, mode, args.seconds, args.rate)

        def med(a):
            return float(np.median(a)) * 1e6

        def p99(a):
            return float(np.quantile(a, 0.99)) * 1e6

        print(f"{r['mode']:6} {r['cycles']:7d} {r['rate']:8.1f} {r['overruns']:8d} | "
              f"{med(r['overhead']):7.1f} / p99 {p99(r['overhead']):6.1f} | "
              f"{med(r['step']):5.1f} / {p99(r['step']):6.1f} | "
              f"{med(r['read']):7.1f} {med(r['command']):7.1f} | "
              f"{r['period_p50'] * 1e3:6.3f} {r['period_p99'] * 1e3:6.3f} {r['period_max'] * 1e3:7.3f} | "
              f"{r['record'] * 1e3:7.1f}")
    print("\nloop overhead = cycle work − driver.read − driver.command − controller.step (fresh cycles): "
          "the stamp/watchdog bookkeeping, the reference, the recording and the deadline arithmetic.")
    compare(args.compare_rate)


if __name__ == "__main__":
    main()
