"""Behaviour report (not speed): the acceptance line of issue #5 run five ways.

The line is the one the tests use (``tests/conftest.py``: UR5e, 0.3 m at 0.2 m/s,
constant orientation, closest approach |q5| = 0.01 rad); this script imports its
definition from there so that the numbers it prints are those the tests assert on.

Run:  python benchmarks/report_wrist_line.py

Prints, per run: completed, largest distance from the line [mm] and orientation error
[deg], largest |q̇|/vmax and |q̈|/amax, end-pose error, duration against the nominal
time law.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from conftest import WRIST_DIRECTION, WRIST_HALF, WRIST_Q_CLOSEST  # noqa: E402

import ratectl as rc  # noqa: E402
from ratectl.planning import joint_path  # noqa: E402

DT = 2e-3


def main() -> None:
    arm = rc.robots.ur5e()
    T0 = arm.fk(WRIST_Q_CLOSEST)
    Ta, Tb = T0.copy(), T0.copy()
    Ta[:3, 3] -= WRIST_HALF * WRIST_DIRECTION
    Tb[:3, 3] += WRIST_HALF * WRIST_DIRECTION
    q0 = joint_path(arm, rc.paths.Line(T0, Ta, speed=0.2, acceleration=1.0), WRIST_Q_CLOSEST).q[-1]
    line = rc.paths.Line(Ta, Tb, speed=0.2, acceleration=1.0)
    runs = {
        "governor": dict(),
        "governor + Ruckig smoothing": dict(controller=rc.ResolvedRateController(arm, smoothing=True)),
        "time law, adaptive DLS": dict(governor=False, controller=rc.ResolvedRateController(
            arm, solver=rc.solvers.AdaptiveDLS())),
        "time law, DLS λ = 0.05": dict(governor=False, controller=rc.ResolvedRateController(
            arm, solver=rc.solvers.DLS(damping=0.05))),
        "time law, exact inverse": dict(governor=False, controller=rc.ResolvedRateController(
            arm, solver=rc.solvers.Inverse())),
    }
    for name, kw in runs.items():
        run = rc.follow(arm, line, q0, dt=DT, **kw)
        e = rc.spatial.pose_error(line.end, arm.fk(run.q[-1]))
        rot = math.degrees(run.orientation_error.max())
        v = np.max(np.abs(run.qd) / arm.vmax)
        a = np.max(np.abs(run.qdd) / arm.amax)
        print(f"{name:28s} completed={run.completed!s:5s} "
              f"path {run.max_position_error * 1e3:.3g} mm {rot:.3g}° | "
              f"|q̇|/vmax {v:.3f} |q̈|/amax {a:.3f} | "
              f"end {np.linalg.norm(e[:3]) * 1e3:.3g} mm {math.degrees(np.linalg.norm(e[3:])):.3g}° | "
              f"{run.duration:.2f} s vs {run.nominal_duration:.2f} s nominal")


if __name__ == "__main__":
    main()
