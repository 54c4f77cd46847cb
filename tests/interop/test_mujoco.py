"""MuJoCo/mink interop: MJCF export, round trips, mink Jacobians, collision rows, simulation."""

from pathlib import Path

import numpy as np
import pytest

import ratectl as rc

mujoco = pytest.importorskip("mujoco")
mink = pytest.importorskip("mink")

from ratectl.interop.mujoco import (  # noqa: E402
    MinkKinematics,
    MinkLimitedSolver,
    geom_distance,
    mink_inequalities,
    mujoco_fk_jacobian,
    simulate,
    to_mjcf,
)

DATA = Path(__file__).resolve().parents[1] / "data"
ARMS = ["ur5e", "panda", "puma560", "stanford", "iiwa7", "rpr", "planar2r"]


def _with_base_and_tool(chain):
    base = rc.spatial.transform(rc.spatial.rotation_from_rpy([0.1, -0.2, 0.3]), [0.1, -0.2, 0.05])
    tool = rc.spatial.transform(rc.spatial.rotation_from_rpy([0.0, 0.4, -0.1]), [0.01, 0.02, 0.12])
    return chain.with_base(base).with_tool(tool)


@pytest.mark.parametrize("name", ARMS)
def test_to_mjcf_kinematics_equal_ratectl(name, rng):
    chain = _with_base_and_tool(rc.robots.BUILTIN[name]())
    model = mujoco.MjModel.from_xml_string(to_mjcf(chain))
    data = mujoco.MjData(model)
    assert model.nq == chain.dof and model.nu == 0
    # joint types and limits
    for k, j in enumerate(chain.joints):
        assert model.jnt_type[k] == (3 if j.kind == "revolute" else 2)
        if np.isfinite(j.qlim).all():
            assert model.jnt_limited[k]
            np.testing.assert_array_equal(model.jnt_range[k], j.qlim)
    worst = 0.0
    for q in chain.random_q(100, rng=rng):
        T, J = mujoco_fk_jacobian(model, data, chain, q, frame="tool")
        # independent read-out: MuJoCo's site pose and mj_jacSite (world axes, at the site)
        sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "tool")
        jp, jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        mujoco.mj_jacSite(model, data, jp, jr, sid)
        np.testing.assert_array_equal(T[:3, 3], data.site_xpos[sid])
        np.testing.assert_array_equal(J, np.vstack([jp, jr]))
        Tc, Jc = chain.fk_jacobian(q)
        worst = max(worst, np.max(np.abs(T - Tc)), np.max(np.abs(J - Jc)))
    assert worst < 1e-10


@pytest.mark.parametrize("name", ARMS)
def test_export_import_round_trip(name, rng):
    chain = _with_base_and_tool(rc.robots.BUILTIN[name]())
    back = rc.Chain.from_mjcf(to_mjcf(chain), tip="tool")
    assert back.joint_names == chain.joint_names
    np.testing.assert_array_equal(back.prismatic, chain.prismatic)
    np.testing.assert_array_equal(back.lower, chain.lower)
    np.testing.assert_array_equal(back.upper, chain.upper)
    qs = chain.random_q(100, rng=rng)
    assert np.max(np.abs(back.fk(qs) - chain.fk(qs))) < 1e-10
    assert np.max(np.abs(back.jacobian(qs) - chain.jacobian(qs))) < 1e-10


def test_round_trip_keeps_unlimited_and_one_sided_joints(rng):
    joints = [rc.Joint(kind="revolute", name="free"),
              rc.Joint(kind="revolute", pre=rc.spatial.transform(rc.spatial.rotx(0.4), [0, 0, 0.2]),
                       qlim=(-1.0, np.inf), name="lower_only"),
              rc.Joint(kind="prismatic", pre=rc.spatial.translation(0.3, 0, 0), qlim=(-np.inf, 0.2),
                       name="upper_only")]
    chain = rc.Chain(joints, tool=rc.spatial.translation(0, 0, 0.1), name="odd")
    back = rc.Chain.from_mjcf(to_mjcf(chain), tip="tool")
    np.testing.assert_array_equal(back.lower, chain.lower)
    np.testing.assert_array_equal(back.upper, chain.upper)
    qs = chain.random_q(20, rng=rng)
    assert np.max(np.abs(back.fk(qs) - chain.fk(qs))) < 1e-12


@pytest.mark.parametrize("fname,tip", [("ur5e_like.urdf", "tool0"), ("panda_like.urdf", "hand_tcp")])
def test_urdf_to_mjcf_round_trip(fname, tip, rng):
    chain = rc.Chain.from_urdf(DATA / fname, tip=tip)
    back = rc.Chain.from_mjcf(to_mjcf(chain), tip="tool")
    qs = chain.random_q(50, rng=rng)
    assert np.max(np.abs(back.fk(qs) - chain.fk(qs))) < 1e-10
    np.testing.assert_array_equal(back.upper, chain.upper)


def test_to_mjcf_options_and_errors():
    chain = rc.robots.ur5e()
    xml = to_mjcf(chain, actuators="position", kp=1000.0, floor=True,
                  obstacles=[{"name": "ball", "type": "sphere", "size": 0.05, "pos": (0.4, 0, 0.3)}])
    model = mujoco.MjModel.from_xml_string(xml)
    assert model.nu == 6
    np.testing.assert_allclose(model.actuator_gainprm[:, 0], 1000.0)
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "ball") >= 0
    vel = mujoco.MjModel.from_xml_string(to_mjcf(chain, actuators="velocity", kv=50.0))
    np.testing.assert_allclose(vel.actuator_biasprm[:, 2], -50.0)
    with pytest.raises(rc.InputError, match="actuators"):
        to_mjcf(chain, actuators="torque")
    with pytest.raises(rc.InputError, match="radius"):
        to_mjcf(chain, radius=-1.0)
    with pytest.raises(rc.InputError, match="ratectl.Chain"):
        to_mjcf("ur5e")


# ---------------------------------------------------------------- mink
def test_mink_body_jacobian_converts_to_ratectl(rng):
    chain = _with_base_and_tool(rc.robots.panda())
    model = mujoco.MjModel.from_xml_string(to_mjcf(chain))
    kin = MinkKinematics(mink.Configuration(model), frame="tool", chain=chain)
    assert kin.dof == 7 and kin.joint_names == chain.joint_names  # limits etc. from the chain
    for q in chain.random_q(30, rng=rng):
        T, J = kin.fk_jacobian(q)
        Tc, Jc = chain.fk_jacobian(q)
        assert np.max(np.abs(T - Tc)) < 1e-12
        assert np.max(np.abs(J - Jc)) < 1e-12
        # mink's own output is the body (tool-axes) Jacobian: ratectl's frame="tool"
        assert np.max(np.abs(kin.body_jacobian(q) - chain.jacobian(q, frame="tool"))) < 1e-12
        # and it is NOT the base-axes Jacobian (the conversion matters)
        assert np.max(np.abs(kin.body_jacobian(q) - Jc)) > 1e-3
    # batched q and the other options go through the same conversion
    qs = chain.random_q((2, 3), rng=rng)
    np.testing.assert_allclose(kin.jacobian(qs, frame="tool", point=[0, 0, 0.1]),
                               chain.jacobian(qs, frame="tool", point=[0, 0, 0.1]), atol=1e-12)


def test_mink_kinematics_on_an_imported_mjcf_with_extra_joints(rng):
    # Panda-like MJCF: the fingers are joints of the model but not of the chain
    model = mujoco.MjModel.from_xml_path(str(DATA / "panda_like.xml"))
    kin = MinkKinematics(model, frame="tcp")
    chain = rc.Chain.from_mjcf(DATA / "panda_like.xml", tip="tcp")
    assert kin.dof == 7
    for q in chain.random_q(20, rng=rng):
        T, J = kin.fk_jacobian(q)
        assert np.max(np.abs(T - chain.fk(q))) < 1e-12
        assert np.max(np.abs(J - chain.jacobian(q))) < 1e-12


def _obstacle_scene():
    arm = rc.robots.ur5e()
    q0 = np.array([0.0, -1.9, 1.9, -1.57, -1.57, 0.0])
    T0 = arm.fk(q0)
    goal = T0.copy()
    goal[:3, 3] += [0.0, 0.45, 0.0]
    centre = (T0[:3, 3] + goal[:3, 3]) / 2 - [0.0, 0.0, 0.07]
    xml = to_mjcf(arm, obstacles=[{"name": "ball", "type": "sphere", "size": 0.06, "pos": centre}])
    model = mujoco.MjModel.from_xml_string(xml)
    links = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, i) for i in range(model.ngeom)]
    links = [g for g in links if g.startswith("link")]
    return arm, q0, goal, model, links


def test_collision_rows_have_velocity_units():
    arm, q0, goal, model, links = _obstacle_scene()
    kin = MinkKinematics(model, frame="tool", chain=arm)
    margin, gain, dt = 0.02, 0.1, 0.01
    lim = mink.CollisionAvoidanceLimit(model, [(links, ["ball"])], gain=gain,
                                       minimum_distance_from_collisions=margin,
                                       collision_detection_distance=0.3)
    # move toward the ball until the pair is within the detection distance
    q = q0 + np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    kin.update(q)
    G, h = mink_inequalities([lim], kin.configuration, dt=dt, dofs=kin.dof_indices)
    assert G.shape[0] >= 1 and G.shape[1] == 6
    data = kin.configuration.data
    pairs = [(g, "ball") for g in links]
    d0 = geom_distance(model, data, pairs)
    assert margin < d0 < 0.3
    # the tightest row: closing speed bound gain·(d − margin)/dt [m/s]
    k = int(np.argmin(h))
    np.testing.assert_allclose(h[k], gain * (d0 - margin) / dt, rtol=1e-9)
    # mink's literal bound (its dt) is 1/dt larger than the displacement it allows
    raw = lim.compute_qp_inequalities(kin.configuration, dt)
    assert np.min(raw.h[np.isfinite(raw.h)]) == pytest.approx(h[k])  # same number ...
    # ... but ratectl applies it to q̇, so one step at the bound closes gain·(d − margin)
    # (to first order in the step):
    qd = G[k] / (G[k] @ G[k]) * h[k]  # G q̇ = h exactly, smallest such q̇
    q1 = q + qd * dt
    data.qpos[:6] = q1
    mujoco.mj_kinematics(model, data)
    d1 = geom_distance(model, data, pairs)
    assert d0 - d1 == pytest.approx(gain * (d0 - margin), rel=0.05)
    assert d1 > margin
    # mink's other limits are displacement bounds: divided by dt
    vel = mink.VelocityLimit(model, {n: 2.0 for n in arm.joint_names})
    cfg_lim = mink.ConfigurationLimit(model, gain=0.9)
    kin.update(q)
    Gv, hv = mink_inequalities([vel], kin.configuration, dt=dt)
    np.testing.assert_allclose(hv, 2.0)
    Gc, hc = mink_inequalities([cfg_lim], kin.configuration, dt=dt)
    np.testing.assert_allclose(hc[:6], 0.9 * (arm.upper - q) / dt, rtol=1e-9)
    # rows keep their number when asked (a warm QP keeps its structure)
    far = q0.copy()
    far[0] += 2.0
    kin.update(far)
    G2, h2 = mink_inequalities([lim], kin.configuration, dt=dt, dofs=kin.dof_indices, keep_inactive=True)
    assert G2.shape[0] == len(lim.geom_id_pairs) and np.isinf(h2).any()
    with pytest.raises(rc.InputError, match="dt"):
        mink_inequalities([lim], kin.configuration, dt=0.0)


def _run_to_goal(kin, solver, goal, q0, model, pairs, *, steps=800, dt=0.01):
    ctrl = rc.ResolvedRateController(kin, solver=solver, gain=2.0)
    data = mujoco.MjData(model)
    q = q0.copy()
    dmin = np.inf
    for _ in range(steps):
        cmd = ctrl.step(q, target=goal, dt=dt)
        assert cmd.status != "halted", cmd.reason
        q = cmd.q_next
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        dmin = min(dmin, geom_distance(model, data, pairs, distmax=1.0))
    return q, dmin, cmd


def test_collision_aware_run_keeps_the_margin_and_reaches_the_goal():
    arm, q0, goal, model, links = _obstacle_scene()
    pairs = [(g, "ball") for g in links]
    margin = 0.02
    # unconstrained: the straight approach runs the wrist through the ball
    kin = MinkKinematics(model, frame="tool", chain=arm)
    q_free, d_free, _ = _run_to_goal(kin, MinkLimitedSolver(kin, []), goal, q0, model, pairs)
    assert d_free < 0.0  # penetration: a collision
    assert np.linalg.norm(arm.fk(q_free)[:3, 3] - goal[:3, 3]) < 1e-4
    # collision-aware: mink's CollisionAvoidanceLimit as QP rows
    kin = MinkKinematics(model, frame="tool", chain=arm)
    lim = mink.CollisionAvoidanceLimit(model, [(links, ["ball"])], gain=0.1,
                                       minimum_distance_from_collisions=margin,
                                       collision_detection_distance=0.15)
    solver = MinkLimitedSolver(kin, [lim])
    q, dmin, cmd = _run_to_goal(kin, solver, goal, q0, model, pairs)
    assert dmin >= margin - 1e-4, dmin
    assert dmin < margin + 0.01  # the rows were active: the arm went around at the margin
    err = rc.spatial.pose_error(goal, arm.fk(q))
    assert np.linalg.norm(err[:3]) < 1e-4 and np.linalg.norm(err[3:]) < 1e-3


def test_collision_aware_run_reports_an_unreachable_goal():
    # the goal lies inside the obstacle: the run stops at the margin and the command says why
    arm, q0, goal, model, links = _obstacle_scene()
    ball = model.geom(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "ball"))
    inside = goal.copy()
    inside[:3, 3] = ball.pos + [0.0, 0.0, 0.02]
    kin = MinkKinematics(model, frame="tool", chain=arm)
    lim = mink.CollisionAvoidanceLimit(model, [(links, ["ball"])], gain=0.1,
                                       minimum_distance_from_collisions=0.02,
                                       collision_detection_distance=0.15)
    solver = MinkLimitedSolver(kin, [lim])
    q, dmin, cmd = _run_to_goal(kin, solver, inside, q0, model, [(g, "ball") for g in links], steps=400)
    assert dmin >= 0.02 - 1e-4
    assert cmd.position_error > 0.02  # it did not get there ...
    G, h = solver.last_rows
    active = G @ cmd.qd >= h - 1e-6
    assert active.any()  # ... because a collision row binds
    assert "extra_active" in cmd.solve.info and cmd.solve.info["extra_active"].any()


# ---------------------------------------------------------------- simulation
def _wrist_line():
    """UR5e line at 0.2 m/s and constant orientation passing 0.01 rad from the wrist singularity."""
    arm = rc.robots.ur5e()
    q_mid = np.array([0.2, -1.4, 1.6, -1.8, 0.01, 0.3])
    T_mid = arm.fk(q_mid)
    T0, T1 = T_mid.copy(), T_mid.copy()
    T0[0, 3] -= 0.15
    T1[0, 3] += 0.15
    path = rc.paths.Line(T0, T1, speed=0.2, acceleration=1.0)
    q0 = q_mid.copy()
    for _ in range(100):  # damped Newton onto the start pose (stays on q_mid's branch)
        e = rc.spatial.pose_error(T0, arm.fk(q0))
        q0 = q0 + 0.5 * np.linalg.lstsq(arm.jacobian(q0), e, rcond=None)[0]
    assert np.all(arm.within_limits(q0)) and abs(q0[4]) < 0.2
    assert np.linalg.norm(rc.spatial.pose_error(T0, arm.fk(q0))) < 1e-10
    return arm, path, q0


@pytest.fixture(scope="module")
def wrist_run():
    arm, path, q0 = _wrist_line()
    return arm, path, q0, rc.follow(arm, path, q0, dt=0.01)


@pytest.mark.parametrize("actuation", ["position", "velocity"])
def test_simulated_follow_run_tracks_the_kinematic_run(wrist_run, actuation):
    arm, path, q0, run = wrist_run
    assert run.completed
    sim, log = simulate(None, arm, run, q0, dt=0.01, actuation=actuation)
    assert isinstance(sim, rc.Execution) and sim.source == "simulate"
    assert sim.completed, sim.message
    assert len(sim.t) == len(run.t)
    np.testing.assert_allclose(sim.t, run.t, atol=1e-12)
    gap = np.linalg.norm(sim.poses[:, :3, 3] - run.poses[:, :3, 3], axis=1)
    assert gap.max() < 2e-3  # within 2 mm of the kinematic run at every step
    assert gap.max() > 1e-6  # and it is a physics run, not a copy
    # the measured state is what MuJoCo reports, and the record is self-consistent
    np.testing.assert_allclose(sim.poses, arm.fk(sim.q), atol=1e-12)
    assert max(path.distance(T)[0] for T in sim.poses) < 2e-3
    assert sim.velocity_ratio <= 1.0 + 1e-9  # measured |q̇| within vmax
    assert log.substeps == 10 and log.qd_command.shape == (len(run.t) - 1, 6)
    assert np.all(np.isfinite(log.tau)) and np.max(np.abs(log.tau)) > 0


def test_simulated_time_law_run_tracks_the_kinematic_loop():
    arm, path, q0 = _wrist_line()
    kin, klog = simulate(None, arm, path, q0, dt=0.01, physics=False, settle=0.2)
    assert kin.source == "simulate (kinematic)" and klog.physics is False
    for actuation in ("position", "velocity"):
        sim, _ = simulate(None, arm, path, q0, dt=0.01, actuation=actuation, settle=0.2)
        gap = np.linalg.norm(sim.poses[:, :3, 3] - kin.poses[:, :3, 3], axis=1)
        assert gap.max() < 2e-3
        # errors are distances from the path, as in follow()
        k = len(sim.t) // 2
        assert sim.position_error[k] == pytest.approx(path.distance(sim.poses[k])[0], abs=1e-9)


def test_simulate_targets_and_user_models():
    arm = rc.robots.ur5e()
    q0 = np.array([0.3, -1.6, 1.7, -1.7, -1.57, 0.2])
    T0 = arm.fk(q0)
    A, B = T0.copy(), T0.copy()
    A[:3, 3] += [0.05, 0.0, 0.05]
    B[:3, 3] += [0.0, 0.08, 0.0]
    xml = to_mjcf(arm, actuators="velocity")
    sim, _ = simulate(xml, arm, [A, B], q0, dt=0.005, actuation="velocity", duration=5.0)
    assert sim.completed, sim.message
    assert np.linalg.norm(sim.poses[-1][:3, 3] - B[:3, 3]) < 1e-3
    assert sim.t[-1] < 5.0  # stops once the last target is reached
    # a model without the requested actuators is refused, naming the joint
    with pytest.raises(rc.InputError, match="shoulder_pan"):
        simulate(to_mjcf(arm, actuators="velocity"), arm, A, q0, dt=0.01, actuation="position")
    with pytest.raises(rc.InputError, match="multiple"):
        simulate(None, arm, A, q0, dt=0.0015)
    with pytest.raises(rc.InputError, match="actuation"):
        simulate(None, arm, A, q0, dt=0.01, actuation="torque")
    with pytest.raises(rc.InputError, match="path_or_targets"):
        simulate(None, arm, "somewhere", q0, dt=0.01)


def test_simulate_reports_an_unstable_model():
    arm = rc.robots.ur5e()
    q0 = np.array([0.3, -1.6, 1.7, -1.7, -1.57, 0.2])
    T = arm.fk(q0)
    T[:3, 3] += [0.0, 0.1, 0.0]
    xml = to_mjcf(arm, actuators="position", kp=1e10, kv=0.0, armature=0.0, timestep=0.002)
    sim, _ = simulate(xml, arm, T, q0, dt=0.01, duration=2.0)
    assert not sim.completed
    assert "unstable" in sim.message


def test_pick_gl_backend_reports_none_when_nothing_renders():
    """A backend that does not exist is probed in a child process and refused (None)."""
    import subprocess
    import sys

    code = ("import os; os.environ['MUJOCO_GL'] = 'no-such-backend'; "
            "from ratectl.interop.offscreen_gl import pick_gl_backend; print(pick_gl_backend())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "None", out.stderr


def test_pick_gl_backend_after_mujoco_is_imported_reports_what_is_in_force(monkeypatch):
    from ratectl.interop.offscreen_gl import pick_gl_backend

    monkeypatch.setenv("MUJOCO_GL", "egl")
    assert pick_gl_backend() == "egl"  # mujoco is already imported here: nothing is probed


def test_mink_limited_solver_bounds_the_total_command_with_a_joint_feed_forward():
    """A `MinkLimitedSolver` sets ``enforces_limits`` (from the QP it wraps), so the
    controller hands it the joint feed-forward ``qd_ff`` and its box holds for the total
    q̇_ff + correction: a feed-forward at vmax into joint 1's upper limit, 2 cm away, with
    a new dt every few periods, stops at the limit within vmax and amax (the controller
    does not limit the answer again)."""
    arm, _, _, model, links = _obstacle_scene()
    kin = MinkKinematics(model, frame="tool", chain=arm)
    lim = mink.CollisionAvoidanceLimit(model, [(links, ["ball"])], gain=0.1,
                                       minimum_distance_from_collisions=0.02,
                                       collision_detection_distance=0.15)
    solver = MinkLimitedSolver(kin, [lim])
    assert solver.enforces_limits
    ctrl = rc.ResolvedRateController(kin, solver=solver)
    q = np.array([0.3, -1.3, 1.6, -1.9, -1.2, 0.2])
    q[0] = arm.upper[0] - 0.02
    T = arm.fk(q)
    qd_ff = np.zeros(6)
    qd_ff[0] = arm.vmax[0]
    prev = np.zeros(6)
    rng = np.random.default_rng(5)
    dt = 1e-3
    for k in range(300):
        if k % 3 == 0:
            dt = float(rng.choice([1e-3, 2e-3, 4e-3, 1e-2]))
        cmd = ctrl.step(q, target=T, qd_ff=qd_ff, dt=dt)
        assert cmd.status != "halted", cmd.reason
        assert np.allclose(cmd.qd, cmd.solve.qd + qd_ff)  # the solver resolved the correction
        assert "acceleration_bounds_dropped" not in cmd.solve.info
        assert np.all(np.abs(cmd.qd) <= arm.vmax * (1 + 1e-9))
        assert np.all(np.abs(cmd.qd - prev) <= arm.amax * dt * (1 + 1e-6)), k
        prev = np.array(cmd.qd)
        q = np.array(cmd.q_next)
        assert np.all(q <= arm.upper + 1e-9) and np.all(q >= arm.lower - 1e-9)
    assert q[0] > arm.upper[0] - 1e-3 and abs(cmd.qd[0]) < 1e-6  # it reached the limit and held
