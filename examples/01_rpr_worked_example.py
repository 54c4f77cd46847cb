"""01 — The RPR worked example: the Jacobian derived by hand against the library.

The arm of the worked example in the documentation (standard DH, A_i = Rz(θ) Tz(d) Tx(a) Rx(α)):

    joint 1  revolute   θ = q1  d = d1  a = 0  α = +90°
    joint 2  prismatic  θ = 0   d = q2  a = 0  α = 0
    joint 3  revolute   θ = q3  d = d3  a = 0  α = 0

Column by column from J_i = [z_{i-1} × (o_3 − o_{i-1}); z_{i-1}] (revolute) and
J_i = [z_{i-1}; 0] (prismatic), with r = q2 + d3, s1 = sin q1, c1 = cos q1:

    z0 = (0, 0, 1)          o0 = (0, 0, 0)
    z1 = z2 = (s1, −c1, 0)  o3 = (r s1, −r c1, d1)

        ⎡ r c1   s1    0  ⎤
        ⎢ r s1  −c1    0  ⎥
    J = ⎢  0     0     0  ⎥      (rows v_x v_y v_z ω_x ω_y ω_z)
        ⎢  0     0    s1  ⎥
        ⎢  0     0   −c1  ⎥
        ⎣  1     0     0  ⎦

This script evaluates the formula at random q, compares it with
``chain.jacobian(q)``, prints the rank and the three twist directions the arm can
never produce, and draws the arm with its joint axes and the tool velocity each
column produces. See docs/worked_example.md for the derivation.

Run: ``python examples/01_rpr_worked_example.py`` (``RATECTL_FAST=1`` for fewer samples).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

import ratectl as rc

FAST = os.environ.get("RATECTL_FAST") == "1"
OUT = Path(__file__).resolve().parent / "out"
D1, D3 = 0.4, 0.1


def jacobian_by_hand(q, *, d3: float = D3) -> np.ndarray:
    """The closed form above, for one configuration q = (q1, q2, q3)."""
    q1, q2, _ = q
    r, s1, c1 = q2 + d3, np.sin(q1), np.cos(q1)
    return np.array([
        [r * c1, s1, 0.0],
        [r * s1, -c1, 0.0],
        [0.0, 0.0, 0.0],
        [0.0, 0.0, s1],
        [0.0, 0.0, -c1],
        [1.0, 0.0, 0.0],
    ])


def lost_directions(q, *, d3: float = D3) -> np.ndarray:
    """Orthonormal basis (3, 6) of the twists J can never produce (the left null space).

    v_z (the tool height is fixed at d1); ω about the horizontal axis z0 × z1 = (c1, s1, 0)
    (both rotation axes are perpendicular to it); and the coupled twist
    [(c1, s1, 0); (0, 0, −r)]: the sideways speed always equals r·ω_z.
    """
    q1, q2, _ = q
    r, s1, c1 = q2 + d3, np.sin(q1), np.cos(q1)
    N = np.array([
        [0, 0, 1, 0, 0, 0],
        [0, 0, 0, c1, s1, 0],
        [c1, s1, 0, 0, 0, -r],
    ], dtype=float)
    return N / np.linalg.norm(N, axis=1, keepdims=True)


def main() -> dict:
    arm = rc.robots.rpr(d1=D1, d3=D3)
    rng = np.random.default_rng(7)
    samples = 200 if FAST else 20000
    qs = arm.random_q(samples, rng=rng)
    J_lib = arm.jacobian(qs)                                   # batched (samples, 6, 3)
    J_hand = np.stack([jacobian_by_hand(q) for q in qs])
    err = np.abs(J_lib - J_hand).max(axis=(1, 2))
    ranks = np.linalg.matrix_rank(J_lib, tol=1e-9)
    left_null = np.stack([lost_directions(q) for q in qs])
    leak = np.abs(np.einsum("bkm,bmn->bkn", left_null, J_lib)).max()
    # finite differences of fk, at a few configurations, as a third opinion
    fd = max(np.abs(rc.kinematics.numerical_jacobian(arm, q) - jacobian_by_hand(q)).max()
             for q in qs[:20])

    q = np.array([0.6, 0.35, -0.4])
    np.set_printoptions(precision=4, suppress=True)
    print("RPR arm (d1 = 0.4 m, d3 = 0.1 m) at q =", q)
    print("J by hand:\n", jacobian_by_hand(q))
    print("J from chain.jacobian(q):\n", arm.jacobian(q))
    print(f"max |J_lib − J_hand| over {samples} random q: {err.max():.2e}")
    print(f"max |J_fd − J_hand| (central differences of fk, 20 q): {fd:.2e}")
    print(f"rank J: {sorted(set(ranks.tolist()))} at every sampled q (3 joints, full column rank)")
    print(f"lost twist directions n with nᵀJ = 0: max |nᵀJ| = {leak:.1e}")
    print("  v_z (tool height fixed at d1), ω about (c1, s1, 0), and v_tangential − r·ω_z")

    _plot(arm, q, err)
    return {"max_error": float(err.max()), "fd_error": float(fd), "ranks": set(ranks.tolist())}


def _plot(arm, q, err) -> None:
    import matplotlib

    matplotlib.use(os.environ.get("MPLBACKEND", "Agg"))
    import matplotlib.pyplot as plt

    T = arm.frames(q)
    o = T[:, :3, 3]
    z = T[:, :3, 2]
    tool = arm.fk(q)[:3, 3]
    J = arm.jacobian(q)
    fig = plt.figure(figsize=(11, 4.8))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    pts = np.vstack([[0, 0, 0], o[1:], tool])
    ax.plot(pts[:, 0], pts[:, 1], pts[:, 2], "-o", color="0.25", lw=3, label="links")
    for i, c in zip(range(3), ["tab:blue", "tab:orange", "tab:green"], strict=True):
        ax.quiver(*o[i], *(0.25 * z[i]), color=c, lw=2, label=f"z{i} (joint {i + 1} axis)")
    for i, c in zip(range(3), ["tab:red", "tab:purple", "tab:brown"], strict=True):
        v = J[:3, i]
        if np.linalg.norm(v) > 1e-9:
            ax.quiver(*tool, *(0.25 * v), color=c, lw=1.5, ls="--", label=f"J_v column {i + 1}")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.set_aspect("equal")
    ax.view_init(elev=20, azim=-50)
    ax.set_title(f"RPR arm at q = {np.round(q, 2).tolist()}")
    ax.legend(fontsize=7, loc="upper left")
    ax2 = fig.add_subplot(1, 2, 2)
    ax2.hist(np.log10(np.maximum(err, 1e-18)), bins=30, color="tab:blue")
    ax2.set_xlabel("log10 max |J_library − J_by_hand| per configuration")
    ax2.set_ylabel("configurations")
    ax2.set_title("closed form vs chain.jacobian(q)")
    fig.tight_layout()
    OUT.mkdir(exist_ok=True)
    path = OUT / "01_rpr_worked_example.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print("saved", path)


if __name__ == "__main__":
    main()
