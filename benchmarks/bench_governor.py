"""Governor benchmark: near and exact singularity crossings, a singular end, blends, sharp corners
(waypoints with ``blend=0``, where the tool must stop), a fast line.

Run:  python benchmarks/bench_governor.py [name-filter ...]

Every path is followed twice with ``rc.follow`` (dt = 2 ms, default governor): without and
with the Ruckig smoother. Per path it prints

* ok — the acceptance of issue #13 for the unsmoothed run: completed, path error ≤ 0.01 mm
  and 0.01°, end within 0.1 mm, |q̇| ≤ vmax and |q̈| ≤ amax by finite differences of the
  recorded q, q inside its range; for the smoothed run: path error ≤ 0.05 mm or not
  completed with a reason, |jerk| ≤ jmax (differences of the recorded q̈), duration ≤ 1.5×
  the unsmoothed one;
* err — the largest distance from the path [mm] / orientation error [°] of the run;
* v, a — the largest |q̇|/vmax and |q̈|/amax (finite differences of q);
* T — the run's duration [s]; T/topp — that duration over the TOPP-RA minimum time
  (toppra, on the joint path the run traced, same vmax and amax, and the path's speed and
  acceleration as limits on ṡ and s̈ through an extra coordinate equal to s);
* the smoothed run: completed, error, jerk ratio, duration over the unsmoothed one;
* crossings — what the joint path passed, with the branch taken.

Exact crossings are built at a configuration q* where det J = 0 (wrist: q5 = 0, elbow:
the forearm in line with the upper arm, shoulder: the wrist centre on the axis of joint 1,
found by root finding on det J): the path tangent is J(q*)·q̇* for a joint velocity q̇*
that moves the singular joint, so it lies in the range of J and the path passes through
the singular configuration itself. Near crossings use the same construction a small
distance from q*.
"""

from __future__ import annotations

import math
import os
import sys
import time

import numpy as np
from scipy.optimize import brentq

import ratectl as rc
from ratectl.singularity import analyze

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "planning"))

from singular_paths import crossing_line, followable, full_reach_line  # noqa: E402

DT = 2e-3


# ---------------------------------------------------------------------- path construction
def det_root(arm, q, joint, lo, hi, kind):
    """q with joint ``joint`` moved to a root of det J in [lo, hi] where analyze says ``kind``."""
    q = np.array(q, float)

    def det(x):
        qq = q.copy()
        qq[joint] = x
        return float(np.linalg.det(arm.jacobian(qq)))

    xs = np.linspace(lo, hi, 721)
    d = [det(x) for x in xs]
    for k in range(len(xs) - 1):
        if d[k] == 0.0 or d[k] * d[k + 1] < 0:
            r = xs[k] if d[k] == 0.0 else brentq(det, xs[k], xs[k + 1], xtol=1e-15)
            qq = q.copy()
            qq[joint] = r
            if str(analyze(arm, qq).kind) == kind:
                return qq
    raise RuntimeError(f"no {kind} singularity of {arm.name} on joint {joint} in [{lo}, {hi}]")


def _unit(n, i, extra, seed):
    rng = np.random.default_rng(seed)
    qd = 0.3 * rng.standard_normal(n) * extra
    qd[i] += 1.0
    return qd


def exact_and_near(arm_name, joint, kind, q, lo, hi, *, near=None, seed=1, **kw):
    """(exact, near) builders for a singularity of ``kind`` found on ``joint``; the near line
    is the exact one shifted sideways by ``near`` [m]."""
    def build(offset):
        def make():
            arm = rc.robots.BUILTIN[arm_name]()
            qs = det_root(arm, q, joint, lo, hi, kind)
            for sd in range(seed, seed + 8):  # a crossing direction whose path stays in the joint range
                try:
                    return (arm, *crossing_line(arm, qs, _unit(arm.dof, joint, 1.0, sd), offset=offset, **kw))
                except RuntimeError:
                    continue
            raise RuntimeError(f"no followable {kind} crossing of {arm.name}")
        return make
    return build(0.0), build(near) if near else None


def wrist_near(arm_name, q, **kw):
    """A crossing line through a given (near-singular) configuration, moving joint 5 mostly."""
    def make():
        arm = rc.robots.BUILTIN[arm_name]()
        return (arm, *crossing_line(arm, np.array(q, float), _unit(len(q), 4, 1.0, 3), **kw))
    return make


def elbow_arc(arm_name, joint, q, lo, hi, *, radius=0.1, angle=0.5, speed=0.2, acceleration=1.0):
    """A constant-orientation arc through the elbow (boundary) singularity q*, tangent there to
    the translations J(q*) can still produce and curving into the workspace: it touches the
    boundary exactly once (a straight line tangent to it would leave the workspace)."""
    def make():
        arm = rc.robots.BUILTIN[arm_name]()
        qs = det_root(arm, q, joint, lo, hi, "elbow")
        Tc, J = arm.fk_jacobian(qs)
        U = np.linalg.svd(J)[0][:, :5]
        from scipy.linalg import null_space

        plane = U[:3] @ null_space(U[3:])  # translations (ω = 0) in the range of J(q*)
        n = np.cross(plane[:, 0], plane[:, 1])
        n /= np.linalg.norm(n)
        v = plane[:, 0] / np.linalg.norm(plane[:, 0])
        for sign in (1.0, -1.0):  # the side of the boundary the workspace is on
            c = Tc[:3, 3] - sign * radius * n
            k = np.cross(sign * n, v)
            T0 = Tc.copy()
            T0[:3, 3] = c + rc.spatial.so3_exp(-0.5 * angle * k) @ (Tc[:3, 3] - c)
            arc = rc.paths.Arc(T0, centre=c, axis=k, angle=angle, speed=speed, acceleration=acceleration)
            for bend in (0.3, -0.3):
                res = rc.ik(arm, T0, qs + bend * np.eye(arm.dof)[joint], max_step=0.05)
                if res.converged and followable(arm, arc, res.q):
                    return arm, arc, np.array(res.q)
        raise RuntimeError(f"no followable elbow arc for {arm.name}")
    return make


def reach_line(arm_name, q_end, elbow, *, length=0.1):
    """A constant-orientation line outwards to a nearly stretched configuration ``q_end``."""
    def make():
        arm = rc.robots.BUILTIN[arm_name]()
        qe = np.array(q_end, float)
        T_end = arm.fk(qe)
        d = T_end[:3, 3] - arm.frames(qe)[2][:3, 3]
        d /= np.linalg.norm(d)
        Ta = T_end.copy()
        Ta[:3, 3] -= length * d
        guess = qe.copy()
        guess[elbow] -= 0.5
        res = rc.ik(arm, Ta, guess, max_step=0.05)
        assert res.converged, res
        return arm, rc.paths.Line(Ta, T_end, speed=0.2, acceleration=1.0), np.array(res.q)
    return make


def waypoints(arm_name, q0, steps, *, blend=0.03, speed=0.15, acceleration=0.8, turn=0.4):
    def make():
        arm = rc.robots.BUILTIN[arm_name]()
        T0 = arm.fk(np.array(q0))
        poses = [T0]
        for dp in steps:
            T = poses[-1].copy()
            T[:3, 3] += dp
            poses.append(T)
        poses[2][:3, :3] = poses[2][:3, :3] @ rc.spatial.rotz(turn)
        path = rc.paths.Waypoints(poses, blend=blend, speed=speed, acceleration=acceleration)
        return arm, path, np.array(q0)
    return make


def fast_line():
    arm = rc.robots.ur5e()
    q0 = np.array([0.0, -1.2, 1.4, -1.8, 0.9, 0.3])
    T0 = arm.fk(q0)
    T1 = T0.copy()
    T1[:3, 3] += [0.25, 0.1, -0.1]
    T1[:3, :3] = T1[:3, :3] @ rc.spatial.rotx(0.3)
    return arm, rc.paths.Line(T0, T1, speed=1.0, acceleration=5.0), q0


def cases():
    ur_q = [0.0, -2.0, -1.6, -1.2, 0.0, 0.0]
    out = {}
    out["ur5e wrist exact"], out["ur5e wrist near (1 mm off)"] = exact_and_near(
        "ur5e", 4, "wrist", ur_q, -0.5, 0.5, near=1e-3)
    out["ur5e elbow exact (arc)"] = elbow_arc("ur5e", 2, [0.3, -1.0, 0.5, -1.2, 1.2, 0.3], -0.5, 0.5)
    out["ur5e shoulder exact"], out["ur5e shoulder near (2 mm off)"] = exact_and_near(
        "ur5e", 1, "shoulder", [0.3, -1.0, 1.2, -1.2, 1.2, 0.3], -3.1, 0.0, near=2e-3, half=0.08)
    out["puma560 wrist exact"], out["puma560 wrist near (1 mm off)"] = exact_and_near(
        "puma560", 4, "wrist", [0.2, 0.6, -0.4, -1.0, 0.0, 0.0], -0.5, 0.5, near=1e-3, half=0.08)
    out["puma560 elbow exact (arc)"] = elbow_arc("puma560", 2, [0.2, 0.6, -1.0, 0.3, 0.8, 0.2], -3.5, 0.7)
    out["puma560 shoulder exact"], _ = exact_and_near(
        "puma560", 1, "shoulder", [0.2, 0.6, -1.0, 0.3, 0.8, 0.2], -0.7, 3.9, half=0.06)
    out["stanford wrist exact"], out["stanford wrist near (1 mm off)"] = exact_and_near(
        "stanford", 4, "wrist", [0.2, 0.8, 0.6, -1.0, 0.0, 1.0], -0.5, 0.5, near=1e-3, half=0.08)
    out["iiwa7 line to near full reach"] = reach_line("iiwa7", [0.2, 0.5, 0.1, -0.03, 0.3, 0.6, 0.1], 3)
    out["panda line past a straight elbow"] = wrist_near("panda", [0.1, -0.3, 0.1, -0.08, 0.2, 1.0, 0.5],
                                                         half=0.06)
    out["ur5e singular end (full reach)"] = full_reach_line
    out["iiwa7 waypoints, 3 cm blends"] = waypoints(
        "iiwa7", [0.0, 0.6, 0.0, -1.2, 0.0, 0.9, 0.0], ([0.1, 0, 0], [0.0, 0.1, -0.05], [-0.1, 0.0, 0.1]))
    out["ur5e waypoints, 3 cm blends"] = waypoints(
        "ur5e", [0.0, -1.2, 1.4, -1.8, 0.9, 0.3], ([0.1, 0, 0], [0.0, 0.1, -0.05], [-0.1, 0.0, 0.1]),
        speed=0.3, acceleration=1.5)
    out["ur5e waypoints, sharp corners"] = waypoints(
        "ur5e", [0.0, -1.2, 1.4, -1.8, 0.9, 0.3], ([0.1, 0, 0], [0.0, 0.1, -0.05], [-0.1, 0.0, 0.1]),
        blend=0.0, speed=0.3, acceleration=1.5)
    out["ur5e fast line 1 m/s"] = fast_line
    return out


# ---------------------------------------------------------------------- measurement
def topp_ra_duration(arm, path, run):
    """TOPP-RA minimum time (toppra) of the joint path the run traced, same vmax/amax, path
    speed and acceleration as limits of an extra coordinate equal to s."""
    import toppra as ta

    s = np.asarray(run.s)
    keep = np.concatenate([[True], np.diff(s) > 1e-9])
    s_u, q_u = s[keep], run.q[keep]
    if s_u[-1] < s[-1]:
        s_u, q_u = np.append(s_u, s[-1]), np.vstack([q_u, run.q[-1]])
    way = np.hstack([q_u, s_u[:, None]])
    geo = ta.SplineInterpolator(s_u, way)
    vlim = np.append(arm.vmax, path.speed)
    alim = np.append(arm.amax, path.acceleration)
    cons = [ta.constraint.JointVelocityConstraint(np.stack([-vlim, vlim], axis=1)),
            ta.constraint.JointAccelerationConstraint(np.stack([-alim, alim], axis=1))]
    grid = np.linspace(s_u[0], s_u[-1], 2001)
    algo = ta.algorithm.TOPPRA(cons, geo, gridpoints=grid, parametrizer="ParametrizeConstAccel")
    traj = algo.compute_trajectory(0.0, 0.0)
    return float(traj.duration) if traj is not None else math.nan


def ratios(arm, run):
    q = run.q
    qd = np.diff(q, axis=0) / DT
    qdd = np.diff(qd, axis=0) / DT
    jerk = np.diff(run.qdd, axis=0) / DT
    return (float(np.max(np.abs(qd) / arm.vmax)), float(np.max(np.abs(qdd) / arm.amax)),
            float(np.max(np.abs(jerk) / arm.jmax)),
            bool(np.all((q >= arm.lower - 1e-12) & (q <= arm.upper + 1e-12))))


def measure(name, make):
    arm, path, q0 = make()
    run = rc.follow(arm, path, q0, dt=DT)
    runs = rc.follow(arm, path, q0, dt=DT, controller=rc.ResolvedRateController(arm, smoothing=True))
    v, a, _, inside = ratios(arm, run)
    _, _, js, inside_s = ratios(arm, runs)
    end = float(np.linalg.norm(run.poses[-1][:3, 3] - path.end[:3, 3]))
    topp = topp_ra_duration(arm, path, run) if run.completed else math.nan
    ok = (run.completed and run.max_position_error <= 1e-5 and run.max_orientation_error <= math.radians(0.01)
          and end <= 1e-4 and v <= 1 + 1e-9 and a <= 1 + 1e-9 and inside)
    ok_s = ((runs.max_position_error <= 5e-5 or (not runs.completed and runs.message)) and js <= 1 + 1e-6
            and inside_s and runs.duration <= 1.5 * run.duration)
    plan = run.info.get("plan")
    cross = "; ".join(f"{c.kind} σ={c.sigma_min:.0e} {c.branch}" for c in plan.joint_path.crossings) \
        if plan is not None else ""
    return dict(name=name, ok=ok and ok_s, completed=run.completed, err=run.max_position_error * 1e3,
                oerr=math.degrees(run.max_orientation_error), v=v, a=a, T=run.duration, topp=topp,
                s_completed=runs.completed, s_err=runs.max_position_error * 1e3, js=js,
                s_ratio=runs.duration / run.duration, end=end * 1e3, cross=cross,
                message=run.message if not run.completed else (runs.message if not runs.completed else ""))


def main(filters) -> None:
    rows = []
    t0 = time.perf_counter()
    print(f"{'path':32s} {'ok':3s} {'done':4s} {'err mm/°':>15s} {'v':>5s} {'a':>5s} {'T s':>6s} "
          f"{'T/topp':>6s} | {'smoothed: done':>14s} {'err mm':>7s} {'jerk':>5s} {'T/T0':>5s} | crossings")
    for name, make in cases().items():
        if make is None or (filters and not any(f in name for f in filters)):
            continue
        r = measure(name, make)
        rows.append(r)
        print(f"{name:32s} {'yes' if r['ok'] else 'NO':3s} {str(r['completed']):4s} "
              f"{r['err']:7.1e}/{r['oerr']:7.1e} {r['v']:5.3f} {r['a']:5.3f} {r['T']:6.3f} "
              f"{r['T'] / r['topp']:6.3f} | "
              f"{str(r['s_completed']):>14s} {r['s_err']:7.1e} {r['js']:5.3f} {r['s_ratio']:5.2f} | "
              f"{r['cross']}"
              + (f"\n    {r['message']}" if r['message'] else ""), flush=True)
    rel = np.array([r["T"] / r["topp"] for r in rows if np.isfinite(r["topp"])])
    if rel.size:
        print(f"\nduration / TOPP-RA: median {np.median(rel):.3f}, max {rel.max():.3f} over {rel.size} "
              f"paths; all ok: {all(r['ok'] for r in rows)}; {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main(sys.argv[1:])
