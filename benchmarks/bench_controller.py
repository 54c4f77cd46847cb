"""Benchmark: cost and jitter of ``ResolvedRateController.step`` in a 1 kHz user loop (UR5e),
beside mink.

The loop resolves a feed-forward tool twist along a 5 cm circle at 0.2 m/s (``ctrl.step(q,
twist=ξ, dt=1 ms)``; ``q = cmd.q_next``), as a user's loop would, and times every call with
the garbage collector enabled: p50 / p99 / max [µs], p99/p50 and the garbage collections
during the run, for the QP solver (velocity, position and acceleration limits) and the
default solver (AdaptiveDLS), with and without Ruckig smoothing. Beside it, in the same
process and on the same arm (exported with ``to_mjcf``), mink's ``Configuration.update(q)``
+ ``solve_ik`` with the daqp backend, a ``FrameTask`` whose target is the pose one period of
the twist ahead, and ``ConfigurationLimit`` + ``VelocityLimit`` (mink has no acceleration
limit); the two loops run in alternating rounds and the ratio is taken per round (these
machines are shared: ratios vary much less than times).

Then the governor's plan of the demo's line past the wrist singularity
(``ratectl.cli.demo.wrist_line``) and a whole ``follow`` run.

Run:  python benchmarks/bench_controller.py [--steps N] [--rounds R] [--clock wall|cpu]
                                            [--markdown | --update-docs] [--no-governor]

``--markdown`` prints the table as markdown; ``--update-docs`` also writes it into
docs/benchmarks.md, between the ``bench_controller.py --update-docs`` markers, with the date,
the machine and the load. Goals (issue #17): the QP step ≤ 0.5 × mink + daqp, and its
p99/p50 ≤ 2 over 5,000 calls.
"""

from __future__ import annotations

import argparse
import gc
import math
import os
import statistics
import sys
import time
from importlib.metadata import PackageNotFoundError, version

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from _timing import CLOCKS, machine, update_docs  # noqa: E402

import ratectl as rc  # noqa: E402

Q0 = np.array([0.3, -1.2, 1.5, -1.9, -1.4, 0.6])  # a regular UR5e configuration
DT = 1e-3
RADIUS, SPEED = 0.05, 0.2  # the circle [m] and the tool speed along it [m/s]


def circle_twist(t: float) -> np.ndarray:
    """The tool twist [v; ω] of the circle at time t (base axes, no rotation)."""
    w = SPEED / RADIUS
    return np.array([-SPEED * math.sin(w * t), SPEED * math.cos(w * t), 0.0, 0.0, 0.0, 0.0])


class GcCounter:
    """Counts the garbage collections (per generation) while installed."""

    def __init__(self) -> None:
        self.counts = [0, 0, 0]

    def __call__(self, phase: str, info: dict) -> None:
        if phase == "start":
            self.counts[info["generation"]] += 1

    def __enter__(self) -> GcCounter:
        gc.callbacks.append(self)
        return self

    def __exit__(self, *exc) -> None:
        gc.callbacks.remove(self)


def ratectl_loop(ctrl, steps: int, clock) -> tuple[np.ndarray, list[int], dict]:
    """Per-call times [µs] of ``ctrl.step`` along the circle, the gc counts and the statuses."""
    ctrl.reset()
    q = Q0.copy()
    twists = [circle_twist(k * DT) for k in range(steps)]
    times = np.empty(steps)
    statuses: dict[str, int] = {}
    step = ctrl.step
    with GcCounter() as gcc:
        for k in range(steps):
            t0 = clock()
            cmd = step(q, twist=twists[k], dt=DT)
            times[k] = clock() - t0
            statuses[cmd.status] = statuses.get(cmd.status, 0) + 1
            q = cmd.q_next
    return times * 1e6, gcc.counts, statuses


class MinkLoop:
    """mink on the same arm: ``update(q)`` + ``solve_ik`` (daqp), velocity and position limits."""

    def __init__(self, arm) -> None:
        import mink
        import mujoco

        from ratectl.interop.mujoco import to_mjcf

        self.mink, self.arm = mink, arm
        model = mujoco.MjModel.from_xml_string(to_mjcf(arm))
        self.conf = mink.Configuration(model)
        self.task = mink.FrameTask("tool", "site", position_cost=1.0, orientation_cost=1.0)
        names = [model.joint(i).name for i in range(model.njnt)]
        vmax = {nm: float(v) for nm, v in zip(names, arm.vmax, strict=True)}
        self.limits = [mink.ConfigurationLimit(model), mink.VelocityLimit(model, vmax)]

    def run(self, steps: int, clock) -> tuple[np.ndarray, list[int]]:
        mink, conf, task = self.mink, self.conf, self.task
        q = Q0.copy()
        times = np.empty(steps)
        with GcCounter() as gcc:
            for k in range(steps):
                # the target one period of the twist ahead of the tool (set outside the timing)
                T = self.arm.fk(q)
                T[:3, 3] += circle_twist(k * DT)[:3] * DT
                task.set_target(mink.SE3.from_matrix(T))
                t0 = clock()
                conf.update(q)
                v = mink.solve_ik(conf, [task], DT, "daqp", damping=1e-3, limits=self.limits)
                times[k] = clock() - t0
                q = q + v * DT
        return times * 1e6, gcc.counts


def _version(name: str) -> str:
    try:
        return version(name)
    except PackageNotFoundError:
        return "not installed"


def stats(us: np.ndarray) -> tuple[float, float, float]:
    return float(np.median(us)), float(np.percentile(us, 99)), float(us.max())


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=5000, help="calls per loop (default 5000)")
    ap.add_argument("--rounds", type=int, default=5, help="alternating rounds (default 5)")
    ap.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                    help="wall: elapsed time per call (default, what a loop sees); cpu: this "
                         "thread's CPU time (leaves out preemption by other processes)")
    ap.add_argument("--markdown", action="store_true", help="print the table as markdown")
    ap.add_argument("--update-docs", action="store_true",
                    help="write the table into docs/benchmarks.md (implies --markdown)")
    ap.add_argument("--no-governor", action="store_true", help="skip the governor and follow timings")
    args = ap.parse_args(argv)
    clock = CLOCKS[args.clock]
    arm = rc.robots.ur5e()
    cases = [
        ("QP (velocity, position, acceleration limits)", dict(solver=rc.solvers.QP())),
        ("QP + Ruckig smoothing", dict(solver=rc.solvers.QP(), smoothing=True)),
        ("default (AdaptiveDLS)", dict()),
        ("default (AdaptiveDLS) + Ruckig smoothing", dict(smoothing=True)),
    ]
    ctrls = [rc.ResolvedRateController(arm, **kw) for _, kw in cases]
    try:
        peer: MinkLoop | None = MinkLoop(arm)
    except ImportError:
        peer = None
        print("mink or mujoco not installed: no ratio")
    for c in ctrls:  # warm-up (kernels, Ruckig objects, the QP's caches)
        ratectl_loop(c, 300, clock)
    if peer is not None:
        peer.run(300, clock)
    rounds: list[list] = [[] for _ in ctrls]
    peer_rounds: list = []
    for _ in range(args.rounds):
        for i, c in enumerate(ctrls):
            rounds[i].append(ratectl_loop(c, args.steps, clock))
        if peer is not None:
            peer_rounds.append(peer.run(args.steps, clock))
    print(f"ratectl {rc.__version__}, numpy {np.__version__}, UR5e, {args.steps} steps × "
          f"{args.rounds} rounds at dt = 1 ms, clock {args.clock}, gc enabled (thresholds "
          f"{gc.get_threshold()})")
    rows = []
    for (name, _), rs in zip(cases, rounds, strict=True):
        # the round with the median p50 stands for the case (its p99 and max alongside)
        r = sorted(rs, key=lambda x: float(np.median(x[0])))[len(rs) // 2]
        p50, p99, mx = stats(r[0])
        rows.append((f"ratectl: {name}", p50, p99, mx, r[1], r[2]))
    if peer is not None:
        r = sorted(peer_rounds, key=lambda x: float(np.median(x[0])))[len(peer_rounds) // 2]
        p50, p99, mx = stats(r[0])
        rows.append(("mink: update + solve_ik (daqp), configuration + velocity limits", p50, p99, mx,
                     r[1], None))
    width = max(len(r[0]) for r in rows)
    print(f"{'step of the 1 kHz loop':{width}s} {'p50 µs':>8s} {'p99 µs':>8s} {'max µs':>8s} "
          f"{'p99/p50':>8s}  gc collections (gen 0/1/2)  statuses")
    for name, p50, p99, mx, gcs, st in rows:
        print(f"{name:{width}s} {p50:8.1f} {p99:8.1f} {mx:8.0f} {p99 / p50:8.2f}  "
              f"{'/'.join(map(str, gcs)):>26s}  {st or ''}")
    ratios = []
    if peer is not None:
        ratios = [float(np.median(a[0]) / np.median(b[0]))
                  for a, b in zip(rounds[0], peer_rounds, strict=True)]
        print(f"QP step / mink + daqp, per round: {' '.join(f'{x:.3f}' for x in ratios)} -> "
              f"best {min(ratios):.3f}, median {statistics.median(ratios):.3f} (target ≤ 0.5)")
    jit = [float(np.percentile(x[0], 99) / np.median(x[0])) for x in rounds[0]]
    print(f"QP step p99/p50 per round: {' '.join(f'{x:.2f}' for x in jit)} -> median "
          f"{statistics.median(jit):.2f} (target ≤ 2)")
    if args.markdown or args.update_docs:
        text = markdown(rows, ratios, jit, args)
        print("\n" + text)
        if args.update_docs:
            update_docs("bench_controller.py", text)
    if not args.no_governor:
        governor(arm)


def markdown(rows: list, ratios: list[float], jit: list[float], args) -> str:
    """The measured table as the markdown block of docs/benchmarks.md."""
    versions = ", ".join(f"{name} {_version(name)}" for name in ("numpy", "mink", "daqp", "mujoco"))
    out = [f"Measured by `benchmarks/bench_controller.py --clock {args.clock}` on {machine()}; "
           f"{versions}:", "",
           f"| step of the 1 kHz loop (UR5e, {args.steps} calls, gc enabled; the round with the "
           f"median p50 of {args.rounds}) | p50 [µs] | p99 [µs] | max [µs] | p99/p50 | gc collections |",
           "|---|---|---|---|---|---|"]
    for name, p50, p99, mx, gcs, _ in rows:
        out.append(f"| {name} | {p50:.1f} | {p99:.1f} | {mx:.0f} | {p99 / p50:.2f} | {sum(gcs)} |")
    out.append("")
    if ratios:
        out.append(f"QP step / (mink `update` + `solve_ik`, daqp), per round: "
                   f"{', '.join(f'{x:.2f}' for x in ratios)} — best {min(ratios):.2f}, median "
                   f"{statistics.median(ratios):.2f} (goal ≤ 0.5).")
    out.append(f"QP step p99/p50 per round: {', '.join(f'{x:.2f}' for x in jit)} — median "
               f"{statistics.median(jit):.2f} (goal ≤ 2).")
    return "\n".join(out) + "\n"


def governor(arm) -> None:
    """The governor's plan of the demo's line past the wrist singularity, and a follow run."""
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
