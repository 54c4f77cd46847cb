"""10 — Drag the target in the browser; the arm servos to it.

A `ratectl.viewer.Viewer` serves a 3-D view of the UR5e on this machine. Open the printed
address, drag the gizmo (arrows move it, rings turn it), and the 100 Hz control loop below
follows it: every cycle it reads ``v.target`` and takes one `ResolvedRateController.step`
toward it, within the arm's velocity and acceleration limits, slowing down near
singularities (σ_min, the kind and the lost directions are shown beside the arm).

Run: ``python examples/10_drag_to_servo.py`` (Ctrl-C to stop).

Without a person at the browser — ``--seconds N --move-target``, or ``RATECTL_FAST=1`` as in
the tests — the script moves the target itself, from Python, three times (10–15 cm each,
with a turn), checks after each move that the tool has reached it (within 1 mm and 0.1°),
and writes the distance to the target over time to ``examples/out/10_drag_to_servo.png``.
Needs the view extra: ``pip install -e ".[view]"``.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

import ratectl as rc

FAST = os.environ.get("RATECTL_FAST") == "1"
OUT = Path(__file__).resolve().parent / "out"
DT = 0.01                        # control period [s]: 100 Hz
Q0 = np.array([0.0, -1.6, 1.7, -1.7, -1.57, 0.0])
# the moves of the target made from Python: translation [m] and a turn about base z [rad]
MOVES = [(np.array([0.12, 0.0, 0.0]), 0.0),
         (np.array([0.0, 0.10, -0.05]), 0.3),
         (np.array([-0.08, -0.06, 0.08]), -0.2)]
POSITION_TOL, ANGLE_TOL = 1e-3, math.radians(0.1)


def moved(T: np.ndarray, shift: np.ndarray, turn: float) -> np.ndarray:
    """T translated by ``shift`` (base axes) and turned by ``turn`` about the base z axis."""
    out = T.copy()
    out[:3, :3] = rc.spatial.rotz(turn) @ T[:3, :3]
    out[:3, 3] += shift
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=None, help="stop after this many seconds")
    p.add_argument("--move-target", action="store_true", help="move the target from Python")
    p.add_argument("--port", type=int, default=None)
    args = p.parse_args()
    auto = args.move_target or FAST
    seconds = args.seconds if args.seconds is not None else (3 * 2.5 if auto else math.inf)

    chain = rc.robots.ur5e()
    ctrl = rc.ResolvedRateController(chain)
    q = Q0.copy()
    log_t, log_e, log_a = [], [], []
    reached = []
    error = (math.inf, math.inf)     # the tool's distance to the target [m], [rad]
    with rc.viewer.Viewer(chain, q, port=args.port) as v:
        print(f"open {v.url} and drag the target (Ctrl-C to stop)", flush=True)
        start = time.monotonic()
        next_time = start
        move, move_time = 0, start
        try:
            while time.monotonic() - start < seconds:
                now = time.monotonic()
                if auto and move < len(MOVES) and now >= move_time:
                    if move > 0:
                        reached.append(error)
                    shift, turn = MOVES[move]
                    v.target = moved(v.target, shift, turn)   # as if dragged in the browser
                    move, move_time = move + 1, now + seconds / len(MOVES)
                cmd = ctrl.step(q, target=v.target, dt=DT)
                q = cmd.q_next                                # a perfect robot
                v.update(q, command=cmd)
                error = (cmd.position_error, cmd.orientation_error)
                log_t.append(now - start)
                log_e.append(cmd.position_error)
                log_a.append(cmd.orientation_error)
                next_time += DT
                time.sleep(max(0.0, next_time - time.monotonic()))
        except KeyboardInterrupt:
            pass
    if auto and move == len(MOVES):
        reached.append(error)
    print(f"{len(log_t)} control cycles at {1 / DT:.0f} Hz")
    ok = True
    if auto:
        for k, (e_p, e_a) in enumerate(reached, start=1):
            good = e_p <= POSITION_TOL and e_a <= ANGLE_TOL
            ok &= good
            print(f"move {k}: tool {1e3 * e_p:.3f} mm and {math.degrees(e_a):.4f}° from the target "
                  f"-> {'reached' if good else 'NOT reached'}")
        ok &= len(reached) == len(MOVES)
    plot(np.array(log_t), np.array(log_e), np.array(log_a))
    return 0 if ok else 1


def plot(t: np.ndarray, e: np.ndarray, a: np.ndarray) -> None:
    import matplotlib

    matplotlib.use(os.environ.get("MPLBACKEND", "Agg"))
    import matplotlib.pyplot as plt

    OUT.mkdir(exist_ok=True)
    fig, ax = plt.subplots(figsize=(8, 3.5))
    ax.plot(t, 1e3 * e, label="position [mm]")
    ax.plot(t, np.degrees(a) * 10, label="orientation [0.1°]")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("distance to the target")
    ax.set_title("servo to a target moved in the viewer (10_drag_to_servo)")
    ax.legend()
    fig.tight_layout()
    path = OUT / "10_drag_to_servo.png"
    fig.savefig(path, dpi=100)
    print(f"plot written to {path}")


if __name__ == "__main__":
    sys.exit(main())
