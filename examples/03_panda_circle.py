"""03 — A circle with the Panda, within its joint limits, with Ruckig smoothing.

The Franka Panda (7 joints) draws a horizontal circle of radius 15 cm with its
flange pointing down, at 0.5 m/s on a jerk-limited time law. ``rc.follow`` runs the
resolved-rate controller along it (``governor=False``: the path's own time law); the
controller's output goes through a Ruckig jerk-limited velocity filter
(``smoothing=True``), so every joint respects Franka's published velocity,
acceleration *and jerk* limits, and the joint positions stay inside Franka's position
limits (joints 4 and 6 have narrow, asymmetric ranges).

Prints the margins to each kind of limit and the path error; saves a figure with the
tool path, the joint positions inside their ranges, and q̇, q̈, jerk relative to
their limits.

Run: ``python examples/03_panda_circle.py`` (``RATECTL_FAST=1``: 2 ms period, half circle).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

import ratectl as rc

FAST = os.environ.get("RATECTL_FAST") == "1"
OUT = Path(__file__).resolve().parent / "out"
RADIUS = 0.15     # [m]
SPEED = 0.5       # [m/s]


def main() -> dict:
    arm = rc.robots.panda()
    q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])     # Franka's "ready" pose
    T0 = arm.fk(q0)
    dt = 2e-3 if FAST else 1e-3
    circle = rc.paths.Arc(T0, centre=T0[:3, 3] + [0.0, RADIUS, 0.0], axis=[0, 0, 1],
                          angle=math.pi if FAST else 2 * math.pi,
                          speed=SPEED, acceleration=2.0, jerk=20.0)
    ctrl = rc.ResolvedRateController(arm, smoothing=True)
    # the circle's own jerk-limited time law (governor=False): within the limits at this speed
    run = rc.follow(arm, circle, q0, dt=dt, controller=ctrl, governor=False)

    jerk = np.zeros_like(run.qdd)
    jerk[1:] = np.diff(run.qdd, axis=0) / dt
    span = arm.upper - arm.lower
    pos_margin = np.minimum(run.q - arm.lower, arm.upper - run.q).min(axis=0)
    ratios = {
        "velocity": float(np.max(np.abs(run.qd) / arm.vmax)),
        "acceleration": float(np.max(np.abs(run.qdd) / arm.amax)),
        "jerk": float(np.max(np.abs(jerk) / arm.jmax)),
    }
    print(run.summary())
    print("largest fraction of each limit used: "
          + ", ".join(f"{k} {v:.3f}" for k, v in ratios.items()))
    print("closest approach to a position limit per joint [rad]: "
          + np.array2string(pos_margin, precision=3))
    within = all(v <= 1 + 1e-6 for v in ratios.values()) and bool(np.all(pos_margin >= 0))
    print(f"all within limits: {within}")
    _plot(arm, circle, run, jerk, span)
    return {"ratios": ratios, "completed": run.completed}


def _plot(arm, circle, run, jerk, span) -> None:
    import matplotlib

    matplotlib.use(os.environ.get("MPLBACKEND", "Agg"))
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 3, figsize=(15, 8))
    p = arm.fk(run.q)[:, :3, 3]
    ref = np.array([circle.position_at(s) for s in np.linspace(0, circle.length, 200)])
    a = ax[0, 0]
    a.plot(ref[:, 0], ref[:, 1], "k--", lw=1, label="path")
    a.plot(p[:, 0], p[:, 1], color="tab:blue", lw=2, alpha=0.7, label="tool")
    a.set_aspect("equal")
    a.set_xlabel("x [m]")
    a.set_ylabel("y [m]")
    a.set_title("tool path (top view)")
    a.legend()
    a = ax[0, 1]
    a.plot(run.t, (run.q - arm.lower) / span)
    a.axhline(0, color="k", lw=1)
    a.axhline(1, color="k", lw=1)
    a.set_ylim(-0.05, 1.05)
    a.set_ylabel("(q − lower)/(upper − lower)")
    a.set_title("joint positions within their ranges")
    a = ax[0, 2]
    a.plot(run.t, np.asarray(run.position_error) * 1e3, color="tab:red")
    a.set_ylabel("distance from the circle [mm]")
    a.set_title("path error")
    for a, data, lim, name in ((ax[1, 0], run.qd, arm.vmax, "q̇ / vmax"),
                               (ax[1, 1], run.qdd, arm.amax, "q̈ / amax"),
                               (ax[1, 2], jerk, arm.jmax, "jerk / jmax")):
        a.plot(run.t, data / lim)
        a.axhline(1, color="k", ls="--", lw=1)
        a.axhline(-1, color="k", ls="--", lw=1)
        a.set_ylabel(name)
        a.set_title(f"{name} per joint (dashed: limit)")
    for a in ax.ravel()[1:]:
        a.set_xlabel("t [s]")
        a.grid(alpha=0.3)
    ax[1, 0].legend([f"q{i + 1}" for i in range(arm.dof)], fontsize=7, ncol=2)
    fig.suptitle(f"Panda: circle r = {RADIUS} m at {SPEED} m/s, Ruckig-smoothed")
    fig.tight_layout()
    OUT.mkdir(exist_ok=True)
    path = OUT / "03_panda_circle.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    print("saved", path)


if __name__ == "__main__":
    main()
