"""Targets that move, then stop; switched targets; a jittered period.

A seeded sweep on random 6- and 7-joint DH arms (`servo_arms.random_chain`) and the
built-ins with six or more joints, smoothing off and on. The target is ``fk(q_T(t))`` of a
joint path q_T from a regular start q0 (so every target, the final one included, is a pose
the arm can reach, inside its range):

* ``sinusoid``: q_T = q0 + sin(2π f t)·Δ (f 0.4–1 Hz, the tool swinging 4–10 cm), which
  stops at a peak of the swing (the target's speed is zero there), after 1–2.5 periods;
* ``drift``: q_T = q0 + (t/t_s)·Δ, the tool drifting at 5–20 cm/s, stopping at t_s;
* ``switch``: q0 + Δ_A for 0.1–0.6 s, then q0 + Δ_B (another 4–10 cm step) for good.

The loop is the user's with a jittered period, ``dt_k = dt·U(0.5, 1.5)`` (dt 1, 2 or 4 ms):
``cmd = ctrl.step(q, target=T(t), dt=dt_k); q = cmd.q_next; t += dt_k``, until a terminal
status after the target has stopped (at t_s), or t_s + 6 s. Every run must:

* end with ``target-reached`` or ``target-unreachable`` within 6 s of t_s;
* hold |q̇| ≤ vmax and |q̈| ≤ amax (``cmd.qdd`` and (q̇_k − q̇_{k−1})/dt_k over the real
  periods; 1e-9 relative) and the range, in every cycle;
* never report ``limit-recovery`` (no fault is injected);
* never be farther from the final target than when it stopped, beyond what the motion the
  arm had then can carry it: position ‖p − p_f‖ ≤ d(t_s) + 1 mm + B_p and orientation
  ∠(R R_fᵀ) ≤ θ(t_s) + 0.1° + B_R. B_p = T_b·Σ_i ‖J_v,i‖ w_i (B_R with J_ω): T_b is the
  longest time-optimal stop of a joint from its velocity v_i and acceleration a_i at t_s
  (jerk-limited with smoothing: first a_i → 0, which adds w_i − |v_i| = a_i²/(2 jmax_i) of
  speed when a_i speeds the joint up), and w_i the fastest the joint moves on that stop;
  a synchronised stop of all joints takes T_b, so the tool covers at most B_p meanwhile.

Default: 2 draws per (arm, scenario, smoothing) on 3 random arms and the built-ins;
``RATECTL_SLOW=1`` adds 10 draws each on other seeds and 8 random arms.
"""

from __future__ import annotations

import functools
import math
import os
from dataclasses import dataclass

import numpy as np
import pytest

import ratectl as rc
from ratectl.spatial import rotation_angle

from . import servo_arms

SETTLE = 6.0        # s after the target stops
REL = 1e-9
SCENARIOS = ("sinusoid", "drift", "switch")


def arms(n_random: int) -> dict:
    out = {f"random{i}": (lambda i=i: servo_arms.random_chain(np.random.default_rng([7, i]), 6 + i % 2,
                                                             name=f"random{i}"))
           for i in range(n_random)}
    out.update(servo_arms.builtin_arms())
    return out


@functools.cache
def _arm(name: str) -> rc.Chain:
    return {**arms(8)}[name]()


def _tool_scale(chain, q, d):
    """Joint offset along the direction d that moves the tool point 1 m (linearised)."""
    v = np.linalg.norm(chain.jacobian(q)[:3] @ d)
    return 1.0 / max(v, 1e-3)


@dataclass(frozen=True)
class Scenario:
    kind: str
    q0: np.ndarray
    dt: float
    t_stop: float
    params: tuple
    seed: int

    def q_target(self, t: float) -> np.ndarray:
        if self.kind == "sinusoid":
            f, delta = self.params
            return self.q0 + math.sin(2.0 * math.pi * f * min(t, self.t_stop)) * delta
        if self.kind == "drift":
            (delta,) = self.params
            return self.q0 + min(t / self.t_stop, 1.0) * delta
        qa, qb = self.params
        return qa if t < self.t_stop else qb

    def label(self, arm: str, smoothing: bool) -> str:
        return (f"{arm} {self.kind} seed {self.seed} (stops at {self.t_stop:.3f} s), "
                f"smoothing={smoothing}, dt {self.dt * 1e3:g} ms × U(0.5, 1.5)")


def make_scenario(chain, kind: str, seed: int) -> Scenario:
    rng = np.random.default_rng([seed, *kind.encode(), *chain.name.encode()])
    q0 = servo_arms.regular_start(chain, rng, sigma=0.05, margin=0.6)
    dt = float(rng.choice([1e-3, 2e-3, 4e-3]))

    def offset(lo, hi):
        d = rng.normal(size=chain.dof)
        d /= np.linalg.norm(d)
        step = float(rng.uniform(lo, hi)) * _tool_scale(chain, q0, d)
        return d * min(step, 0.5 / float(np.max(np.abs(d))))   # ≤ 0.5 rad per joint

    if kind == "sinusoid":
        f = float(rng.uniform(0.4, 1.0))
        periods = int(rng.integers(1, 3))
        t_stop = (periods + 0.25) / f          # a peak of the swing: the target at rest
        return Scenario(kind, q0, dt, t_stop, (f, offset(0.04, 0.10)), seed)
    if kind == "drift":
        delta = offset(0.05, 0.2)
        speed = float(rng.uniform(0.05, 0.2))
        length = float(np.linalg.norm(chain.jacobian(q0)[:3] @ delta))
        return Scenario(kind, q0, dt, max(length / speed, 0.2), (delta,), seed)
    t_stop = float(rng.uniform(0.1, 0.6))
    return Scenario(kind, q0, dt, t_stop, (q0 + offset(0.04, 0.10), q0 + offset(0.04, 0.10)), seed)


@dataclass(frozen=True)
class Result:
    final: str
    t_terminal: float           # s after the stop (inf: none)
    vratio: float
    aratio_cmd: float
    aratio_diff: float
    beyond: float
    recovery: int               # cycles in limit-recovery
    grow_p: float               # max (‖p − p_f‖ − allowance) after the stop [m]; ≤ 0 passes
    grow_o: float               # the same for the orientation [rad]
    d_stop: float               # ‖p − p_f‖ at the stop [m]
    d_max: float                # max ‖p − p_f‖ after the stop [m]
    reason: str

    def violations(self) -> list[str]:
        out = []
        if not self.t_terminal <= SETTLE:
            out.append(f"no terminal status within {SETTLE:g} s of the stop (final "
                       f"{self.final!r}: {self.reason or 'no reason'})")
        if self.vratio > 1 + REL:
            out.append(f"|q̇|/vmax = {self.vratio:.9g}")
        if self.aratio_cmd > 1 + REL:
            out.append(f"|cmd.qdd|/amax = {self.aratio_cmd:.9g}")
        if self.aratio_diff > 1 + REL:
            out.append(f"|Δq̇/dt_k|/amax = {self.aratio_diff:.9g}")
        if self.beyond > 1e-12:
            out.append(f"q beyond its range by {self.beyond:.3g}")
        if self.recovery:
            out.append(f"'limit-recovery' in {self.recovery} cycles without a fault")
        if self.grow_p > 0.0:
            out.append(f"moved {self.d_max * 1e3:.1f} mm from the final target after it stopped "
                       f"{self.d_stop * 1e3:.1f} mm away (beyond the allowance by "
                       f"{self.grow_p * 1e3:.2f} mm)")
        if self.grow_o > 0.0:
            out.append(f"turned away from the final target by {math.degrees(self.grow_o):.3f}° "
                       "beyond the allowance")
        return out


def braking_allowance(chain, J, qd, qdd, smoothing: bool) -> tuple[float, float]:
    """(B_p [m], B_R [rad]) of the module docstring for the joint state (q̇, q̈) at J."""
    v = np.abs(qd)
    a = np.where(qd >= 0.0, qdd, -qdd)          # > 0: speeding up
    A = chain.amax
    if smoothing:
        Jm = chain.jmax
        ap = np.maximum(a, 0.0)
        w = v + ap * ap / (2.0 * Jm)
        t = ap / Jm + np.where(w <= A * A / Jm, 2.0 * np.sqrt(w / Jm), w / A + A / Jm)
    else:
        w = v
        t = v / A
    Tb = float(np.max(t))
    return (Tb * float(np.linalg.norm(J[:3], axis=0) @ w),
            Tb * float(np.linalg.norm(J[3:], axis=0) @ w))


def run(chain, sc: Scenario, *, smoothing: bool) -> Result:
    rng = np.random.default_rng([sc.seed, 99])
    ctrl = rc.ResolvedRateController(chain, smoothing=smoothing)
    qf = sc.q_target(math.inf)
    Tf = chain.fk(qf)
    q = np.array(sc.q0, dtype=float)
    qd_prev = np.zeros(chain.dof)
    t = 0.0
    vr = acr = adr = 0.0
    beyond = -math.inf
    recovery = 0
    t_terminal = math.inf
    stop_state = None          # (d, θ, allowance_p, allowance_o) at the stop
    grow_p = grow_o = -math.inf
    d_max = 0.0
    qdd_prev = np.zeros(chain.dof)
    cmd = None
    while t < sc.t_stop + SETTLE:
        dt = sc.dt * float(rng.uniform(0.5, 1.5))
        T = chain.fk(sc.q_target(t))
        cmd = ctrl.step(q, target=T, dt=dt)
        qd = np.array(cmd.qd)
        vr = max(vr, float(np.max(np.abs(qd) / chain.vmax)))
        acr = max(acr, float(np.max(np.abs(cmd.qdd) / chain.amax)))
        adr = max(adr, float(np.max(np.abs(qd - qd_prev) / dt / chain.amax)))
        recovery += cmd.status == "limit-recovery"
        if t >= sc.t_stop:
            Tq, J = chain.fk_jacobian(q)
            d = float(np.linalg.norm(Tq[:3, 3] - Tf[:3, 3]))
            th = float(rotation_angle(Tq[:3, :3] @ Tf[:3, :3].T))
            if stop_state is None:       # the motion the arm had when the target stopped
                bp, bo = braking_allowance(chain, J, qd_prev, qdd_prev, smoothing)
                stop_state = (d, th, d + 1e-3 + bp, th + math.radians(0.1) + bo)
            grow_p = max(grow_p, d - stop_state[2])
            grow_o = max(grow_o, th - stop_state[3])
            d_max = max(d_max, d)
            if cmd.status in ("target-reached", "target-unreachable"):
                t_terminal = t - sc.t_stop
                break
        qd_prev = qd
        qdd_prev = np.array(cmd.qdd)
        q = np.array(cmd.q_next)
        beyond = max(beyond, float(np.max(np.maximum(q - chain.upper, chain.lower - q))))
        t += dt
    assert cmd is not None and stop_state is not None
    return Result(cmd.status, t_terminal, vr, acr, adr, beyond, recovery, grow_p, grow_o,
                  stop_state[0], d_max, cmd.reason)


def _judge(arm: str, kind: str, smoothing: bool, seeds) -> None:
    chain = _arm(arm)
    failures = []
    for seed in seeds:
        sc = make_scenario(chain, kind, seed)
        res = run(chain, sc, smoothing=smoothing)
        v = res.violations()
        if v:
            failures.append(f"{sc.label(arm, smoothing)}: " + "; ".join(v))
    assert not failures, f"{len(failures)} of {len(seeds)} runs:\n" + "\n".join(failures)


DEFAULT_ARMS = [*(f"random{i}" for i in range(3)), *servo_arms.builtin_arms()]
SLOW_ARMS = [*(f"random{i}" for i in range(8)), *servo_arms.builtin_arms()]


def _grid(names):
    return [(a, k, s) for a in names for k in SCENARIOS for s in (False, True)]


def _ids(grid):
    return [f"{a}-{k}-{'smooth' if s else 'plain'}" for a, k, s in grid]


@pytest.mark.parametrize(("arm", "kind", "smoothing"), _grid(DEFAULT_ARMS), ids=_ids(_grid(DEFAULT_ARMS)))
def test_moving_then_stopped_targets_end_well(arm, kind, smoothing):
    _judge(arm, kind, smoothing, seeds=range(2))


@pytest.mark.slow
@pytest.mark.skipif(not os.environ.get("RATECTL_SLOW"), reason="full sweep: set RATECTL_SLOW=1")
@pytest.mark.parametrize(("arm", "kind", "smoothing"), _grid(SLOW_ARMS), ids=_ids(_grid(SLOW_ARMS)))
def test_moving_then_stopped_targets_end_well_full_sweep(arm, kind, smoothing):
    _judge(arm, kind, smoothing, seeds=range(100, 110))


def test_a_smoothed_arm_held_off_its_line_near_the_target_settles():
    """A switched target on a 7-joint random arm (ℓ = 2.26 m, so 20 mm of weighted lag is
    0.5° of rotation) with smoothing at 4 ms × U(0.5, 1.5): the arm is held off its line by
    the filter's lag near the target and the line restarts from where the arm is. It must
    restart from the arm's velocity only: with the arm's acceleration carried on, the short
    line left no jerk-limited stop on it, and the arm circled the target for good."""
    _judge("random3", "switch", True, seeds=[108])
