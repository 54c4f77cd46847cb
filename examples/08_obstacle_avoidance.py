"""Reach past an obstacle: ratectl's controller on MuJoCo kinematics with mink's collision rows.

A UR5e (exported to MJCF with a 6 cm ball just below the straight line to the goal)
is driven to a goal pose by ``rc.ResolvedRateController``. The kinematics come from
MuJoCo through ``mink.Configuration`` (``MinkKinematics``). With no limits the tool
passes above the ball but a link of the arm (the forearm or wrist, whichever is
nearest) runs through it; with ``mink.CollisionAvoidanceLimit`` turned into velocity rows
of ratectl's QP (``MinkLimitedSolver``) it goes around it at the 2 cm margin and still
reaches the goal. The plot shows the smallest link–ball distance over time and, in the
y–z plane, the arm at its closest approach in both runs with the path of the arm's
point nearest the ball (not only the tool path, which never touches the ball). Saves a
plot (and a GIF of the avoiding motion where an offscreen OpenGL context exists) under
``examples/out/`` and prints a summary.

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

from ratectl.interop.mujoco import MinkKinematics, MinkLimitedSolver, render_frames, to_mjcf  # noqa: E402

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
    ball = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "ball")
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, g) for g in links]
    fromto = np.zeros(6)
    q = q0.copy()
    qs, dist, tool, near, near_link, bound = [q.copy()], [], [], [], [], 0
    for _ in range(STEPS):
        cmd = ctrl.step(q, target=goal, dt=DT)
        if cmd.solve is not None and np.any(cmd.solve.info.get("extra_active", False)):
            bound += 1
        q = cmd.q_next
        qs.append(q.copy())
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        best = (np.inf, None, None)
        for name, gid in zip(links, ids, strict=True):
            d = mujoco.mj_geomDistance(model, data, gid, ball, 1.0, fromto)
            if d < best[0]:
                best = (d, name, fromto[:3].copy())      # the point on the link
        dist.append(best[0])
        near.append(best[2])
        near_link.append(best[1])
        tool.append(arm.fk(q)[:3, 3])
    return np.array(qs), np.array(dist), np.array(tool), np.array(near), near_link, cmd, bound


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

    q_free, d_free, p_free, n_free, l_free, c_free, _ = run(model, arm, q0, goal, links, avoid=False)
    q_safe, d_safe, p_safe, n_safe, l_safe, c_safe, bound = run(model, arm, q0, goal, links, avoid=True)
    k_free, k_safe = int(np.argmin(d_free)), int(np.argmin(d_safe))
    hit = l_free[k_free]
    t = np.arange(1, STEPS + 1) * DT

    fig, ax = plt.subplots(1, 2, figsize=(13, 4.8))
    ax[0].plot(t, d_free * 1e3, label="no collision rows")
    ax[0].plot(t, d_safe * 1e3, label="mink CollisionAvoidanceLimit rows")
    ax[0].axhline(MARGIN * 1e3, color="k", ls=":", lw=1, label="margin 20 mm")
    ax[0].axhline(0.0, color="r", lw=0.8)
    ax[0].set_xlabel("t [s]")
    ax[0].set_ylabel("smallest link–ball distance [mm]")
    ax[0].set_ylim(-30, 150)
    ax[0].legend()
    ax[1].add_patch(plt.Circle((centre[1], centre[2]), radius, color="tab:red", alpha=0.4, label="ball"))
    for q_run, k, n_run, p_run, colour, name in (
            (q_free, k_free, n_free, p_free, "C0", "no collision rows"),
            (q_safe, k_safe, n_safe, p_safe, "C1", "with collision rows")):
        o = rc.robots.ur5e().frames(q_run[k + 1])[:, :3, 3]          # joint origins at the closest approach
        ax[1].plot(o[:, 1], o[:, 2], "-o", color=colour, lw=2.5, ms=3, alpha=0.8,
                   label=f"arm at its closest approach ({name})")
        ax[1].plot(n_run[:, 1], n_run[:, 2], ":", color=colour, lw=1.2)
        ax[1].plot(p_run[:, 1], p_run[:, 2], "--", color=colour, lw=0.8, alpha=0.6)
    ax[1].plot([], [], "k:", lw=1.2, label="path of the arm's point nearest the ball")
    ax[1].plot([], [], "k--", lw=0.8, alpha=0.6, label="tool path")
    ax[1].plot(n_free[k_free, 1], n_free[k_free, 2], "rx", ms=9, mew=2, label=f"collision ({hit})")
    ax[1].plot([T0[1, 3], goal[1, 3]], [T0[2, 3], goal[2, 3]], "ko", ms=4)
    ax[1].set_xlabel("y [m] (arm projected on the y–z plane)")
    ax[1].set_ylabel("z [m]")
    ax[1].set_aspect("equal")
    ax[1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
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
          f"({'COLLISION of ' + hit if d_free.min() < 0 else 'clear'}, at t = {(k_free + 1) * DT:.2f} s), "
          f"goal error {err_free * 1e3:.3f} mm")
    print(f"with collision rows:    min distance {d_safe.min() * 1e3:+.1f} mm "
          f"(margin {MARGIN * 1e3:.0f} mm), goal error {err_safe * 1e3:.3f} mm, "
          f"a collision row bound on {bound} of {STEPS} steps")
    print(f"{rendered}; wrote {OUT / '08_obstacle_avoidance.png'}")


if __name__ == "__main__":
    main()
