"""The public names of the package, called exactly as the README and the guides write them."""

import numpy as np

import ratectl as rc


def test_design_public_names_work_as_written():
    rows = [rc.DH(a=0.0, alpha=np.pi / 2, d=0.3, theta=0.0, joint="revolute", qlim=(-3.0, 3.0),
                  vmax=2.0, amax=10.0, jmax=100.0),
            rc.DH(a=0.4, alpha=0.0, d=0.0, theta=0.0, joint="revolute", qlim=(-2.0, 2.0)),
            rc.DH(a=0.0, alpha=0.0, d=0.1, theta=0.0, joint="prismatic", qlim=(0.0, 0.5))]
    tool = np.eye(4)
    tool[2, 3] = 0.05
    chain = rc.Chain.from_dh(rows, base=None, tool=tool, name="three")
    mdh = rc.Chain.from_mdh([rc.MDH(a=0.0, alpha=0.0, d=0.2, theta=0.0, joint="revolute")],
                            tool=tool, name="one")
    assert chain.dof == 3 and mdh.dof == 1 and chain.name == "three"
    q = np.array([0.1, 0.2, 0.3])
    assert chain.fk(q).shape == (4, 4)
    assert chain.jacobian(q).shape == (6, 3) and chain.jacobian(q, frame="tool").shape == (6, 3)

    arms = [rc.robots.ur5e(), rc.robots.panda(), rc.robots.puma560(), rc.robots.stanford(),
            rc.robots.iiwa7()]
    ur = arms[0]
    qs = ur.random_q(5, rng=1)
    J = ur.jacobian(qs)
    assert rc.singular_values(J[0]).shape == (6,) and rc.singular_values(J).shape == (5, 6)
    assert rc.manipulability(J[0]).shape == () and rc.manipulability(J).shape == (5,)
    q_wrist = np.array([0.0, -1.2, 1.4, -1.8, 0.0, 0.3])
    assert rc.analyze(ur, q_wrist).kind == "wrist"

    Jr = ur.jacobian(qs[0])
    xi = np.array([0.01, 0.0, -0.02, 0.0, 0.05, 0.0])
    for solver in (rc.solvers.Inverse(), rc.solvers.PseudoInverse(), rc.solvers.DLS(damping=0.01),
                   rc.solvers.AdaptiveDLS(epsilon=0.05, max_damping=0.05), rc.solvers.SDLS(),
                   rc.solvers.QP()):
        assert solver.solve(Jr, xi).qd.shape == (6,)

    ctrl = rc.ResolvedRateController(ur, solver=rc.solvers.DLS(damping=0.01))
    T_des = ur.fk(qs[0])
    cmd = ctrl.step(qs[0], target=T_des, twist=np.zeros(6), dt=1e-3)
    assert cmd.qd.shape == (6,) and isinstance(cmd.status, str)

    q0 = np.array([0.3, -1.3, 1.6, -1.9, -1.2, 0.2])
    T_start = ur.fk(q0)
    T_end = T_start.copy()
    T_end[:3, 3] += [0.0, 0.05, 0.0]
    path = rc.paths.Line(T_start, T_end, speed=0.1, acceleration=0.5)
    run = rc.follow(ur, path, q0, dt=2e-3, controller=None)
    k = len(run.t)
    assert run.q.shape == (k, 6) and run.qd.shape == (k, 6) and run.qdd.shape == (k, 6)
    assert run.position_error.shape == (k,) and run.orientation_error.shape == (k,)
    assert run.completed and float(run.position_error.max()) < 1e-3
