"""Servo conformance report: step targets on every arm, worst overshoot and settling time.

For every built-in arm and the URDF arms of ``tests/conformance`` (no acceleration
limits in their files), runs the user's loop ``cmd = ctrl.step(q, target=T, dt=dt);
q = cmd.q_next`` from random regular starts to step targets of 1–20 cm in random
directions with turns up to 30°, with smoothing off and on (URDF arms get amax/jmax via
``Chain.with_limits`` for smoothing), at dt = 1 ms and 4 ms, for 4 s each, and prints per
arm and smoothing setting: the worst overshoot along the step [mm] (and in % of the
step), the worst settling time to 0.1 mm / 0.01° [s], the largest |q̇|/vmax and |q̈|/amax,
and the number of runs that fail the acceptance (settled within 4 s; overshoot ≤ 1 % of
the step + 0.1 mm; |q̇| ≤ vmax; |q̈| ≤ amax; q inside its range).

Run:  python benchmarks/report_servo.py [--cases N] [--arms NAME ...] [--dt 0.001 0.004]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "conformance"))

import harness  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=6, help="step targets per arm")
    ap.add_argument("--arms", nargs="*", default=None, help="arm names (default: all)")
    ap.add_argument("--dt", nargs="*", type=float, default=[1e-3, 4e-3])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--verbose", action="store_true", help="print every failing run")
    args = ap.parse_args()
    arms = harness.all_arms()
    names = args.arms or list(arms)
    print(f"{'arm':24s} {'smoothing':9s} {'runs':>4s} {'fail':>4s} {'overshoot mm':>13s} {'% step':>7s} "
          f"{'settle s':>9s} {'|qd|/vmax':>9s} {'|qdd|/amax':>10s}")
    t0 = time.perf_counter()
    total = fails = 0
    for name in names:
        chain = arms[name]()
        cases = harness.make_cases(name, chain, args.cases, seed=args.seed)
        for smoothing in (False, True):
            ch = harness.smoothing_limits(chain) if smoothing else chain
            worst_os = worst_pct = worst_settle = vr = ar = 0.0
            nfail = 0
            runs = 0
            for case in cases:
                for dt in args.dt:
                    out = harness.run_case(ch, case, smoothing=smoothing, dt=dt)
                    runs += 1
                    worst_os = max(worst_os, out.overshoot)
                    worst_pct = max(worst_pct, 100.0 * out.overshoot / case.step)
                    worst_settle = max(worst_settle, out.settle)
                    vr = max(vr, out.vratio)
                    ar = max(ar, out.aratio) if not math.isnan(out.aratio) else ar
                    if not out.ok(case.step):
                        nfail += 1
                        if args.verbose:
                            print(f"   FAIL {name} smoothing={smoothing} dt={dt} step={case.step:.3f} "
                                  f"turn={math.degrees(case.turn):.1f}° {out}")
            total += runs
            fails += nfail
            a_txt = f"{ar:10.3f}" if ar > 0 else f"{'(none)':>10s}"
            print(f"{name:24s} {str(smoothing):9s} {runs:4d} {nfail:4d} {worst_os * 1e3:13.4f} "
                  f"{worst_pct:7.3f} {worst_settle:9.3f} {vr:9.3f} {a_txt}", flush=True)
    print(f"{total} runs, {fails} failing, {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
