"""Benchmark: the servo to a moving target (UR5e), per-cycle cost beside mink + daqp.

The loop users run in a perception or teleoperation loop: a target pose that moves every
cycle, ``cmd = ctrl.step(q, target=T_t, dt=1 ms); q = cmd.q_next``. The target runs on the
5 cm circle at 0.2 m/s of ``benchmarks/bench_controller.py`` (its orientation fixed), starting
at the tool, so ratectl and mink chase the same moving pose. Every call is timed with the
garbage collector enabled: p50 / p99 [µs], p99/p50, and the median distance from the moving
target (a cheap call that does not track is no win). Cases: the QP solver and the default
solver (AdaptiveDLS), with and without Ruckig smoothing, and, for reference, the twist-fed
loop of ``bench_controller.py`` (QP and default). Beside them, in the same process and in
alternating rounds, mink on the same arm (``bench_controller.MinkLoop``: ``to_mjcf``, a
``FrameTask``, ``ConfigurationLimit`` + ``VelocityLimit``): ``Configuration.update(q)`` +
``solve_ik`` with daqp, the ``FrameTask`` target set to T_t before the timed call (as in
``bench_controller.py``), q += v·dt. The ratio QP target step / mink is taken per round.

Run:  python benchmarks/bench_servo.py [--steps N] [--rounds R] [--clock wall|cpu]
                                       [--markdown | --update-docs]

``--update-docs`` writes the table into docs/benchmarks.md between the ``bench_servo.py
--update-docs`` markers. Goals (issue #21): the QP target step ≤ 0.5 × mink + daqp per
cycle, and its p99 ≤ 2 × its median.
"""

from __future__ import annotations

import argparse
import gc
import math
import os
import statistics
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from _timing import CLOCKS, machine, update_docs  # noqa: E402
from bench_controller import DT, Q0, RADIUS, SPEED, GcCounter, MinkLoop, _version, ratectl_loop, stats  # noqa: E402

import ratectl as rc  # noqa: E402


def circle_targets(arm, steps: int) -> list[np.ndarray]:
    """The moving target T_t, t = k·dt: the tool pose at Q0 moved along the circle of radius
    RADIUS at SPEED (through the start point, in the base x-y plane), orientation fixed."""
    T0 = arm.fk(Q0)
    w = SPEED / RADIUS
    centre = T0[:3, 3] - np.array([RADIUS, 0.0, 0.0])
    out = []
    for k in range(steps):
        t = k * DT
        T = T0.copy()
        T[:3, 3] = centre + RADIUS * np.array([math.cos(w * t), math.sin(w * t), 0.0])
        out.append(T)
    return out


def ratectl_target_loop(ctrl, targets, clock) -> tuple[np.ndarray, list[int], dict, float]:
    """Per-call times [µs] of ``ctrl.step(q, target=T_t, dt)``, the gc counts, the statuses
    and the median distance of the tool from the moving target [m]."""
    ctrl.reset()
    q = Q0.copy()
    n = len(targets)
    times = np.empty(n)
    err = np.empty(n)
    statuses: dict[str, int] = {}
    step = ctrl.step
    with GcCounter() as gcc:
        for k in range(n):
            T = targets[k]
            t0 = clock()
            cmd = step(q, target=T, dt=DT)
            times[k] = clock() - t0
            statuses[cmd.status] = statuses.get(cmd.status, 0) + 1
            err[k] = cmd.position_error
            q = cmd.q_next
    return times * 1e6, gcc.counts, statuses, float(np.median(err))


def mink_target_loop(peer: MinkLoop, targets, clock) -> tuple[np.ndarray, list[int], float]:
    """mink chasing the same targets: ``update(q)`` + ``solve_ik`` (daqp) timed."""
    mink, conf, task = peer.mink, peer.conf, peer.task
    q = Q0.copy()
    n = len(targets)
    times = np.empty(n)
    err = np.empty(n)
    with GcCounter() as gcc:
        for k in range(n):
            task.set_target(mink.SE3.from_matrix(targets[k]))
            t0 = clock()
            conf.update(q)
            v = mink.solve_ik(conf, [task], DT, "daqp", damping=1e-3, limits=peer.limits)
            times[k] = clock() - t0
            err[k] = np.linalg.norm(peer.arm.fk(q)[:3, 3] - targets[k][:3, 3])
            q = q + v * DT
    return times * 1e6, gcc.counts, float(np.median(err))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=3000, help="calls per loop (default 3000)")
    ap.add_argument("--rounds", type=int, default=5, help="alternating rounds (default 5)")
    ap.add_argument("--clock", choices=("wall", "cpu"), default="cpu",
                    help="cpu: this thread's CPU time (default; leaves out preemption on a "
                         "shared machine); wall: elapsed time per call")
    ap.add_argument("--markdown", action="store_true", help="print the table as markdown")
    ap.add_argument("--update-docs", action="store_true",
                    help="write the table into docs/benchmarks.md (implies --markdown)")
    args = ap.parse_args(argv)
    clock = CLOCKS[args.clock]
    arm = rc.robots.ur5e()
    targets = circle_targets(arm, args.steps)
    target_cases = [
        ("target, QP", dict(solver=rc.solvers.QP())),
        ("target, QP + Ruckig smoothing", dict(solver=rc.solvers.QP(), smoothing=True)),
        ("target, default (AdaptiveDLS)", dict()),
        ("target, default + Ruckig smoothing", dict(smoothing=True)),
    ]
    twist_cases = [
        ("twist (reference), QP", dict(solver=rc.solvers.QP())),
        ("twist (reference), default (AdaptiveDLS)", dict()),
    ]
    tctrls = [rc.ResolvedRateController(arm, **kw) for _, kw in target_cases]
    wctrls = [rc.ResolvedRateController(arm, **kw) for _, kw in twist_cases]
    try:
        peer: MinkLoop | None = MinkLoop(arm)
    except ImportError:
        peer = None
        print("mink or mujoco not installed: no ratio")
    for c in tctrls:  # warm-up
        ratectl_target_loop(c, targets[:300], clock)
    for c in wctrls:
        ratectl_loop(c, 300, clock)
    if peer is not None:
        mink_target_loop(peer, targets[:300], clock)
        peer.run(300, clock)
    trounds: list[list] = [[] for _ in tctrls]
    wrounds: list[list] = [[] for _ in wctrls]
    prounds: list = []
    ptw: list = []
    for _ in range(args.rounds):
        for i, c in enumerate(tctrls):
            trounds[i].append(ratectl_target_loop(c, targets, clock))
        for i, c in enumerate(wctrls):
            wrounds[i].append(ratectl_loop(c, args.steps, clock))
        if peer is not None:
            prounds.append(mink_target_loop(peer, targets, clock))
            ptw.append(peer.run(args.steps, clock))

    def pick(rs):  # the round with the median p50 stands for the case
        return sorted(rs, key=lambda x: float(np.median(x[0])))[len(rs) // 2]

    rows = []  # (name, p50, p99, max, gc, statuses, tracking error [m] or None)
    for (name, _), rs in zip(target_cases, trounds, strict=True):
        r = pick(rs)
        rows.append((f"ratectl: {name}", *stats(r[0]), r[1], r[2], r[3]))
    if peer is not None:
        r = pick(prounds)
        rows.append(("mink: target, update + solve_ik (daqp)", *stats(r[0]), r[1], None, r[2]))
    for (name, _), rs in zip(twist_cases, wrounds, strict=True):
        r = pick(rs)
        rows.append((f"ratectl: {name}", *stats(r[0]), r[1], r[2], None))
    if peer is not None:
        r = pick(ptw)
        rows.append(("mink: twist (reference), update + solve_ik (daqp)", *stats(r[0]), r[1], None, None))
    print(f"ratectl {rc.__version__}, UR5e, {args.steps} steps × {args.rounds} rounds at dt = 1 ms, "
          f"clock {args.clock}, gc enabled (thresholds {gc.get_threshold()})")
    width = max(len(r[0]) for r in rows)
    print(f"{'step of the 1 kHz loop':{width}s} {'p50 µs':>8s} {'p99 µs':>8s} {'max µs':>8s} "
          f"{'p99/p50':>8s} {'err mm':>7s}  statuses")
    for name, p50, p99, mx, _gcs, st, err in rows:
        e = f"{err * 1e3:7.2f}" if err is not None else f"{'':7s}"
        print(f"{name:{width}s} {p50:8.1f} {p99:8.1f} {mx:8.0f} {p99 / p50:8.2f} {e}  {st or ''}")
    ratios: dict[str, list[float]] = {}
    if peer is not None:
        for (name, _), rs in zip(target_cases, trounds, strict=True):
            ratios[name] = [float(np.median(a[0]) / np.median(b[0]))
                            for a, b in zip(rs, prounds, strict=True)]
        ratios["twist (reference), QP"] = [float(np.median(a[0]) / np.median(b[0]))
                                           for a, b in zip(wrounds[0], ptw, strict=True)]
        for name, rs in ratios.items():
            print(f"{name} / mink, per round: {' '.join(f'{x:.2f}' for x in rs)} -> median "
                  f"{statistics.median(rs):.2f}" + (" (goal ≤ 0.5)" if name == "target, QP" else ""))
    jit = [float(np.percentile(x[0], 99) / np.median(x[0])) for x in trounds[0]]
    print(f"target, QP: p99/p50 per round: {' '.join(f'{x:.2f}' for x in jit)} -> median "
          f"{statistics.median(jit):.2f} (goal ≤ 2)")
    if args.markdown or args.update_docs:
        text = markdown(rows, ratios, jit, args)
        print("\n" + text)
        if args.update_docs:
            update_docs("bench_servo.py", text)


def markdown(rows: list, ratios: dict, jit: list[float], args) -> str:
    versions = ", ".join(f"{name} {_version(name)}" for name in ("numpy", "mink", "daqp", "mujoco"))
    out = [f"Measured by `benchmarks/bench_servo.py --clock {args.clock}` on {machine()}; {versions}:",
           "",
           f"| step of the 1 kHz loop (UR5e, {args.steps} calls, gc enabled; the round with the median "
           f"p50 of {args.rounds}) | p50 [µs] | p99 [µs] | p99/p50 | median distance from the moving "
           "target [mm] |",
           "|---|---|---|---|---|"]
    for name, p50, p99, _mx, _gcs, _st, err in rows:
        e = f"{err * 1e3:.2f}" if err is not None else "—"
        out.append(f"| {name} | {p50:.1f} | {p99:.1f} | {p99 / p50:.2f} | {e} |")
    out.append("")
    for name, rs in ratios.items():
        goal = " (goal ≤ 0.5)" if name == "target, QP" else ""
        out.append(f"ratectl {name} / mink + daqp, per round: {', '.join(f'{x:.2f}' for x in rs)} — "
                   f"median {statistics.median(rs):.2f}{goal}.")
    out.append(f"Target QP step p99/p50 per round: {', '.join(f'{x:.2f}' for x in jit)} — median "
               f"{statistics.median(jit):.2f} (goal ≤ 2).")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    main()
