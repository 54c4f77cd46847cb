"""Behaviour report (not speed): the UR5e wrist line of ``ratectl demo``, run every way
the documentation describes, with the date and the machine.

The line is ``ratectl.cli.demo.wrist_line("ur5e")``: 0.3 m at 0.2 m/s, constant
orientation, passing 0.01 rad from the wrist singularity (q5 = 0), in the direction in
which the exact inverse is fastest. It is the one line of the README, the home page,
the paths guide and example 07.

Run:  python benchmarks/report_wrist_line.py [--figures docs/img]

Prints (as Markdown tables, ready for the docs):

1. the demo's comparison at dt = 1 ms: the textbook loop on the nominal time law with
   the exact inverse, DLS, adaptive DLS and the QP, and ``rc.follow`` with the governor;
2. ``rc.follow`` at dt = 2 ms with a governor, with the governor and Ruckig smoothing,
   and on the nominal time law with adaptive DLS, DLS and the exact inverse (the
   controller's own velocity scaling).

``--figures DIR`` also writes ``DIR/examples_02_wrist_singularity_line.png`` (the demo's
plot) and ``DIR/governor_ur5e_wrist.png`` (the governor run: joint velocities, path
error, σ_min).
"""

from __future__ import annotations

import argparse
import datetime
import math
import platform
from pathlib import Path

import numpy as np

import ratectl as rc
from ratectl.cli import demo


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import os

    return (f"{cpu}, {os.cpu_count()} cores, {platform.system()} {platform.release()}, "
            f"Python {platform.python_version()}, numpy {np.__version__}, ratectl {rc.__version__}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--figures", type=Path, help="write the two figures into this directory")
    args = ap.parse_args(argv)
    print(f"date: {datetime.date.today().isoformat()}; machine: {machine()}\n")

    comp = demo.compare("ur5e", dt=1e-3)
    sc = comp.scenario
    print(f"line: {sc.chain.name}, {sc.path.length:.2f} m at {sc.path.speed:g} m/s, closest |q5| = "
          f"{sc.min_q5:.4f} rad; the exact inverse needs {sc.exact_speed:.1f} rad/s "
          f"(vmax = {np.min(sc.chain.vmax):.2f} rad/s); nominal time law {sc.path.duration:.2f} s\n")
    print("1. `ratectl demo` (dt = 1 ms)\n")
    print("| method | max \\|q̇\\|/vmax | max \\|q̈\\|/amax | path error [mm] | orientation error [°] "
          "| duration [s] |")
    print("|---|---|---|---|---|---|")
    for r in comp.results:
        print(f"| {r.method} | {r.max_velocity_ratio:.2f} | {r.max_acceleration_ratio:.2f} | "
              f"{r.max_position_error * 1e3:.3g} | {math.degrees(r.max_orientation_error):.3g} | "
              f"{r.duration:.2f} |")

    arm, line, q0 = sc.chain, sc.path, sc.q0
    dt = 2e-3
    runs = {
        "governor (default)": dict(),
        "governor + Ruckig smoothing": dict(controller=rc.ResolvedRateController(arm, smoothing=True)),
        "time law, adaptive DLS (default solver)": dict(governor=False),
        "time law, DLS λ = 0.05": dict(governor=False, controller=rc.ResolvedRateController(
            arm, solver=rc.solvers.DLS(damping=0.05))),
        "time law, exact inverse, q̇ scaled to vmax": dict(
            governor=False, controller=rc.ResolvedRateController(arm, solver=rc.solvers.Inverse())),
    }
    print("\n2. `rc.follow` (dt = 2 ms)\n")
    print("| how the line is run | completed | path error [mm] | orientation error [°] | max \\|q̇\\|/vmax "
          "| max \\|q̈\\|/amax | end error [mm] | duration [s] |")
    print("|---|---|---|---|---|---|---|---|")
    gov_run = None
    for name, kw in runs.items():
        run = rc.follow(arm, line, q0, dt=dt, **kw)
        gov_run = run if gov_run is None else gov_run
        e = rc.spatial.pose_error(line.end, arm.fk(run.q[-1]))
        print(f"| {name} | {'yes' if run.completed else 'no'} | {run.max_position_error * 1e3:.2g} | "
              f"{math.degrees(run.max_orientation_error):.2g} | {run.velocity_ratio:.2f} | "
              f"{run.acceleration_ratio:.2f} | {np.linalg.norm(e[:3]) * 1e3:.2g} | {run.duration:.2f} "
              f"({run.extra_time:+.2f}) |")
    print(f"\ngovernor run: min σ_min(J) = {np.nanmin(gov_run.sigma_min):.4f}")

    if args.figures is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        args.figures.mkdir(parents=True, exist_ok=True)
        demo.plot_comparison(comp, args.figures / "examples_02_wrist_singularity_line.png")
        fig = gov_run.plot(title=f"UR5e wrist line, governor (dt = 2 ms): {gov_run.duration:.2f} s, "
                                 f"nominal {gov_run.nominal_duration:.2f} s")
        fig.savefig(args.figures / "governor_ur5e_wrist.png", dpi=100)
        plt.close(fig)
        print(f"figures written to {args.figures}")


if __name__ == "__main__":
    main()
