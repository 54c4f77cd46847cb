"""12 — Strict priorities on a 7-axis arm: tool, elbow away from an obstacle, posture.

The Franka Panda of the example-robot-data package (its URDF and collision meshes) has
seven joints for a six-dimensional tool task, so its elbow can move without the tool
seeing it. Three tasks, each on its own priority level:

* priority 0 — the tool pose follows a 20 cm line (a quintic time law, feed-forward twist);
* priority 1 — the elbow (``panda_link4``'s origin) moves 12 cm away from a ball placed
  beside it; the ball is also a hard constraint (``Obstacles``: links 3–5 keep 3 cm);
* priority 2 — a posture (the start configuration) fixes the motion left over.

A lower level never changes what a higher level achieves within the limits: the tool
tracks the line as if it were alone, the elbow uses what the tool leaves free, the
posture what both leave. The figure plots each level's error against time, with the
distance from the ball.

Run: ``python examples/12_priorities.py`` (``RATECTL_FAST=1``: 4 ms period).
Needs the example-robot-data package and coal (``pip install "ratectl[collision]"``).
"""

from __future__ import annotations

import glob
import os
import sys
from pathlib import Path

import numpy as np

import ratectl as rc

FAST = os.environ.get("RATECTL_FAST") == "1"
OUT = Path(__file__).resolve().parent / "out"
HOME = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])


def panda_urdf() -> str:
    """example-robot-data's panda.urdf (installed with pip install example-robot-data)."""
    roots = [os.path.join(p, "cmeel.prefix", "share") for p in sys.path if p]
    roots.append(os.path.join(sys.prefix, "share"))
    for root in roots:
        hits = glob.glob(os.path.join(root, "example-robot-data", "robots", "panda_description", "urdf",
                                      "panda.urdf"))
        if hits:
            return hits[0]
    raise SystemExit("this example needs the example-robot-data package: pip install example-robot-data")


def line_target(T0: np.ndarray, t: float, *, duration: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """The tool pose and twist at time t on a 20 cm line (quintic time law)."""
    s = min(t / duration, 1.0)
    s5 = 10 * s**3 - 15 * s**4 + 6 * s**5
    sd = (30 * s**2 - 60 * s**3 + 30 * s**4) / duration if t < duration else 0.0
    d = np.array([0.0, 0.16, -0.12])
    T = T0.copy()
    T[:3, 3] += s5 * d
    return T, np.concatenate([sd * d, np.zeros(3)])


def main() -> dict:
    urdf = panda_urdf()
    chain = rc.Chain.from_urdf(urdf, tip="panda_hand_tcp").with_limits(
        amax=[15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0])
    dt = 4e-3 if FAST else 1e-3
    T0 = chain.fk(HOME)
    p4 = chain.fk(HOME, link="panda_link4")[:3, 3]
    away = np.array([0.0, -1.0, 0.0])             # the ball sits on the elbow's +y side
    ball = rc.collision.Sphere(p4 - 0.22 * away, 0.06, name="ball")
    obstacles = rc.collision.Obstacles.from_urdf(urdf, chain, [ball], margin=0.03,
                                                 links=["panda_link3", "panda_link4", "panda_link5"])
    tool = rc.tasks.Pose(priority=0)
    elbow = rc.tasks.Position(link="panda_link4", priority=1, gain=3.0, target=p4 + 0.12 * away)
    posture = rc.tasks.Posture(HOME, priority=2, gain=1.0)
    ctrl = rc.ResolvedRateController(chain, tasks=[tool, elbow, posture], collision=[obstacles])
    q = HOME.copy()
    steps = int(round(3.0 / dt))
    log: dict[str, list] = {k: [] for k in ("t", "tool", "elbow", "posture", "ball", "status")}
    for k in range(steps):
        T, xi = line_target(T0, k * dt)
        tool.set_target(T, twist=xi)
        cmd = ctrl.step(q, dt=dt)
        q = cmd.q_next.copy()
        errors = cmd.solve.task_errors                # each task's error norm, in the order given
        log["t"].append((k + 1) * dt)
        on_line = line_target(T0, (k + 1) * dt)[0]
        log["tool"].append(float(np.linalg.norm(chain.fk(q)[:3, 3] - on_line[:3, 3])))
        log["elbow"].append(float(errors[1]))
        log["posture"].append(float(errors[2]))
        log["ball"].append(float(obstacles.distances(q).min()))
        log["status"].append(cmd.status)
    arr = {k: np.array(v) for k, v in log.items() if k != "status"}
    start = float(np.linalg.norm(p4 + 0.12 * away - p4))
    moved = 1.0 - arr["elbow"][-1] / start
    print(f"Panda (example-robot-data), {steps} steps at dt = {dt * 1e3:g} ms")
    print(f"priority 0, tool:    max position error along the line {arr['tool'].max() * 1e3:.3f} mm")
    print(f"priority 1, elbow:   {moved * 100:.0f} % of the way to its target (12 cm away from the ball), "
          f"final error {arr['elbow'][-1] * 1e3:.1f} mm")
    print(f"priority 2, posture: final error {arr['posture'][-1]:.3f} rad (what the tool and elbow leave)")
    print(f"ball: smallest distance from links 3-5 {arr['ball'].min() * 1e3:.1f} mm (margin 30 mm)")
    statuses = {s: log["status"].count(s) for s in dict.fromkeys(log["status"])}
    print(f"statuses: {statuses}")
    plot(arr)
    return arr


def plot(arr: dict) -> None:
    import matplotlib.pyplot as plt

    OUT.mkdir(exist_ok=True)
    fig, ax = plt.subplots(4, 1, figsize=(8, 8.5), sharex=True)
    t = arr["t"]
    ax[0].semilogy(t, np.maximum(arr["tool"] * 1e3, 1e-6), color="C0")
    ax[0].set_ylabel("tool [mm]")
    ax[0].set_title("priority 0: tool position error along the line")
    ax[1].plot(t, arr["elbow"] * 1e3, color="C1")
    ax[1].set_ylabel("elbow [mm]")
    ax[1].set_title("priority 1: elbow distance from its target (away from the ball)")
    ax[2].plot(t, arr["posture"], color="C2")
    ax[2].set_ylabel("posture [rad]")
    ax[2].set_title("priority 2: ‖q_home − q‖")
    ax[3].plot(t, arr["ball"] * 1e3, color="C3")
    ax[3].axhline(30.0, color="k", lw=0.8, ls="--", label="margin")
    ax[3].set_ylabel("ball [mm]")
    ax[3].set_title("distance from the ball (links 3–5), a hard constraint of every level")
    ax[3].legend(loc="upper right")
    ax[3].set_xlabel("time [s]")
    for a in ax:
        a.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(OUT / "12_priorities.png", dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    main()
