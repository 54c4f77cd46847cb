"""Teleoperation: stream a tool twist to a robot with ``rc.run`` — MuJoCo, or a Franka FR3.

A joystick or a spacemouse sends a twist [v; ω] every few milliseconds; here a scripted
operator does: 1 s along +y at 5 cm/s, 1 s turning about the vertical at 0.3 rad/s while
moving down, then the stream ends (the callable returns None) and the robot comes to rest.
The twist is in base axes at the tool point, as MoveIt Servo's ``base_link`` frame.

    python examples/11_teleop_twist.py          # the UR5e in MuJoCo (headless)
    python examples/11_teleop_twist.py fr3      # also franky-sim's simulated FR3 on loopback

Every run is bounded: by the stream's end, by ``duration`` and by the watchdog ``timeout``
(no fresh state for 0.1 s: safe halt). The plot (``examples/out/11_teleop_twist.png``) shows
the streamed against the measured tool velocity and the controller's status per cycle.
``RATECTL_FAST=1`` streams half as long.
"""

import math
import os
import sys
from pathlib import Path

import numpy as np

import ratectl as rc

FAST = os.environ.get("RATECTL_FAST") == "1"
OUT = Path(__file__).resolve().parent / "out"
T_SEG = 0.5 if FAST else 1.0  # length of each segment of the stream [s]


def operator(t: float):
    """The twist [v; ω] at time t [s] (base axes, at the tool point), or None: the stream ends."""
    if t < T_SEG:
        return np.array([0.0, 0.05, 0.0, 0.0, 0.0, 0.0])
    if t < 2 * T_SEG:
        return np.array([0.0, 0.0, -0.03, 0.0, 0.0, 0.3])
    return None


def stream(driver, name: str) -> rc.Execution:
    ex = rc.run(driver, twist=operator, rate_hz=500.0, timeout=0.1, duration=3 * T_SEG)
    print(f"--- {name}")
    print(ex.summary())
    return ex


def mujoco_run() -> rc.Execution:
    from ratectl.interop.mujoco import MujocoDriver

    arm = rc.robots.ur5e()
    q0 = np.array([0.3, -1.3, 1.6, -1.8, -1.5, 0.2])
    return stream(MujocoDriver(arm, q0=q0, period=0.002), "UR5e in MuJoCo")


def fr3_run() -> rc.Execution:
    from ratectl.drivers import FrankyDriver, FrankySim

    with FrankySim() as sim:
        return stream(FrankyDriver(sim.hostname), "FR3 on franky-sim")


def plot(runs: dict, file: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, len(runs), figsize=(6 * len(runs), 5.5), squeeze=False)
    for col, (name, ex) in enumerate(runs.items()):
        ax = axes[0, col]
        streamed = np.array([operator(t) if operator(t) is not None else np.zeros(6) for t in ex.t])
        ax.plot(ex.t, streamed[:, 1] * 1e3, "k--", lw=1, label="streamed v_y")
        ax.plot(ex.t, streamed[:, 2] * 1e3, "k:", lw=1, label="streamed v_z")
        ax.plot(ex.t, ex.info["twist_linear_error"] * 1e3, color="C3", lw=1,
                label="|measured − streamed| linear")
        ax.set_ylabel("[mm/s]")
        ax.set_title(name, fontsize=10)
        ax.legend(fontsize=7)
        ax = axes[1, col]
        names = sorted(set(ex.statuses), key=rc.control.STATUSES.index)
        ax.plot(ex.t, [names.index(s) for s in ex.statuses], drawstyle="steps-post")
        ax.set_yticks(range(len(names)), names, fontsize=7)
        ax.set_xlabel("t [s]")
    fig.tight_layout()
    file.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(file, dpi=100)
    plt.close(fig)
    print(f"plot written to {file}")


def main(argv: list[str]) -> None:
    runs = {"UR5e in MuJoCo": mujoco_run()}
    if "fr3" in argv:
        runs["FR3 on franky-sim"] = fr3_run()
    for name, ex in runs.items():
        lin = ex.info["twist_linear_error"]
        print(f"{name}: median tracking {np.nanmedian(lin) * 1e3:.2f} mm/s, "
              f"completed={ex.completed} ({ex.message}); ran {ex.t[-1]:.2f} s, "
              f"{math.degrees(float(np.nanmax(ex.info['twist_angular_error']))):.2f}°/s worst angular")
    plot(runs, OUT / "11_teleop_twist.png")


if __name__ == "__main__":
    main(sys.argv[1:])
