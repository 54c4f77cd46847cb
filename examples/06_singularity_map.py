"""06 — A singularity map of a workspace.

Two views of where the UR5e is close to singular, from ``rc.workspace_map``:

1. joint space: σ_min of the unit-consistent Jacobian over a grid of q3 (elbow) and
   q5 (wrist 2), other joints fixed, with the near-singular regions outlined by kind
   (elbow at q3 = 0, wrist at q5 = 0, shoulder where the wrist passes over joint 1);
2. task space: the best σ_min reachable with the tool origin in the vertical plane
   y = 0 (random configurations within the limits, binned by tool position). The dark
   column in the middle is the shoulder singularity (wrist centre over the axis of
   joint 1) and the dark rim is the workspace boundary (elbow stretched).

It also prints the share of configurations of each singularity kind from
``rc.scan`` over random configurations.

Run: ``python examples/06_singularity_map.py`` (``RATECTL_FAST=1``: coarser grids, fewer samples).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

import ratectl as rc

FAST = os.environ.get("RATECTL_FAST") == "1"
OUT = Path(__file__).resolve().parent / "out"


def main() -> dict:
    from ratectl.singularity import plot_workspace_map

    arm = rc.robots.ur5e()
    q_other = np.array([0.0, -1.2, 0.0, -1.5, 0.0, 0.0])
    joints_map = rc.workspace_map(arm, joints=(2, 4), q=q_other, measure="sigma_min_scaled",
                                  resolution=61 if FAST else 181)
    plane_map = rc.workspace_map(arm, plane="xz", measure="sigma_min_scaled",
                                 resolution=41 if FAST else 121,
                                 samples=100_000 if FAST else 1_000_000, slab=0.04, rng=1)
    res = rc.scan(arm, arm.random_q(20_000 if FAST else 200_000, rng=np.random.default_rng(2)))
    counts = res.count()
    total = sum(counts.values())
    print(f"{arm.name}: near-singular share over {total} random configurations: "
          + ", ".join(f"{k} {100 * v / total:.1f}%" for k, v in counts.items() if v))
    vals = np.asarray(joints_map.values)
    print(f"joint-space map q3 × q5: sigma_min(J_L) from {vals.min():.2e} to {vals.max():.3f}; "
          f"{np.mean(vals < 0.02) * 100:.1f}% of the grid below 0.02")
    covered = np.isfinite(np.asarray(plane_map.values))
    print(f"task-space map (plane y = 0): {covered.mean() * 100:.0f}% of the cells reached")

    import matplotlib

    matplotlib.use(os.environ.get("MPLBACKEND", "Agg"))
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(14, 5.6))
    plot_workspace_map(joints_map, ax=ax[0])
    plot_workspace_map(plane_map, ax=ax[1])
    ax[1].set_aspect("equal")
    fig.tight_layout()
    OUT.mkdir(exist_ok=True)
    path = OUT / "06_singularity_map.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    print("saved", path)
    return {"counts": counts}


if __name__ == "__main__":
    main()
