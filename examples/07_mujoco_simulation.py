"""Follow a line past the UR5e wrist singularity in MuJoCo, with physics.

The kinematic run (``rc.follow`` with the path-speed governor) is replayed on a MuJoCo
model of the same arm (exported with ``to_mjcf``) through position servos: the
controller reads the simulated joint state every 10 ms and commands the servos. The
script prints how far the simulated tool is from the kinematic run and from the line,
and saves plots (and rendered frames where an offscreen OpenGL context exists) under
``examples/out/``.

``RATECTL_FAST=1`` runs the same thing with fewer rendered frames (a few seconds).
"""

import os
from pathlib import Path

import numpy as np

import ratectl as rc
from ratectl.interop.offscreen_gl import pick_gl_backend

FAST = os.environ.get("RATECTL_FAST") == "1"
OUT = Path(__file__).parent / "out"


GL = pick_gl_backend()  # before mujoco is imported

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import mujoco  # noqa: E402

from ratectl.cli.demo import wrist_line  # noqa: E402
from ratectl.interop.mujoco import render_frames, simulate, to_mjcf  # noqa: E402


def main():
    OUT.mkdir(exist_ok=True)
    scenario = wrist_line("ur5e")              # the line of `ratectl demo`, 0.01 rad from q5 = 0
    arm, path, q0 = scenario.chain, scenario.path, scenario.q0
    dt = 0.01
    run = rc.follow(arm, path, q0, dt=dt)                      # kinematic run (governor)
    xml = to_mjcf(arm, actuators="position", floor=True)
    model = mujoco.MjModel.from_xml_string(xml)
    sim, log = simulate(model, arm, run, q0, dt=dt, actuation="position")
    vel, _ = simulate(None, arm, run, q0, dt=dt, actuation="velocity")
    gap = np.linalg.norm(sim.poses[:, :3, 3] - run.poses[:, :3, 3], axis=1)
    gap_v = np.linalg.norm(vel.poses[:, :3, 3] - run.poses[:, :3, 3], axis=1)
    path_err = np.array([path.distance(T)[0] for T in sim.poses])

    fig, ax = plt.subplots(3, 1, sharex=True, figsize=(8, 8))
    ax[0].plot(run.t, run.position_error * 1e3, label="kinematic run (follow)")
    ax[0].plot(sim.t, path_err * 1e3, label="MuJoCo, position servos")
    ax[0].set_ylabel("distance from line [mm]")
    ax[0].legend()
    ax[1].plot(sim.t, gap * 1e3, label="position servos")
    ax[1].plot(vel.t, gap_v * 1e3, label="velocity servos")
    ax[1].axhline(2.0, color="k", ls=":", lw=1, label="2 mm")
    ax[1].set_ylabel("|p_sim − p_kin| [mm]")
    ax[1].legend()
    for i in range(6):
        ax[2].plot(sim.t, sim.qd[:, i], label=arm.joint_names[i])
    ax[2].set_ylabel("measured q̇ [rad/s]")
    ax[2].set_xlabel("t [s]")
    ax[2].legend(ncol=3, fontsize=7)
    fig.suptitle("UR5e line 0.01 rad from the wrist singularity: kinematic run vs MuJoCo physics")
    fig.tight_layout()
    fig.savefig(OUT / "07_mujoco_simulation.png", dpi=110)
    plt.close(fig)

    rendered = "no offscreen OpenGL (EGL/OSMesa): plots only"
    if GL is not None:
        picks = np.linspace(0, len(sim.t) - 1, 3 if FAST else 5).astype(int)
        data = mujoco.MjData(model)
        frames = render_frames(model, data, arm, sim.q[picks], width=320 if FAST else 400,
                               height=240 if FAST else 300, lookat=(-0.3, -0.15, 0.3), distance=1.6,
                               azimuth=150.0, elevation=-20.0)
        s_done = np.array([path.closest(T[:3, 3]) for T in sim.poses[picks]])
        ffig, fax = plt.subplots(1, len(frames), figsize=(3.2 * len(frames), 2.9))
        for k, (axk, frame) in enumerate(zip(np.atleast_1d(fax), frames, strict=True)):
            axk.imshow(frame)
            axk.set_axis_off()
            axk.set_title(f"t = {sim.t[picks[k]]:.2f} s\n{s_done[k] * 1e3:.0f} of {path.length * 1e3:.0f} mm "
                          f"along the line, q5 = {sim.q[picks[k], 4]:+.3f} rad", fontsize=8)
        ffig.suptitle("MuJoCo (position servos) following the wrist line: rendered frames", fontsize=10)
        ffig.tight_layout(rect=(0, 0, 1, 0.9))
        ffig.savefig(OUT / "07_mujoco_simulation_frames.png", dpi=100)
        plt.close(ffig)
        rendered = f"rendered {len(frames)} frames with MUJOCO_GL={GL}"

    print(run.summary())
    print(sim.summary())
    print(f"max |p_sim − p_kin|: position servos {gap.max() * 1e3:.3f} mm, "
          f"velocity servos {gap_v.max() * 1e3:.3f} mm (the plot marks 2 mm)")
    print(f"max distance from the line in simulation: {path_err.max() * 1e3:.3f} mm; "
          f"{log.substeps} physics steps per control period")
    print(f"{rendered}; wrote {OUT / '07_mujoco_simulation.png'}")


if __name__ == "__main__":
    main()
