"""Follow a line with a Franka FR3 through franky — on franky-sim, or on your robot.

The robot is driven over the libfranka network protocol by franky (``pip install
'ratectl[franka]'``). Without an argument the script starts franky-sim's simulated FR3 on
loopback in a process of its own; with a hostname it drives that robot::

    python examples/09_franka_fr3.py              # simulated FR3
    python examples/09_franka_fr3.py 172.16.0.2   # a real FR3: it WILL move 15 cm along +y

The model comes from the robot itself (its URDF, tip ``link8``) with the joint limits franky
enforces; ``rc.run`` closes the loop at 500 Hz on the *measured* joint positions. The plot
(``examples/out/09_franka_fr3.png``) shows the measured tool path against the planned line,
the distance from it, and the loop timing.

``RATECTL_FAST=1`` follows 5 cm instead of 15 cm.
"""

import math
import os
import sys
from pathlib import Path

import numpy as np

import ratectl as rc

FAST = os.environ.get("RATECTL_FAST") == "1"
OUT = Path(__file__).resolve().parent / "out"


def drive(hostname: str):
    """Connect, build the line from the measured tool pose, run it; returns (execution, line)."""
    driver = rc.drivers.FrankyDriver(hostname)
    chain = driver.chain
    print(f"connected to {hostname}: {chain.name}, vmax {np.round(chain.vmax, 3).tolist()} rad/s "
          "(the robot's own limits)")
    T0 = chain.fk(driver.read().q)
    T1 = T0.copy()
    T1[1, 3] += 0.05 if FAST else 0.15
    line = rc.paths.Line(T0, T1, speed=0.1, acceleration=0.5)
    ex = rc.run(driver, path=line, rate_hz=500.0, tolerance=(1e-4, math.radians(0.2)), timeout=0.5)
    return ex, line


def plot(ex: rc.Execution, line, file: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    p = ex.poses[:, :3, 3]
    ax = axes[0]
    start = p[0]
    planned = np.array([line.start[:3, 3], line.end[:3, 3]]) - start
    ax.plot(planned[:, 1] * 1e3, planned[:, 2] * 1e3, "k--", lw=1, label="planned line")
    ax.plot((p[:, 1] - start[1]) * 1e3, (p[:, 2] - start[2]) * 1e3, color="C0", lw=1.5,
            label="measured tool (fk of measured q)")
    ax.set_xlabel("y [mm]")
    ax.set_ylabel("z [mm]")
    ax.set_title("tool path (y–z)")
    ax.legend(fontsize=7)
    ax = axes[1]
    ax.plot(ex.t, ex.position_error * 1e3, color="C0", label="distance from the line [mm]")
    ax2 = ax.twinx()
    ax2.plot(ex.t, np.degrees(ex.orientation_error), color="C3", lw=1, label="orientation [°]")
    ax.set_xlabel("robot time [s]")
    ax.set_ylabel("[mm]")
    ax2.set_ylabel("[°]", color="C3")
    ax.set_title(f"path error: max {ex.max_position_error * 1e3:.3f} mm")
    ax = axes[2]
    ax.plot(np.arange(1, len(ex.periods)), ex.periods[1:] * 1e3, ".", ms=2, color="C2")
    ax.axhline(1e3 / ex.rate_hz, color="k", lw=0.8, ls=":")
    ax.set_xlabel("cycle")
    ax.set_ylabel("period [ms]")
    ax.set_title(f"loop: {ex.achieved_rate_hz:.0f} Hz, p99 {ex.period_p99 * 1e3:.2f} ms, "
                 f"{ex.overruns} overruns")
    fig.tight_layout()
    fig.savefig(file, dpi=100)


def main():
    OUT.mkdir(exist_ok=True)
    if len(sys.argv) > 1:
        print(f"driving the robot at {sys.argv[1]}: it will move {50 if FAST else 150} mm along +y")
        ex, line = drive(sys.argv[1])
    else:
        with rc.drivers.FrankySim(nice=-5) as sim:
            print(f"franky-sim serves a simulated FR3 at {sim.hostname}")
            ex, line = drive(sim.hostname)
    print(ex.summary())
    print(f"measured pose from the line: max {ex.max_position_error * 1e3:.3f} mm, "
          f"{math.degrees(ex.max_orientation_error):.3f}°; end {ex.info['end_position_error'] * 1e3:.3f} mm")
    print(f"measured |q̇|/vmax max {np.max(np.abs(ex.qd_measured) / ex.vmax):.3f}")
    plot(ex, line, OUT / "09_franka_fr3.png")
    print(f"wrote {OUT / '09_franka_fr3.png'}")


if __name__ == "__main__":
    main()
