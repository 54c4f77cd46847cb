"""The straight-approach sweep of the servo: does the tool go straight to a step target?

A *case* is an arm, a start q0 and a target: a **step** (the tool point moves 5–25 cm in a
random direction while the tool turns 0–45° about a random axis) or a **pure turn** (the
tool point stays, the tool turns 15–45°). Starts are seeded random configurations inside
the range (0.3 rad from every limit) whose length-scaled σ_min is at least 0.05; a case is
kept only if its straight line is clear: `ratectl.ik`, warm-started along 21 poses of the
straight pose interpolation, finds a continuous joint path (≤ 0.25 rad between samples)
that stays 0.05 rad inside the range with scaled σ_min ≥ 0.03. So every kept target can be
reached along the straight line within the limits; nothing blocks it.

`run_case` runs the loop a user writes,

    cmd = ctrl.step(q, target=T, dt=dt); q = cmd.q_next

from rest at q0 until ``cmd.status`` is terminal (``target-reached``, ``target-unreachable``
or ``halted-singularity``) or 4 s have passed, and measures, over the states q_0 … q_K
(the last one ``cmd.q_next`` of the last call):

* **segment deviation** — the largest distance of the tool point p(t) from the segment
  p_0 → p_target (the closest point of the segment, ends included; for a pure turn the
  segment is the point p_0). Allowed: 1 mm + 0.5 % of the step length L.
* **orientation deviation** — the largest angle between R(t) and the closest rotation on
  the geodesic R_0 → R_target. With the turn R_0ᵀR_target = exp(θ â) and the relative
  rotation R_0ᵀR(t) = the unit quaternion (w, v) (w ≥ 0), the geodesic's quaternions are
  (cos φ/2, sin φ/2 â) for φ ∈ [0, θ]; the angle to one of them is 2 arccos|w cos φ/2 +
  (v·â) sin φ/2|, smallest at φ* = clip(2 atan2(v·â, w), 0, θ). The unclipped φ is the
  rotational progress; its excess over θ is the rotational overshoot. This suite allows
  0.5° + 1 % of the turn (its own reading of "geodesic rotation"; the issue gives the
  position bound only).
* **overshoot** — max over t of (p(t) − p_0)·u − L along the step direction u (≥ 0; none
  for a pure turn). Allowed: 1 % of L + 0.1 mm.
* **time to reach** — the time k·dt of the state at which ``status == "target-reached"``
  first (the loop stops there); 4 s at most.
* **limits** — max |q̇_i|/vmax_i of ``cmd.qd``; max |q̈_i|/amax_i of ``cmd.qdd`` and of the
  difference quotients (q̇_k − q̇_{k−1})/dt (from rest); the worst excursion of q beyond
  its range. Allowed: 1 + 1e-9 (relative) and 1e-12.
* **sync** (reported, not judged) — the largest gap between the translational progress
  (p − p_0)·u / L and the rotational progress φ/θ on a step with a turn of 5° or more: 0
  on the straight pose interpolation, where both follow one profile.

Run as a script for the table (arm × smoothing × dt):

    python -m tests.conformance.servo_sweep            # the default size of the test
    python -m tests.conformance.servo_sweep --slow     # the RATECTL_SLOW=1 size
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass, field

import numpy as np

import ratectl as rc
from ratectl.spatial import interpolate, quat_from_rotation, so3_log

from . import servo_arms

DURATION = 4.0                       # s: the acceptance's time to reach
TERMINAL = ("target-reached", "target-unreachable", "halted-singularity")
STEP_RANGE = (0.05, 0.25)            # m
MAX_TURN = math.radians(45.0)        # rad, with a step
PURE_TURN = (math.radians(15.0), math.radians(45.0))
START_SIGMA = 0.05                   # scaled σ_min of a start
LINE_SIGMA = 0.03                    # scaled σ_min along the straight line's joint path
LINE_MARGIN = 0.05                   # rad (m) inside the range along the line
LINE_SAMPLES = 21
REL = 1e-9                           # relative tolerance of vmax and amax

# default (test) and slow sizes: cases per arm
DEFAULT_SIZE = {"steps": 3, "turns": 2}
SLOW_SIZE = {"steps": 10, "turns": 4}


def segment_allowed(L: float) -> float:
    """Allowed distance from the straight segment [m]: 1 mm + 0.5 % of the step L."""
    return 1e-3 + 0.005 * L


def overshoot_allowed(L: float) -> float:
    """Allowed overshoot along the step [m]: 1 % of L + 0.1 mm."""
    return 0.01 * L + 1e-4


def orientation_allowed(turn: float) -> float:
    """Allowed angle from the geodesic [rad]: 0.5° + 1 % of the turn."""
    return math.radians(0.5) + 0.01 * turn


def _rot(axis: np.ndarray, angle: float) -> np.ndarray:
    return rc.spatial.so3_exp(np.asarray(axis, dtype=float) / np.linalg.norm(axis) * angle)


@dataclass(frozen=True)
class Case:
    """One step target: ``kind`` is "step" or "turn"; ``step`` [m], ``turn`` [rad]."""

    arm: str
    index: int
    kind: str
    q0: np.ndarray
    target: np.ndarray
    step: float
    turn: float

    @property
    def label(self) -> str:
        return (f"{self.arm} case {self.index} ({self.kind}: step {self.step * 1e3:.1f} mm, "
                f"turn {math.degrees(self.turn):.1f}°)")


def line_is_clear(chain: rc.Chain, q0: np.ndarray, T0: np.ndarray, T1: np.ndarray) -> bool:
    """The straight pose interpolation T0 → T1 has a continuous joint path from q0 that
    stays `LINE_MARGIN` inside the (finite) range with scaled σ_min ≥ `LINE_SIGMA`."""
    lo = np.where(np.isfinite(chain.lower), chain.lower + LINE_MARGIN, -np.inf)
    hi = np.where(np.isfinite(chain.upper), chain.upper - LINE_MARGIN, np.inf)
    q = q0
    for s in np.linspace(0.0, 1.0, LINE_SAMPLES)[1:]:
        res = rc.ik(chain, interpolate(T0, T1, s), q, tol=(1e-9, 1e-9))
        if not res.converged or np.max(np.abs(res.q - q)) > 0.25:
            return False
        q = res.q
        if np.any(q < lo) or np.any(q > hi) or servo_arms.sigma_min(chain, q) < LINE_SIGMA:
            return False
    return True


def make_cases(arm: str, chain: rc.Chain, *, steps: int, turns: int, seed: int = 0,
               tries: int = 200) -> list[Case]:
    """``steps`` step cases then ``turns`` pure-turn cases for ``chain`` (see the module
    docstring), seeded by ``seed`` and the arm's name (so adding an arm changes no other
    arm's cases)."""
    rng = np.random.default_rng([seed, *arm.encode()])
    cases: list[Case] = []
    for kind, count in (("step", steps), ("turn", turns)):
        made = 0
        for _ in range(tries * max(count, 1)):
            if made == count:
                break
            q0 = servo_arms.regular_start(chain, rng, sigma=START_SIGMA)
            T0 = chain.fk(q0)
            if kind == "step":
                L = float(rng.uniform(*STEP_RANGE))
                turn = float(rng.uniform(0.0, MAX_TURN))
                d = rng.normal(size=3)
                d /= np.linalg.norm(d)
            else:
                L, d = 0.0, np.zeros(3)
                turn = float(rng.uniform(*PURE_TURN))
            T1 = T0.copy()
            T1[:3, 3] += L * d
            T1[:3, :3] = _rot(rng.normal(size=3), turn) @ T0[:3, :3]
            if line_is_clear(chain, q0, T0, T1):
                cases.append(Case(arm, len(cases), kind, q0, T1, L, turn))
                made += 1
    return cases


@dataclass(frozen=True)
class Outcome:
    """What one run measured (see the module docstring); lengths [m], angles [rad]."""

    case: Case
    smoothing: bool
    dt: float
    status: str                 # the last command's status
    reason: str                 # the last command's reason
    reached: float              # s: time of the first "target-reached" state (inf: never)
    t_end: float                # s: time of the last state
    segment: float              # max distance from the straight segment
    orientation: float          # max angle from the geodesic
    overshoot: float            # max overshoot along the step (0 for a pure turn)
    rot_overshoot: float        # max rotational progress beyond the turn
    sync: float                 # max |translational − rotational progress| (NaN if not measured)
    vratio: float               # max |q̇|/vmax of cmd.qd
    aratio_cmd: float           # max |q̈|/amax of cmd.qdd
    aratio_diff: float          # max |Δq̇/dt|/amax
    beyond: float               # worst excursion of q beyond its range (≤ 0: inside)
    final_p: float              # position error at the last state
    final_o: float              # orientation error at the last state
    statuses: dict = field(default_factory=dict)   # status → cycles

    @property
    def where(self) -> str:
        return f"{self.case.label}, smoothing={self.smoothing}, dt={self.dt * 1e3:g} ms"

    def violations(self, *, straight: bool = True) -> list[str]:
        """The acceptance criteria this run broke, each as 'what: measured vs allowed'.
        ``straight=False`` (a blocked line) judges the limits and the report only."""
        c = self.case
        out = []
        if straight:
            if not self.reached <= DURATION:
                out.append(f"not reached in {DURATION:g} s: final status {self.status!r} at "
                           f"t = {self.t_end:.3f} s ({self.reason or 'no reason'}); "
                           f"{self.final_p * 1e3:.3g} mm / {math.degrees(self.final_o):.3g}° from "
                           f"the target")
            if self.segment > segment_allowed(c.step):
                out.append(f"off the straight segment by {self.segment * 1e3:.3f} mm "
                           f"(allowed {segment_allowed(c.step) * 1e3:.3f} mm)")
            if self.overshoot > overshoot_allowed(c.step):
                out.append(f"overshoot {self.overshoot * 1e3:.3f} mm along the step "
                           f"(allowed {overshoot_allowed(c.step) * 1e3:.3f} mm)")
            if self.orientation > orientation_allowed(c.turn):
                out.append(f"off the geodesic rotation by {math.degrees(self.orientation):.3f}° "
                           f"(allowed {math.degrees(orientation_allowed(c.turn)):.3f}°)")
        elif not (self.reached <= DURATION
                  or (self.status in TERMINAL[1:] and self.reason and self.t_end <= DURATION)):
            out.append(f"blocked line neither reached nor reported within {DURATION:g} s: "
                       f"final status {self.status!r} ({self.reason or 'no reason'})")
        if self.vratio > 1.0 + REL:
            out.append(f"|q̇|/vmax = {self.vratio:.9g} (allowed 1)")
        if self.aratio_cmd > 1.0 + REL:
            out.append(f"|cmd.qdd|/amax = {self.aratio_cmd:.9g} (allowed 1)")
        if self.aratio_diff > 1.0 + REL:
            out.append(f"|Δq̇/dt|/amax = {self.aratio_diff:.9g} (allowed 1)")
        if self.beyond > 1e-12:
            out.append(f"q beyond its range by {self.beyond:.3g} rad (allowed 0)")
        return out

    def summary(self) -> str:
        return (f"status {self.status!r}, reached {self.reached:.3f} s, segment "
                f"{self.segment * 1e3:.3f} mm, geodesic {math.degrees(self.orientation):.3f}°, "
                f"overshoot {self.overshoot * 1e3:.3f} mm, rot. overshoot "
                f"{math.degrees(self.rot_overshoot):.3f}°, sync {self.sync:.3f}, |q̇|/vmax "
                f"{self.vratio:.4f}, |q̈|/amax {self.aratio_cmd:.4f} (cmd) {self.aratio_diff:.4f} "
                f"(Δq̇), statuses {self.statuses}")


def geodesic_deviation(R0: np.ndarray, R1: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For rotations R (..., 3, 3): the angle to the closest rotation of the geodesic
    R0 → R1 and the rotational progress φ (unclipped) along it [rad] (module docstring)."""
    r = so3_log(R0.T @ R1)
    theta = float(np.linalg.norm(r))
    a = r / theta if theta > 0.0 else np.zeros(3)
    quat = quat_from_rotation(np.swapaxes(R0, -1, -2) @ R)     # (..., 4), w ≥ 0
    w, va = quat[..., 0], quat[..., 1:] @ a
    phi = 2.0 * np.arctan2(va, w)
    half = 0.5 * np.clip(phi, 0.0, theta)
    dot = np.abs(w * np.cos(half) + va * np.sin(half))
    # 2 arccos|dot|: resolves angles down to ~1e-8 rad, far below the tolerance
    ang = 2.0 * np.arccos(np.clip(dot, 0.0, 1.0))
    return ang, phi


def run_case(chain: rc.Chain, case: Case, *, smoothing: bool, dt: float,
             duration: float = DURATION, solver=None) -> Outcome:
    """Run the user's loop on ``case`` and measure it (module docstring)."""
    ctrl = rc.ResolvedRateController(chain, solver=solver, smoothing=smoothing)
    T = case.target
    q = np.array(case.q0, dtype=float)
    steps = int(round(duration / dt))
    qs, qds, qdds = [q], [], []
    statuses: dict[str, int] = {}
    reached = math.inf
    cmd = None
    for k in range(steps):
        cmd = ctrl.step(q, target=T, dt=dt)
        qds.append(np.array(cmd.qd))
        qdds.append(np.array(cmd.qdd))
        statuses[cmd.status] = statuses.get(cmd.status, 0) + 1
        q = np.array(cmd.q_next)
        qs.append(q)
        if cmd.status in TERMINAL:
            if cmd.status == "target-reached":
                reached = k * dt
            break
    assert cmd is not None
    Q, QD, QDD = np.array(qs), np.array(qds), np.array(qdds)
    poses = chain.fk(Q)
    P, R = poses[:, :3, 3], poses[:, :3, :3]
    T0 = chain.fk(case.q0)
    p0, p1 = T0[:3, 3], T[:3, 3]
    d = p1 - p0
    L = float(np.linalg.norm(d))
    rel = P - p0
    if L > 0.0:
        u = d / L
        along = rel @ u
        closest = np.clip(along, 0.0, L)
        seg = np.linalg.norm(rel - closest[:, None] * u, axis=1)
        overshoot = max(float(np.max(along)) - L, 0.0)
    else:
        along = np.zeros(len(P))
        seg = np.linalg.norm(rel, axis=1)
        overshoot = 0.0
    ang, phi = geodesic_deviation(T0[:3, :3], T[:3, :3], R)
    theta = case.turn
    sync = math.nan
    if L > 0.0 and theta >= math.radians(5.0):
        sync = float(np.max(np.abs(along / L - phi / theta)))
    inv_v = 1.0 / chain.vmax
    inv_a = 1.0 / chain.amax
    dqd = np.diff(np.vstack([np.zeros(chain.dof), QD]), axis=0) / dt
    e = rc.spatial.pose_error(T, poses[-1])
    return Outcome(
        case=case, smoothing=smoothing, dt=dt, status=cmd.status, reason=cmd.reason,
        reached=reached, t_end=(len(Q) - 1) * dt, segment=float(np.max(seg)),
        orientation=float(np.max(ang)), overshoot=overshoot,
        rot_overshoot=max(float(np.max(phi)) - theta, 0.0), sync=sync,
        vratio=float(np.max(np.abs(QD) * inv_v)), aratio_cmd=float(np.max(np.abs(QDD) * inv_a)),
        aratio_diff=float(np.max(np.abs(dqd) * inv_a)),
        beyond=float(np.max(np.maximum(Q - chain.upper, chain.lower - Q))),
        final_p=float(np.linalg.norm(e[:3])), final_o=float(np.linalg.norm(e[3:])),
        statuses=statuses)


# --- blocked lines: the straight line passes a singularity or leaves the workspace ----------

def blocked_cases() -> list[tuple[str, rc.Chain, Case]]:
    """Targets whose straight line is blocked (judged with ``straight=False``: reached, or a
    terminal status with a reason, within 4 s; the limits always):

    * ``ur5e-wrist-line``: the UR5e line of ``ratectl demo`` that passes 0.01 rad from the
      wrist singularity (q5 = 0), its end as the target;
    * ``ur5e-out-of-reach``: a target 0.6 m beyond the tool, outside the workspace;
    * ``panda-through-limit``: the Panda tool 0.25 m down from the ready pose with a 45° turn
      about the tool z axis plus what joint 7 can give (its range ends on the way).
    """
    from ratectl.cli.demo import wrist_line

    out = []
    sc = wrist_line("ur5e")
    T0 = sc.chain.fk(sc.q0)
    T1 = np.array(sc.path.end)
    L = float(np.linalg.norm(T1[:3, 3] - T0[:3, 3]))
    turn = float(np.linalg.norm(so3_log(T0[:3, :3].T @ T1[:3, :3])))
    out.append(("ur5e-wrist-line", sc.chain,
                Case("builtin:ur5e", 0, "blocked", np.array(sc.q0, dtype=float), T1, L, turn)))
    ur5e = rc.robots.ur5e()
    q0 = np.array([0.3, -1.2, 1.5, -1.9, -1.4, 0.6])
    T0 = ur5e.fk(q0)
    T1 = T0.copy()
    T1[:3, 3] += 0.6 * T0[:3, 3] / np.linalg.norm(T0[:3, 3])
    out.append(("ur5e-out-of-reach", ur5e, Case("builtin:ur5e", 1, "blocked", q0, T1, 0.6, 0.0)))
    panda = rc.robots.panda()
    q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 2.6])
    T0 = panda.fk(q0)
    T1 = T0.copy()
    T1[:3, 3] += [0.0, 0.0, -0.25]
    T1[:3, :3] = T0[:3, :3] @ rc.spatial.rotz(math.radians(45.0))
    out.append(("panda-through-limit", panda,
                Case("builtin:panda", 2, "blocked", q0, T1, 0.25, math.radians(45.0))))
    return out


# --- the table -------------------------------------------------------------------------------

def sweep(arms: dict, *, steps: int, turns: int, seed: int = 0, dts=(1e-3, 4e-3),
          smoothings=(False, True)) -> list[Outcome]:
    """Every case of every arm, with every smoothing and dt."""
    outs = []
    for name, factory in arms.items():
        chain = factory()
        for case in make_cases(name, chain, steps=steps, turns=turns, seed=seed):
            for smoothing in smoothings:
                for dt in dts:
                    outs.append(run_case(chain, case, smoothing=smoothing, dt=dt))
    return outs


def table(outs: list[Outcome]) -> str:
    """One row per (arm, smoothing, dt): runs failed, the worst of each measure (the
    segment and overshoot as a fraction of what is allowed), the statuses at the end."""
    groups: dict[tuple, list[Outcome]] = {}
    for o in outs:
        groups.setdefault((o.case.arm, o.smoothing, o.dt), []).append(o)
    head = (f"{'arm':18s} {'smooth':6s} {'dt':>4s} {'fail':>6s} {'seg mm':>8s} {'seg/al':>7s} "
            f"{'geo °':>7s} {'over mm':>8s} {'ov/al':>6s} {'t_reach':>7s} {'v/vmax':>7s} "
            f"{'a/amax':>7s} {'Δa/amax':>7s} {'range':>5s}  final statuses")
    lines = [head, "-" * len(head)]
    for (arm, sm, dt), os_ in groups.items():
        fails = sum(1 for o in os_ if o.violations())
        seg = max(o.segment for o in os_)
        segr = max(o.segment / segment_allowed(o.case.step) for o in os_)
        geo = max(o.orientation for o in os_)
        ov = max(o.overshoot for o in os_)
        ovr = max(o.overshoot / overshoot_allowed(o.case.step) for o in os_)
        tr = max(o.reached for o in os_)
        fin: dict[str, int] = {}
        for o in os_:
            fin[o.status] = fin.get(o.status, 0) + 1
        lines.append(
            f"{arm:18s} {'on' if sm else 'off':6s} {dt * 1e3:4g} {fails:3d}/{len(os_):<2d} "
            f"{seg * 1e3:8.3f} {segr:7.2f} {math.degrees(geo):7.3f} {ov * 1e3:8.3f} {ovr:6.2f} "
            f"{tr:7.3f} {max(o.vratio for o in os_):7.4f} {max(o.aratio_cmd for o in os_):7.4f} "
            f"{max(o.aratio_diff for o in os_):7.4f} "
            f"{'ok' if max(o.beyond for o in os_) <= 1e-12 else 'OUT':>5s}  "
            + ", ".join(f"{k} {v}" for k, v in sorted(fin.items())))
    return "\n".join(lines)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--slow", action="store_true", help="the RATECTL_SLOW=1 size")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--arm", action="append", help="only these arms (repeatable)")
    ap.add_argument("--failures", action="store_true", help="list every failing run")
    args = ap.parse_args(argv)
    size = SLOW_SIZE if args.slow else DEFAULT_SIZE
    arms = servo_arms.sweep_arms()
    if args.arm:
        arms = {k: v for k, v in arms.items() if k in args.arm or k.split(":")[1] in args.arm}
    t0 = time.perf_counter()
    outs = sweep(arms, seed=args.seed, **size)
    print(f"straight-approach sweep: {len(outs)} runs ({size['steps']} steps + {size['turns']} "
          f"pure turns per arm, seed {args.seed}), {time.perf_counter() - t0:.0f} s")
    print(table(outs))
    bad = [o for o in outs if o.violations()]
    print(f"\n{len(bad)} of {len(outs)} runs break a criterion")
    if args.failures:
        for o in bad:
            print(f"- {o.where}: " + "; ".join(o.violations()))
    print("\nblocked lines (reached, or reported within 4 s):")
    for name, chain, case in blocked_cases():
        for smoothing in (False, True):
            o = run_case(chain, case, smoothing=smoothing, dt=1e-3)
            v = o.violations(straight=False)
            print(f"- {name} smoothing={smoothing}: {o.status!r} at {o.t_end:.3f} s "
                  f"({o.reason or 'no reason'}); {'; '.join(v) if v else 'ok'}")


if __name__ == "__main__":
    main()
