"""Benchmark: a control step with several tasks (strict priorities) and self-collision
avoidance, beside mink + daqp with the same tasks and limits, in one process.

The arm is example-robot-data's Panda (its URDF and collision meshes; fingers held),
to its TCP, with velocity, position and acceleration limits (mink has no acceleration
limit). mink runs on the same URDF compiled by MuJoCo (the same 17 collision meshes, convex
hulls in both). Every call is timed with the garbage collector enabled; the loops run in
alternating rounds and the ratio ratectl / mink is taken per round.

Cases (the tool target moves on a 5 cm circle at 0.2 m/s around the tool at HOME, 1 kHz):

* **pose + posture, one level** — ratectl: ``Pose`` and ``Posture`` (weight 0.01) on
  priority 0; mink: ``FrameTask`` (cost 1) + ``PostureTask`` (cost 0.1 = √0.01). Goal ≤ 0.5×.
* **three levels** — ratectl: tool ``Pose`` (p0) + ``panda_link4`` ``Position`` (p1) +
  ``Posture`` (p2); mink has no priorities: the same tasks weighted 1 / 0.1 / 0.01.
  Goal ≤ 1.0×.
* **self-collision** — the servo from HOME to a target behind the base that a plain servo
  reaches through links 1 and 2 (2 ms steps): ratectl ``Pose`` (p0) + ``Posture`` (p1) +
  ``SelfCollision`` (margin 2 cm, influence 12 cm, 73 pairs); mink ``FrameTask`` +
  ``PostureTask`` + ``CollisionAvoidanceLimit`` on the same 73 pairs with the same
  distances. Reported with the smallest distance either reached (coal, convex hulls).

Run:  python benchmarks/bench_tasks.py [--steps N] [--rounds R] [--clock wall|cpu]
                                       [--markdown | --update-docs]

``--update-docs`` writes the table into docs/benchmarks.md between the ``bench_tasks.py
--update-docs`` markers.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import statistics
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests", "tasks"))
from _timing import CLOCKS, machine, update_docs  # noqa: E402
from bench_controller import GcCounter, _version, stats  # noqa: E402
from panda_erd import HOME, panda_chain, panda_urdf  # noqa: E402

import ratectl as rc  # noqa: E402

DT = 1e-3
RADIUS, SPEED = 0.05, 0.2
#: the target behind the base of the self-collision test (tests/tasks/test_self_collision_acceptance.py)
BEHIND = ((-0.163, 0.148, 0.25), (2.397, -0.454, -0.564))
LINK4_OFFSET = np.array([0.0, 0.15, 0.05])


def circle(T0: np.ndarray, steps: int, dt: float = DT) -> list[np.ndarray]:
    """The tool target at t = k·dt: T0 moved along a circle through its origin (base x-y)."""
    w = SPEED / RADIUS
    centre = T0[:3, 3] - np.array([RADIUS, 0.0, 0.0])
    out = []
    for k in range(steps):
        T = T0.copy()
        T[:3, 3] = centre + RADIUS * np.array([math.cos(w * k * dt), math.sin(w * k * dt), 0.0])
        out.append(T)
    return out


def behind_target() -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = rc.spatial.so3_exp(np.array(BEHIND[1]))
    T[:3, 3] = BEHIND[0]
    return T


def mujoco_panda(urdf: str):
    """example-robot-data's Panda URDF compiled by MuJoCo: collision meshes only, fingers
    fixed, every link a body (fusestatic off, so panda_hand_tcp is a body)."""
    import mujoco

    txt = open(urdf, encoding="utf-8").read()
    meshes = os.path.join(os.path.dirname(os.path.dirname(urdf)), "meshes", "collision")
    txt = re.sub(r"<visual>.*?</visual>", "", txt, flags=re.S)
    txt = re.sub(r'filename="package://[^"]*/([^/"]+)"', r'filename="\1"', txt)
    txt = re.sub(r'(<joint name="panda_finger_joint\d" type=")prismatic', r"\1fixed", txt)
    compiler = (f'<mujoco><compiler meshdir="{meshes}" strippath="true" fusestatic="false" '
                'discardvisual="true"/></mujoco>')
    txt = re.sub(r"(<robot[^>]*>)", lambda m: m.group(1) + compiler, txt, count=1)
    return mujoco.MjModel.from_xml_string(txt)


class Case:
    """One case: ratectl's controller and mink's tasks/limits on the same targets."""

    def __init__(self, name, chain, model, kind, steps, dt, sc=None):
        import mink

        self.name, self.chain, self.kind, self.dt = name, chain, kind, dt
        self.mink = mink
        T0 = chain.fk(HOME)
        p4 = chain.fk(HOME, link="panda_link4")[:3, 3] + LINK4_OFFSET
        self.targets = [behind_target()] * steps if kind == "collision" else circle(T0, steps, dt)
        # ratectl
        self.tool = rc.tasks.Pose(priority=0)
        if kind == "one-level":
            tasks = [self.tool, rc.tasks.Posture(HOME, priority=0, weight=0.01, gain=1.0)]
        elif kind == "three-levels":
            tasks = [self.tool, rc.tasks.Position(link="panda_link4", priority=1, target=p4, gain=2.0),
                     rc.tasks.Posture(HOME, priority=2, gain=1.0)]
        else:
            tasks = [self.tool, rc.tasks.Posture(HOME, priority=1, gain=1.0)]
        self.sc = sc
        self.ctrl = rc.ResolvedRateController(chain, tasks=tasks, collision=[sc] if sc is not None else None)
        # mink: the same tasks weighted, the same limits (no acceleration limit in mink)
        self.conf = mink.Configuration(model)
        self.mtool = mink.FrameTask("panda_hand_tcp", "body", position_cost=1.0, orientation_cost=1.0)
        post = mink.PostureTask(model, cost=0.1 if kind == "one-level" else 0.01)
        post.set_target(HOME)
        self.mtasks = [self.mtool, post]
        if kind == "three-levels":
            elbow = mink.FrameTask("panda_link4", "body", position_cost=0.1, orientation_cost=0.0)
            T4 = np.eye(4)
            T4[:3, 3] = p4
            elbow.set_target(mink.SE3.from_matrix(T4))
            self.mtasks.insert(1, elbow)
        names = [model.joint(i).name for i in range(model.njnt)]
        vmax = {nm: float(v) for nm, v in zip(names, chain.vmax, strict=True)}
        self.mlimits = [mink.ConfigurationLimit(model), mink.VelocityLimit(model, vmax)]
        if sc is not None:
            body = {model.body(model.geom_bodyid[g]).name: [] for g in range(model.ngeom)}
            for g in range(model.ngeom):
                body[model.body(model.geom_bodyid[g]).name].append(g)
            groups = {}
            for a, b in sc.pair_names:
                ga, gb = a.split("#")[0], b.split("#")[0]
                groups[frozenset((ga, gb))] = (ga, gb)
            pairs = [(body[a], body[b]) for a, b in groups.values()]
            self.mlimits.append(mink.CollisionAvoidanceLimit(
                model, pairs, gain=sc.gain / (sc.influence - sc.margin) * dt,
                minimum_distance_from_collisions=sc.margin, collision_detection_distance=sc.influence))

    def run_ratectl(self, clock):
        """The ratectl loop: the tool task's target set, then ``ctrl.step(q, dt)`` timed."""
        ctrl, tool, dt = self.ctrl, self.tool, self.dt
        ctrl.reset()
        return self._run(clock, tool.set_target, lambda q: ctrl.step(q, dt=dt), lambda q, cmd: cmd.q_next)

    def run_mink(self, clock):
        """The mink loop: the FrameTask's target set, then ``update(q)`` + ``solve_ik`` timed."""
        mink, conf, dt = self.mink, self.conf, self.dt

        def step(q):
            conf.update(q)
            return mink.solve_ik(conf, self.mtasks, dt, "daqp", damping=1e-3, limits=self.mlimits)

        return self._run(clock, lambda T: self.mtool.set_target(mink.SE3.from_matrix(T)), step,
                         lambda q, v: q + v * dt)

    def _run(self, clock, set_target, step, advance):
        """One loop over the targets from HOME: ``set_target(T_k)``, ``r = step(q)`` timed,
        ``q = advance(q, r)``; returns the per-call times [µs], the gc counts, the median and
        last tool distance from the target [m] and the smallest link distance [m]."""
        q = HOME.copy()
        n = len(self.targets)
        times, err = np.empty(n), np.empty(n)
        dmin = np.inf
        with GcCounter() as gcc:
            for k in range(n):
                set_target(self.targets[k])
                t0 = clock()
                r = step(q)
                times[k] = clock() - t0
                q = advance(q, r)
                err[k] = np.linalg.norm(self.chain.fk(q)[:3, 3] - self.targets[k][:3, 3])
                if self.sc is not None:
                    dmin = min(dmin, float(self.sc.distances(q).min()))
        return times * 1e6, gcc.counts, float(np.median(err)), dmin, float(err[-1])

def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000, help="calls per loop (default 2000)")
    ap.add_argument("--rounds", type=int, default=3, help="alternating rounds (default 3)")
    ap.add_argument("--clock", choices=("wall", "cpu"), default="cpu",
                    help="cpu: this thread's CPU time (default); wall: elapsed time per call")
    ap.add_argument("--markdown", action="store_true", help="print the table as markdown")
    ap.add_argument("--update-docs", action="store_true",
                    help="write the table into docs/benchmarks.md (implies --markdown)")
    args = ap.parse_args(argv)
    clock = CLOCKS[args.clock]
    urdf = panda_urdf()
    if urdf is None:
        raise SystemExit("example-robot-data is not installed")
    chain = panda_chain(urdf)
    model = mujoco_panda(urdf)
    sc = rc.collision.SelfCollision.from_urdf(urdf, chain, margin=0.02)
    cases = [
        Case("pose + posture, one level", chain, model, "one-level", args.steps, DT),
        Case("tool p0 + panda_link4 p1 + posture p2", chain, model, "three-levels", args.steps, DT),
        Case(f"self-collision ({len(sc.pairs)} pairs), servo behind the base", chain, model, "collision",
             max(args.steps // 2, 1), 2e-3, sc=sc),
    ]
    goals = {0: 0.5, 1: 1.0}
    for c in cases:  # warm-up
        c.run_ratectl(clock)
        c.run_mink(clock)
    res: list[tuple[list, list]] = [([], []) for _ in cases]
    for _ in range(args.rounds):
        for i, c in enumerate(cases):
            res[i][0].append(c.run_ratectl(clock))
            res[i][1].append(c.run_mink(clock))

    def pick(rs):
        return sorted(rs, key=lambda x: float(np.median(x[0])))[len(rs) // 2]

    rows = []
    for i, c in enumerate(cases):
        ra, mi = res[i]
        ratios = [float(np.median(a[0]) / np.median(b[0])) for a, b in zip(ra, mi, strict=True)]
        rows.append((c.name, pick(ra), pick(mi), ratios, goals.get(i)))
    print(f"ratectl {rc.__version__}, example-robot-data Panda, {args.steps} steps × {args.rounds} rounds, "
          f"clock {args.clock}")
    for name, r, m, ratios, goal in rows:
        print(f"{name}:")
        for who, x in (("ratectl", r), ("mink + daqp", m)):
            p50, p99, _ = stats(x[0])
            extra = f", min distance {x[3] * 1e3:.1f} mm" if np.isfinite(x[3]) else ""
            print(f"  {who:12s} p50 {p50:8.1f} µs  p99 {p99:8.1f} µs  median tool error "
                  f"{x[2] * 1e3:6.2f} mm  final {x[4] * 1e3:6.2f} mm{extra}")
        g = f" (goal ≤ {goal})" if goal is not None else ""
        print(f"  ratio per round: {' '.join(f'{x:.2f}' for x in ratios)} -> median "
              f"{statistics.median(ratios):.2f}{g}")
    if args.markdown or args.update_docs:
        text = markdown(rows, args)
        print("\n" + text)
        if args.update_docs:
            update_docs("bench_tasks.py", text)


def markdown(rows: list, args) -> str:
    versions = ", ".join(f"{name} {_version(name)}" for name in ("numpy", "mink", "daqp", "mujoco", "coal"))
    out = [f"Measured by `benchmarks/bench_tasks.py --clock {args.clock}` on {machine()}; {versions}:",
           "",
           f"| case (example-robot-data Panda; the round with the median p50 of {args.rounds}) | "
           "ratectl p50 [µs] | ratectl p99 [µs] | mink + daqp p50 [µs] | ratio (median of rounds) | "
           "median tool error ratectl / mink [mm] |",
           "|---|---|---|---|---|---|"]
    for name, r, m, ratios, goal in rows:
        g = f" (goal ≤ {goal})" if goal is not None else ""
        dist = (f"; smallest distance {r[3] * 1e3:.1f} / {m[3] * 1e3:.1f} mm"
                if np.isfinite(r[3]) else "")
        out.append(f"| {name} | {np.median(r[0]):.0f} | {np.percentile(r[0], 99):.0f} | "
                   f"{np.median(m[0]):.0f} | {statistics.median(ratios):.2f}{g} | "
                   f"{r[2] * 1e3:.2f} / {m[2] * 1e3:.2f}{dist} |")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    main()
