"""Singularity analysis speed: batched scans, one-configuration analysis, the gradient.

Run:  python benchmarks/bench_singularity.py [--quick] [--figure docs/img/singularity_ur5e_map.png]

Prints
* the wall time of ``rc.scan`` over 10^5 random UR5e configurations (the acceptance
  target is < 1 s on one core; pin with ``taskset -c 0``), and configurations per second;
* the share of that time spent in the batched Jacobian;
* median µs per call of ``rc.analyze``, ``rc.singularity.classify`` (the control-loop
  path, regular and near-singular), ``rc.manipulability`` and
  ``rc.manipulability_gradient`` for one configuration;
* when roboticstoolbox-python is installed: its ``manipulability`` and ``jacobm``
  (manipulability gradient) on the same arm, cross-checked against ratectl.

``--figure PATH`` writes the workspace-map figure used in ``docs/singularity.md``.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from _timing import median_s, median_us  # noqa: E402

import ratectl as rc  # noqa: E402
from ratectl import singularity as S  # noqa: E402


def bench_scan(B: int, repeat: int) -> None:
    arm = rc.robots.ur5e()
    qs = arm.random_q(B, rng=1)
    res = rc.scan(arm, qs)  # also warms up
    t = median_s(lambda: rc.scan(arm, qs), repeat=repeat)
    tj = median_s(lambda: arm.jacobian(qs), repeat=repeat)
    print(f"scan of {B:,} UR5e configurations: {t:.3f} s  ({B / t:,.0f} configurations/s; "
          f"batched Jacobian {tj:.3f} s of it)")
    print("  kinds:", ", ".join(f"{k} {v}" for k, v in res.count().items()))
    # looped equals batched (spot check)
    for i in range(0, B, max(1, B // 50)):
        r = rc.analyze(arm, qs[i])
        assert r.kind == res.kinds[i] and abs(r.sigma_min_scaled - res.sigma_min_scaled[i]) < 1e-12


def bench_single(number: int) -> None:
    arm = rc.robots.ur5e()
    q = np.array([0.3, -1.0, 1.2, -0.7, 0.8, 0.4])
    qn = q.copy()
    qn[4] = 1e-3
    J = arm.jacobian(q)
    rows = [
        ("analyze (full report)", lambda: rc.analyze(arm, q)),
        ("classify, regular q", lambda: S.classify(arm, q)),
        ("classify, near-singular q", lambda: S.classify(arm, qn)),
        ("classify(J=...) regular", lambda: S.classify(arm, J=J)),
        ("manipulability(J)", lambda: rc.manipulability(J)),
        ("manipulability_gradient", lambda: rc.manipulability_gradient(arm, q)),
    ]
    for name, fn in rows:
        print(f"  {name:28s} {median_us(fn, number=number, repeat=7):8.1f} µs")
    qs = arm.random_q(10_000, rng=2)
    t = median_s(lambda: rc.manipulability_gradient(arm, qs), repeat=3)
    print(f"  manipulability_gradient, batch of 10^4: {t * 1e3:.1f} ms ({1e4 / t:,.0f}/s)")


def bench_rtb(number: int) -> None:
    try:
        import roboticstoolbox as rtb
    except Exception:  # noqa: BLE001 - optional peer
        print("roboticstoolbox-python not installed: peer comparison skipped")
        return
    # the same arm in both libraries: ratectl chain built from the toolbox's UR5 DH table
    peer = rtb.models.DH.UR5()
    rows = [rc.DH(a=L.a, alpha=L.alpha, d=L.d, theta=L.offset) for L in peer.links]
    arm = rc.Chain.from_dh(rows, base=np.asarray(peer.base.A), tool=np.asarray(peer.tool.A), name="UR5")
    q = np.array([0.3, -1.0, 1.2, -0.7, 0.8, 0.4])
    w_peer = float(peer.manipulability(q))
    w_ours = float(rc.manipulability(arm.jacobian(q)))
    g_peer = np.asarray(peer.jacobm(q)).ravel()
    g_ours = rc.manipulability_gradient(arm, q)
    print(f"roboticstoolbox-python, UR5 (toolbox DH): manipulability {w_peer:.9g} vs ratectl {w_ours:.9g}; "
          f"gradient max |Δ| = {np.max(np.abs(g_peer - g_ours)):.1e}")
    t_peer = median_us(lambda: peer.manipulability(q), number=max(1, number // 4), repeat=5)
    t_ours = median_us(lambda: rc.manipulability(arm.jacobian(q)), number=number, repeat=5)
    tg_peer = median_us(lambda: peer.jacobm(q), number=max(1, number // 4), repeat=5)
    tg_ours = median_us(lambda: rc.manipulability_gradient(arm, q), number=number, repeat=5)
    print(f"  manipulability(q):        rtb {t_peer:8.1f} µs   ratectl {t_ours:8.1f} µs")
    print(f"  gradient (rtb jacobm):    rtb {tg_peer:8.1f} µs   ratectl {tg_ours:8.1f} µs")


def figure(path: str) -> None:
    """Two workspace maps of the UR5e: over (q2, q3), and over the vertical plane y = 0.133 m."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    arm = rc.robots.ur5e()
    fig, axes = plt.subplots(1, 2, figsize=(12, 5), constrained_layout=True)
    q = np.array([0.0, -1.0, 1.0, -1.4, 1.0, 0.0])
    jm = S.workspace_map(arm, joints=(1, 2), q=q, resolution=241, measure="sigma_min_scaled")
    S.plot_workspace_map(jm, ax=axes[0])
    axes[0].set_title("UR5e: σ_min(J_L) over q2, q3 (q1 = 0, q4 = −1.4, q5 = 1, q6 = 0);\n"
                      "outlined: near-singular (σ_min < 0.01) by kind", fontsize=9)
    pm = S.workspace_map(arm, plane="xz", offset=0.1333, slab=0.03, resolution=81, samples=6_000_000,
                         measure="inverse_condition_scaled")
    S.plot_workspace_map(pm, ax=axes[1], cmap="magma")
    axes[1].set_aspect("equal")
    axes[1].set_title("UR5e: best 1/κ(J_L) with the tool origin in the plane y = 0.133 m (±15 mm)\n"
                      "(6·10⁶ random configurations, best value per 3.6 cm cell)", fontsize=9)
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repetitions (a smoke run)")
    ap.add_argument("--figure", metavar="PATH", help="write the docs workspace-map figure")
    args = ap.parse_args()
    if args.figure:
        figure(args.figure)
        return
    bench_scan(100_000, repeat=2 if args.quick else 7)
    print("one configuration (UR5e):")
    bench_single(200 if args.quick else 2000)
    bench_rtb(200 if args.quick else 2000)


if __name__ == "__main__":
    main()
