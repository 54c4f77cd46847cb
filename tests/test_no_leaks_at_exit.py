"""Objects that wrap Ruckig results may live until the interpreter exits (a path at module
level, a result kept by a test) without nanobind reporting leaked instances at exit:
a fresh interpreter builds each of them, keeps them in module globals, and exits; its
stderr must not say "leaked". (`python -m pytest` ending with "nanobind: leaked …
ruckig.Trajectory" blocks was the symptom.)"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SCRIPT = """
import numpy as np
import ratectl as rc
from ratectl.control import move, stop

arm = rc.robots.ur5e()
q = np.array([0.1, -1.2, 1.3, -1.6, -1.5, 0.2])
T0 = arm.fk(q)
T1 = T0.copy()
T1[:3, 3] += [0.05, 0.0, 0.0]
LINE = rc.paths.Line(T0, T1, speed=0.1, acceleration=1.0, jerk=10.0)
WAY = rc.paths.Waypoints([T0, T1], speed=0.1, acceleration=1.0, jerk=10.0)
MOVE = move(q, q + 0.1, vmax=arm.vmax, amax=arm.amax, jmax=arm.jmax)
STOP = stop(q, np.full(6, 0.3), amax=arm.amax, jmax=arm.jmax)
CTRL = rc.ResolvedRateController(arm, smoothing=True)
CMD = CTRL.step(q, target=T1, dt=1e-3)
RUN = rc.follow(arm, LINE, q, dt=5e-3)
print(LINE.pose(0.1)[0, 3], MOVE.at(0.1)[0][0], STOP.duration, CMD.status, RUN.completed)
"""


def test_ruckig_results_held_until_exit_leak_nothing():
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env,
                          timeout=300, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "leaked" not in proc.stderr, proc.stderr[-3000:]
