"""The user's servo loop, measured: step targets on an arm, every limit checked.

One *case* is an arm, a start q0, a step target (1–20 cm in some direction, a turn of up
to 30°), ``smoothing`` off or on and a period dt. `run_case` runs the loop a user
writes, ``cmd = ctrl.step(q, target=T, dt=dt); q = cmd.q_next``, for ``duration`` seconds
and measures what the acceptance asks: the settling time (from then on within 0.1 mm and
0.01° of the target), the overshoot along the step, and the largest ratios |q̇|/vmax and
|q̈|/amax (finite differences of the commanded stream) and the worst excursion beyond a
position limit. Used by ``tests/conformance`` and ``benchmarks/report_servo.py``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

import ratectl as rc

DATA = os.path.join(os.path.dirname(__file__), "..", "data")
POS_TOL = 1e-4                  # m
ORI_TOL = math.radians(0.01)    # rad
MAX_TURN = math.radians(30.0)   # rad


def _franky_fr3_urdf() -> str | None:
    try:
        import franky_sim
    except ImportError:  # pragma: no cover - franky-sim is a test dependency
        return None
    path = os.path.join(os.path.dirname(franky_sim.__file__), "assets", "fr3.urdf")
    return path if os.path.exists(path) else None


def urdf_arms() -> dict:
    """Arms imported from URDF files that carry no acceleration (or jerk) limits."""
    arms = {
        "irb_like": lambda: rc.Chain.from_urdf(os.path.join(DATA, "irb_like.urdf"), tip="tool0"),
        "rail_ur_like": lambda: rc.Chain.from_urdf(os.path.join(DATA, "rail_ur_like.urdf"), tip="tool0"),
        "ur5e_like": lambda: rc.Chain.from_urdf(os.path.join(DATA, "ur5e_like.urdf")),
    }
    fr3 = _franky_fr3_urdf()
    if fr3 is not None:
        arms["fr3_urdf"] = lambda: rc.Chain.from_urdf(fr3, tip="fr3_hand_tcp")
    return arms


def all_arms() -> dict:
    """Name → factory: every built-in arm and the URDF arms."""
    arms = {f"builtin:{k}": v for k, v in rc.robots.BUILTIN.items()}
    arms.update({f"urdf:{k}": v for k, v in urdf_arms().items()})
    return arms


def smoothing_limits(chain):
    """The chain with acceleration and jerk limits where it has none (10 rad/s², 100 rad/s³;
    2 m/s², 20 m/s³ for prismatic joints), as a user would add them for smoothing."""
    if np.all(np.isfinite(chain.amax)) and np.all(np.isfinite(chain.jmax)):
        return chain
    pri = chain.prismatic
    amax = np.where(np.isfinite(chain.amax), chain.amax, np.where(pri, 2.0, 10.0))
    jmax = np.where(np.isfinite(chain.jmax), chain.jmax, np.where(pri, 20.0, 100.0))
    return chain.with_limits(amax=amax, jmax=jmax)


def _rot(axis, angle):
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


@dataclass(frozen=True)
class Case:
    arm: str
    q0: np.ndarray
    target: np.ndarray
    step: float      # m
    turn: float      # rad


def _regular_along(chain, q0, q1, sigma=0.03, margin=0.05) -> bool:
    """q0 → q1 in joint space stays regular and inside the limits with a margin."""
    for s in np.linspace(0.0, 1.0, 11):
        q = q0 + s * (q1 - q0)
        if not np.all((q > chain.lower + margin) & (q < chain.upper - margin)):
            return False
        J = chain.jacobian(q)
        m = min(J.shape)
        if np.linalg.svd(J, compute_uv=False)[m - 1] < sigma:
            return False
    return True


def make_cases(name: str, chain, count: int, *, seed: int = 0, steps=(0.01, 0.2),
               max_turn=MAX_TURN) -> list[Case]:
    """``count`` reachable step targets for ``chain``: a random regular start inside the
    limits, a step of random length in ``steps`` [m] in a random direction and a random
    turn up to ``max_turn``; kept only if `ratectl.ik` reaches it from the start with
    a regular, in-range joint motion. Arms with fewer than 6 joints get targets fk(q1) at a
    joint offset scaled to the step length (their reachable poses)."""
    rng = np.random.default_rng(seed)
    cases: list[Case] = []
    tries = 0
    while len(cases) < count and tries < 400 * count:
        tries += 1
        q0 = chain.random_q(rng=rng)
        q0 = np.clip(q0, chain.lower + 0.3, chain.upper - 0.3)
        if not _regular_along(chain, q0, q0):
            continue
        step = float(rng.uniform(*steps))
        T0 = chain.fk(q0)
        if chain.dof >= 6:
            d = rng.normal(size=3)
            d /= np.linalg.norm(d)
            turn = float(rng.uniform(0.0, max_turn))
            T1 = T0.copy()
            T1[:3, 3] += step * d
            T1[:3, :3] = _rot(rng.normal(size=3), turn) @ T0[:3, :3]
            res = rc.ik(chain, T1, q0, tol=(1e-10, 1e-10))
            if not res.converged or np.max(np.abs(res.q - q0)) > 1.5:
                continue
            q1 = res.q
        else:
            dq = rng.normal(size=chain.dof)
            dp = np.linalg.norm(chain.fk(q0 + 1e-4 * dq)[:3, 3] - T0[:3, 3]) / 1e-4
            if dp < 1e-3:
                continue
            q1 = q0 + dq * step / dp
            T1 = chain.fk(q1)
            step = float(np.linalg.norm(T1[:3, 3] - T0[:3, 3]))
            turn = float(np.linalg.norm(rc.spatial.pose_error(T1, T0)[3:]))
            if step < 0.005 or turn > max_turn:
                continue
        if not _regular_along(chain, q0, q1):
            continue
        cases.append(Case(name, q0, T1, step, turn))
    return cases


@dataclass(frozen=True)
class Outcome:
    settle: float         # s after which the error stays within tolerance (inf: never)
    overshoot: float      # m beyond the target along the step (≥ 0)
    vratio: float         # max |q̇|/vmax
    aratio: float         # max |q̈|/amax (finite differences of the commanded q̇), NaN without amax
    beyond: float         # worst excursion beyond a position limit [rad or m] (≤ 0: inside)
    final_p: float        # m
    final_o: float        # rad

    def ok(self, step: float, *, duration: float = 4.0) -> bool:
        return (self.settle <= duration and self.overshoot <= 0.01 * step + 1e-4
                and self.vratio <= 1.0 + 1e-9 and not self.aratio > 1.0 + 1e-6
                and self.beyond <= 1e-12)


def run_case(chain, case: Case, *, smoothing: bool, dt: float, duration: float = 4.0,
             loop: str = "q_next", hold: float = 0.3) -> Outcome:
    """Run the user's loop on ``case`` and measure it (see the module docstring).
    ``loop="q_next"`` integrates with ``q = cmd.q_next``, ``"euler"`` with ``q += cmd.qd·dt``.
    The run ends early once the pose has stayed within tolerance for ``hold`` seconds with
    the command at rest (|q̇| < 1e-6)."""
    ctrl = rc.ResolvedRateController(chain, smoothing=smoothing)
    T = case.target
    p0 = chain.fk(case.q0)[:3, 3]
    u = T[:3, 3] - p0
    L = float(np.linalg.norm(u))
    u = u / L
    steps = int(round(duration / dt))
    q = case.q0.copy()
    qd_prev = np.zeros(chain.dof)
    inv_v = np.where(np.isfinite(chain.vmax), 1.0 / chain.vmax, 0.0)
    has_a = bool(np.all(np.isfinite(chain.amax)))
    inv_a = np.where(np.isfinite(chain.amax), 1.0 / chain.amax, 0.0)
    vr = ar = 0.0
    beyond = -math.inf
    along = -math.inf
    settle = math.inf
    inside = False
    for k in range(steps):
        cmd = ctrl.step(q, target=T, dt=dt)
        qd = cmd.qd
        vr = max(vr, float(np.max(np.abs(qd) * inv_v)))
        ar = max(ar, float(np.max(np.abs(qd - qd_prev) * inv_a)) / dt)
        qd_prev = qd
        if loop == "euler":
            q = q + qd * dt
        else:
            q = cmd.q_next
        beyond = max(beyond, float(np.max(np.maximum(q - chain.upper, chain.lower - q))))
        Tq = chain.fk(q)
        along = max(along, float((Tq[:3, 3] - p0) @ u))
        e = rc.spatial.pose_error(T, Tq)
        ok = np.linalg.norm(e[:3]) <= POS_TOL and np.linalg.norm(e[3:]) <= ORI_TOL
        if ok and not inside:
            settle = (k + 1) * dt
        elif not ok:
            settle = math.inf
        inside = ok
        if ok and (k + 1) * dt - settle >= hold and float(np.max(np.abs(qd))) < 1e-6:
            break
    e = rc.spatial.pose_error(T, chain.fk(q))
    return Outcome(settle, max(along - L, 0.0), vr, ar if has_a else math.nan, beyond,
                   float(np.linalg.norm(e[:3])), float(np.linalg.norm(e[3:])))
