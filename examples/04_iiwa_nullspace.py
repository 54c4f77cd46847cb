"""04 — The redundant iiwa 7: null-space joint centring or manipulability.

The KUKA LBR iiwa 7 has seven joints for a six-dimensional task, so every tool
motion can be made by a one-parameter family of joint motions. The solver picks one;
``rc.solvers.NullSpace`` adds a secondary motion in the null space of J,

    q̇ = q̇_primary + k (I − J⁺J) z(q),

that the tool does not see: here z = −∇H for the distance H from the joint centres
("centring"), or z = ∇w for the manipulability w = √det(JJᵀ) ("manipulability").

The arm starts far from its joint centres and follows a 0.3 m line at constant
orientation three times: adaptive DLS alone, with centring, and with manipulability.
The script prints, for each, the path error (the primary task, unchanged) and how the
secondary measure evolved; the figure plots both against time.

Run: ``python examples/04_iiwa_nullspace.py`` (``RATECTL_FAST=1``: 2 ms period).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

import ratectl as rc
from ratectl.solvers import AdaptiveDLS, JointCentring, NullSpace

FAST = os.environ.get("RATECTL_FAST") == "1"
OUT = Path(__file__).resolve().parent / "out"


def main() -> dict:
    arm = rc.robots.iiwa7()
    q0 = np.array([0.9, 0.8, -1.3, -1.3, 1.0, 1.1, 0.4])
    T0 = arm.fk(q0)
    T1 = T0.copy()
    T1[:3, 3] += [0.0, 0.25, -0.15]
    line = rc.paths.Line(T0, T1, speed=0.15, acceleration=0.5)
    dt = 2e-3 if FAST else 1e-3
    centring = JointCentring(arm)
    variants = {
        "adaptive DLS only": AdaptiveDLS(),
        "+ joint centring": NullSpace(AdaptiveDLS(), "centring", chain=arm, gain=2.0),
        "+ manipulability": NullSpace(AdaptiveDLS(), "manipulability", chain=arm, gain=20.0),
    }
    runs = {}
    for name, solver in variants.items():
        ctrl = rc.ResolvedRateController(arm, solver=solver)
        runs[name] = rc.follow(arm, line, q0, dt=dt, controller=ctrl, governor=False)

    print(f"iiwa7: line of {line.length:.2f} m at {line.speed} m/s from q0 = {np.round(q0, 2).tolist()}")
    heads = ("path err [mm]", "H start", "H end", "w start", "w end")
    print(f"{'solver':22s} " + " ".join(f"{h:>{14 if i == 0 else 9}s}" for i, h in enumerate(heads)))
    summary = {}
    for name, run in runs.items():
        H = np.array([centring.cost(q) for q in run.q])
        w = np.asarray(rc.manipulability(arm.jacobian(run.q)))
        summary[name] = (H, w)
        print(f"{name:22s} {run.max_position_error * 1e3:14.4f} {H[0]:9.4f} {H[-1]:9.4f} "
              f"{w[0]:9.4f} {w[-1]:9.4f}")
    print("H: distance from the joint centres ½Σ((q−c)/r)² (lower is better); "
          "w: manipulability √det(JJᵀ) (higher is better)")
    _plot(runs, summary)
    return {k: (float(v[0][-1]), float(v[1][-1])) for k, v in summary.items()}


def _plot(runs, summary) -> None:
    import matplotlib

    matplotlib.use(os.environ.get("MPLBACKEND", "Agg"))
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(15, 4.2))
    for (name, run), c in zip(runs.items(), ["tab:gray", "tab:blue", "tab:green"], strict=True):
        H, w = summary[name]
        ax[0].plot(run.t, H, color=c, label=name)
        ax[1].plot(run.t, w, color=c, label=name)
        ax[2].plot(run.t, np.asarray(run.position_error) * 1e3, color=c, label=name)
    ax[0].set_ylabel("H = ½Σ((q − c)/r)²")
    ax[0].set_title("distance from the joint centres")
    ax[1].set_ylabel("w = √det(J Jᵀ)")
    ax[1].set_title("manipulability")
    ax[2].set_ylabel("distance from the line [mm]")
    ax[2].set_title("primary task: path error (unchanged)")
    for a in ax:
        a.set_xlabel("t [s]")
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    fig.suptitle("iiwa7: secondary objectives in the null space while following a line")
    fig.tight_layout()
    OUT.mkdir(exist_ok=True)
    path = OUT / "04_iiwa_nullspace.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    print("saved", path)


if __name__ == "__main__":
    main()
