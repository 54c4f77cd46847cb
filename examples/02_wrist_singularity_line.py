"""02 — A line past a wrist singularity: five methods side by side.

A UR5e follows a straight line at constant orientation (0.3 m at 0.2 m/s) that passes
0.01 rad from its wrist singularity (q5 = 0). To stay on the line the wrist must turn
joints 4 and 6 by about π while the tool passes the closest point: the exact inverse
needs about 40 rad/s there, thirteen times the UR5e's 3.14 rad/s.

The same comparison runs behind ``ratectl demo`` (``ratectl.cli.demo.compare``):

* exact inverse  — follows the line but far beyond the velocity and acceleration limits;
* DLS (λ = 0.05) and adaptive DLS — stay within the speed limit by *not* turning the wrist:
  the tool's orientation leaves the path near the singularity (≈ 1°);
* QP (λ = 0.001, joint velocity / position / acceleration limits) — turns the wrist as fast
  as the limits allow while the time law runs on: the tool leaves the path by centimetres;
* governor (``rc.follow``) — slows down along the line so the wrist can turn within the
  limits: on the path (to well under a micrometre), within every limit, and slower.

Prints the table and saves the plot (joint speed / limit, position and orientation
error, q4, q5, progress along the line).

Run: ``python examples/02_wrist_singularity_line.py`` (``RATECTL_FAST=1``: 2 ms period).
"""

from __future__ import annotations

import os
from pathlib import Path

from ratectl.cli import demo

FAST = os.environ.get("RATECTL_FAST") == "1"
OUT = Path(__file__).resolve().parent / "out"


def main():
    comparison = demo.compare("ur5e", dt=2e-3 if FAST else 1e-3)
    print(demo.format_table(comparison))
    gov = comparison["governor"]
    print(f"\nthe governor took {gov.duration:.2f} s for a {gov.nominal:.2f} s time law "
          f"({gov.duration / gov.nominal:.1f}x) and stayed within "
          f"{gov.max_position_error:.1e} m of the line")
    OUT.mkdir(exist_ok=True)
    path = demo.plot_comparison(comparison, OUT / "02_wrist_singularity_line.png")
    print("saved", path)
    return comparison


if __name__ == "__main__":
    main()
