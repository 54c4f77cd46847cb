"""Reach past an obstacle: ratectl's controller on MuJoCo kinematics with mink's collision rows.

A UR5e (exported to MJCF with a 6 cm ball just below the straight line to the goal)
is driven to a goal pose by ``rc.ResolvedRateController``. The kinematics come from
MuJoCo through ``mink.Configuration`` (``MinkKinematics``). With no limits the wrist
runs through the ball; with ``mink.CollisionAvoidanceLimit`` turned into velocity rows
of ratectl's QP (``MinkLimitedSolver``) it goes around it at the 2 cm margin and still
reaches the goal. Saves a plot (and a GIF of the avoiding motion where an offscreen
OpenGL context exists) under ``examples/out/`` and prints a summary.

``RATECTL_FAST=1``: fewer GIF frames (a few seconds).
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
import mink  # noqa: E402
import mujoco  # noqa: E402

from ratectl.interop.mujoco import MinkKinematics, MinkLimitedSolver, geom_distance, render_frames, to_mjcf  # noqa: E402

MARGIN = 0.02      # configured minimum distance [m]
DT = 0.01          # control period [s]
STEPS = 600


def run(model, arm, q0, goal, links, *, avoid: bool):
    kin = MinkKinematics(mink.Configuration(model), frame="tool", chain=arm)
    limits = []
    if avoid:
        limits.append(mink.CollisionAvoidanceLimit(model, [(links, ["ball"])], gain=0.1,
                                                   minimum_distance_from_collisions=MARGIN,
                                                   collision_detection_distance=0.15))
    solver = MinkLimitedSolver(kin, limits)
    ctrl = rc.ResolvedRateController(kin, solver=solver, gain=2.0)
    data = mujoco.MjData(model)
    pairs = [(g, "ball") for g in links]
    q = q0.copy()
    qs, dist, tool, bound = [q.copy()], [], [], 0
    for _ in range(STEPS):
        cmd = ctrl.step(q, target=goal, dt=DT)
        if cmd.solve is not None and np.any(cmd.solve.info.get("extra_active", False)):
            bound += 1
        q = cmd.q_next
        qs.append(q.copy())
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        dist.append(geom_distance(model, data, pairs))
        tool.append(arm.fk(q)[:3, 3])
    return np.array(qs), np.array(dist), np.array(tool), cmd, bound


def main():
    OUT.mkdir(exist_ok=True)
    arm = rc.robots.ur5e()
    q0 = np.array([0.0, -1.9, 1.9, -1.57, -1.57, 0.0])
    T0 = arm.fk(q0)
    goal = T0.copy()
    goal[:3, 3] += [0.0, 0.45, 0.0]
    centre = (T0[:3, 3] + goal[:3, 3]) / 2 - [0.0, 0.0, 0.07]
    radius = 0.06
    xml = to_mjcf(arm, floor=True,
                  obstacles=[{"name": "ball", "type": "sphere", "size": radius, "pos": centre}])
    model = mujoco.MjModel.from_xml_string(xml)
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, i) for i in range(model.ngeom)]
    links = [g for g in names if g and g.startswith("link")]

    q_free, d_free, p_free, c_free, _ = run(model, arm, q0, goal, links, avoid=False)
    q_safe, d_safe, p_safe, c_safe, bound = run(model, arm, q0, goal, links, avoid=True)
    t = np.arange(1, STEPS + 1) * DT

    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    ax[0].plot(t, d_free * 1e3, label="no collision rows")
    ax[0].plot(t, d_safe * 1e3, label="mink CollisionAvoidanceLimit rows")
    ax[0].axhline(MARGIN * 1e3, color="k", ls=":", lw=1, label="margin 20 mm")
    ax[0].axhline(0.0, color="r", lw=0.8)
    ax[0].set_xlabel("t [s]")
    ax[0].set_ylabel("smallest link–ball distance [mm]")
    ax[0].set_ylim(-30, 150)
    ax[0].legend()
    ax[1].plot(p_free[:, 1], p_free[:, 2], label="no collision rows")
    ax[1].plot(p_safe[:, 1], p_safe[:, 2], label="with collision rows")
    ax[1].add_patch(plt.Circle((centre[1], centre[2]), radius, color="tab:red", alpha=0.4, label="ball"))
    ax[1].plot([T0[1, 3], goal[1, 3]], [T0[2, 3], goal[2, 3]], "ko", ms=4)
    ax[1].set_xlabel("tool y [m]")
    ax[1].set_ylabel("tool z [m]")
    ax[1].set_aspect("equal")
    ax[1].legend(fontsize=8)
    fig.suptitle("UR5e reaching past a ball: ratectl QP + mink collision rows (MuJoCo kinematics)")
    fig.tight_layout()
    fig.savefig(OUT / "08_obstacle_avoidance.png", dpi=110)
    plt.close(fig)

    rendered = "no offscreen OpenGL (EGL/OSMesa): plot only"
    if GL is not None:
        from PIL import Image

        n_frames = 8 if FAST else 30
        picks = np.linspace(0, np.argmax(np.linalg.norm(p_safe - goal[:3, 3], axis=1) < 1e-3) or STEPS,
                            n_frames).astype(int)
        data = mujoco.MjData(model)
        frames = render_frames(model, data, arm, q_safe[picks], width=320, height=240,
                               lookat=(-0.3, 0.1, 0.35), distance=1.3, azimuth=180.0, elevation=-15.0)
        imgs = [Image.fromarray(f) for f in frames]
        imgs[0].save(OUT / "08_obstacle_avoidance.gif", save_all=True, append_images=imgs[1:],
                     duration=80, loop=0)
        rendered = f"rendered a {n_frames}-frame GIF with MUJOCO_GL={GL}"

    err_free = np.linalg.norm(rc.spatial.pose_error(goal, arm.fk(q_free[-1]))[:3])
    err_safe = np.linalg.norm(rc.spatial.pose_error(goal, arm.fk(q_safe[-1]))[:3])
    print(f"without collision rows: min distance {d_free.min() * 1e3:+.1f} mm "
          f"({'COLLISION' if d_free.min() < 0 else 'clear'}), goal error {err_free * 1e3:.3f} mm")
    print(f"with collision rows:    min distance {d_safe.min() * 1e3:+.1f} mm "
          f"(margin {MARGIN * 1e3:.0f} mm), goal error {err_safe * 1e3:.3f} mm, "
          f"a collision row bound on {bound} of {STEPS} steps")
    print(f"{rendered}; wrote {OUT / '08_obstacle_avoidance.png'}")


if __name__ == "__main__":
    main()
