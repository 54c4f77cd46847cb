"""05 — A user control loop at 1 kHz with ``controller.step``, timed.

This is the loop a user writes around a robot driver: every millisecond, read q,
ask the controller for a command, send ``cmd.qd`` (or ``cmd.q_next``) to the robot.
Here the "robot" is perfect (the next measured q is ``cmd.q_next``), and the target
moves on a horizontal circle (radius 5 cm, speeding up smoothly to 0.1 m/s) with its
velocity as feed-forward.

The controller runs the default adaptive-DLS solver, the chain's velocity,
acceleration and position limits, and Ruckig jerk-limited smoothing. The script prints
the median / 99th-percentile / worst time per ``step`` call (the budget is 1000 µs at
1 kHz), the tracking error, and the statuses seen, and plots them.

Run: ``python examples/05_control_loop.py`` (``RATECTL_FAST=1``: 0.5 s of loop instead of 4 s).
"""

from __future__ import annotations

import math
import os
import time
from collections import Counter
from pathlib import Path

import numpy as np

import ratectl as rc

FAST = os.environ.get("RATECTL_FAST") == "1"
OUT = Path(__file__).resolve().parent / "out"
DT = 1e-3            # control period [s]: 1 kHz
RADIUS = 0.05        # [m]
SPEED = 0.1          # tangential speed of the target [m/s]


RAMP = 0.3           # the target's speed rises smoothly from 0 over this time [s]


def target(T0: np.ndarray, t: float):
    """Target pose and twist at time t: a horizontal circle through T0's position, its
    angular rate ramped up as w·(1 − cos(πt/RAMP))/2 during the first RAMP seconds."""
    w = SPEED / RADIUS
    if t < RAMP:
        phi = w * (t / 2 - RAMP / (2 * math.pi) * math.sin(math.pi * t / RAMP))
        phid = w * (1 - math.cos(math.pi * t / RAMP)) / 2
    else:
        phi, phid = w * (t - RAMP / 2), w
    c = T0[:3, 3] - np.array([RADIUS, 0.0, 0.0])
    T = T0.copy()
    T[:3, 3] = c + RADIUS * np.array([math.cos(phi), math.sin(phi), 0.0])
    v = RADIUS * phid * np.array([-math.sin(phi), math.cos(phi), 0.0])
    return T, np.concatenate([v, np.zeros(3)])


def main() -> dict:
    arm = rc.robots.ur5e()
    q = np.array([0.3, -1.3, 1.6, -1.9, -1.2, 0.2])
    T0 = arm.fk(q)
    ctrl = rc.ResolvedRateController(arm, smoothing=True)
    duration = 0.5 if FAST else 4.0
    steps = int(round(duration / DT))
    # warm-up: the first calls compile the chain's kinematic kernels and set up the solver
    for _ in range(20):
        ctrl.step(q, target=T0, dt=DT)
    ctrl.reset()

    tick = np.empty(steps)
    err_p = np.empty(steps)
    err_o = np.empty(steps)
    qd = np.empty((steps, arm.dof))
    statuses: Counter = Counter()
    clock = time.perf_counter
    for k in range(steps):
        T_des, xi = target(T0, k * DT)
        t0 = clock()
        cmd = ctrl.step(q, target=T_des, twist=xi, dt=DT)          # the controller call
        tick[k] = clock() - t0
        q = cmd.q_next                                              # "send" and "measure"
        err_p[k], err_o[k] = cmd.position_error, cmd.orientation_error
        qd[k] = cmd.qd
        statuses[cmd.status] += 1

    us = tick * 1e6
    med, p99, worst = np.median(us), np.percentile(us, 99), us.max()
    settled = slice(int(0.2 / DT), None)          # after the first 0.2 s
    print(f"UR5e, {steps} cycles at {1 / DT:.0f} Hz with Ruckig smoothing and limits")
    print(f"controller.step: median {med:.1f} µs, 99th percentile {p99:.1f} µs, worst {worst:.1f} µs "
          f"({100 * med * 1e-6 / DT:.1f}% of the {DT * 1e6:.0f} µs budget at the median)")
    print(f"tracking error after 0.2 s: max {err_p[settled].max() * 1e3:.3f} mm, "
          f"{math.degrees(err_o[settled].max()):.3f} deg")
    print(f"max |q̇_i|/vmax_i = {np.max(np.abs(qd) / arm.vmax):.3f}")
    print("statuses:", dict(statuses))
    _plot(us, err_p, qd, arm)
    return {"median_us": float(med), "max_error": float(err_p[settled].max())}


def _plot(us, err_p, qd, arm) -> None:
    import matplotlib

    matplotlib.use(os.environ.get("MPLBACKEND", "Agg"))
    import matplotlib.pyplot as plt

    t = np.arange(len(us)) * DT
    fig, ax = plt.subplots(1, 3, figsize=(14, 4))
    ax[0].hist(us, bins=60, color="tab:blue")
    ax[0].axvline(np.median(us), color="k", ls="--", label=f"median {np.median(us):.1f} µs")
    ax[0].set_xlabel("controller.step time [µs]")
    ax[0].set_ylabel("cycles")
    ax[0].set_yscale("log")
    ax[0].legend()
    ax[0].set_title("time per cycle (budget 1000 µs)")
    ax[1].plot(t, err_p * 1e3, color="tab:red")
    ax[1].set_xlabel("t [s]")
    ax[1].set_ylabel("position error [mm]")
    ax[1].set_title("tracking a moving target")
    for i, name in enumerate(arm.joint_names):
        ax[2].plot(t, qd[:, i] / arm.vmax[i], label=name)
    ax[2].legend(fontsize=7, ncol=2)
    ax[2].set_xlabel("t [s]")
    ax[2].set_ylabel("q̇_i / vmax_i")
    ax[2].set_title("joint velocities (Ruckig-smoothed)")
    for a in ax[1:]:
        a.grid(alpha=0.3)
    fig.tight_layout()
    OUT.mkdir(exist_ok=True)
    path = OUT / "05_control_loop.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    print("saved", path)


if __name__ == "__main__":
    main()
