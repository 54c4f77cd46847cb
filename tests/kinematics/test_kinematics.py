"""Kinematic core: finite differences, closed forms, batching, conventions."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ratectl as rc
from ratectl.kinematics import numerical_jacobian, rotate_jacobian, shift_jacobian


def test_jacobian_matches_finite_differences(arm, rng):
    for _ in range(20):
        q = arm.random_q(rng=rng)
        J = arm.jacobian(q)
        Jfd = numerical_jacobian(arm, q)
        assert np.max(np.abs(J - Jfd)) < 1e-7


def test_tool_frame_jacobian_matches_finite_differences(arm, rng):
    for _ in range(10):
        q = arm.random_q(rng=rng)
        T = arm.fk(q)
        Jfd_tool = rotate_jacobian(numerical_jacobian(arm, q), T[:3, :3])
        assert np.max(np.abs(arm.jacobian(q, frame="tool") - Jfd_tool)) < 1e-7


def test_jacobian_at_a_tool_point_matches_finite_differences(rng):
    arm = rc.robots.ur5e()
    point = np.array([0.02, -0.03, 0.15])
    shifted = arm.with_tool(rc.spatial.translation(*point))
    for _ in range(10):
        q = arm.random_q(rng=rng)
        J = arm.jacobian(q, point=point)
        assert np.max(np.abs(J - numerical_jacobian(shifted, q))) < 1e-7
        # the same point in tool axes
        Jt = arm.jacobian(q, point=point, frame="tool")
        Tt = shifted.fk(q)
        assert np.max(np.abs(Jt - rotate_jacobian(numerical_jacobian(shifted, q), Tt[:3, :3]))) < 1e-7


def test_rpr_closed_form(rng):
    d1, d3 = 0.4, 0.1
    arm = rc.robots.rpr(d1=d1, d3=d3)
    for _ in range(50):
        q1, q2, q3 = arm.random_q(rng=rng)
        c1, s1 = math.cos(q1), math.sin(q1)
        r = q2 + d3
        J_closed = np.array([
            [r * c1, s1, 0.0],
            [r * s1, -c1, 0.0],
            [0.0, 0.0, 0.0],
            [0.0, 0.0, s1],
            [0.0, 0.0, -c1],
            [1.0, 0.0, 0.0],
        ])
        J = arm.jacobian(np.array([q1, q2, q3]))
        assert np.max(np.abs(J - J_closed)) < 1e-12
        p = arm.fk(np.array([q1, q2, q3]))[:3, 3]
        assert np.allclose(p, [r * s1, -r * c1, d1], atol=1e-12)


def test_planar_2r_closed_form(rng):
    l1, l2 = 0.7, 0.4
    arm = rc.robots.planar2r(l1=l1, l2=l2)
    for _ in range(50):
        q1, q2 = rng.uniform(-math.pi, math.pi, 2)
        s1, c1, s12, c12 = math.sin(q1), math.cos(q1), math.sin(q1 + q2), math.cos(q1 + q2)
        J_closed = np.array([
            [-l1 * s1 - l2 * s12, -l2 * s12],
            [l1 * c1 + l2 * c12, l2 * c12],
            [0, 0], [0, 0], [0, 0], [1, 1],
        ])
        assert np.max(np.abs(arm.jacobian(np.array([q1, q2])) - J_closed)) < 1e-12


def _panda_standard_dh():
    """The Panda written independently in standard DH: the MDH rows regrouped so that
    row i carries (θ_i, d_i) of MDH row i and (a, α) of MDH row i+1."""
    p2 = math.pi / 2
    rows = [
        rc.DH(d=0.333, a=0.0, alpha=-p2),
        rc.DH(d=0.0, a=0.0, alpha=p2),
        rc.DH(d=0.316, a=0.0825, alpha=p2),
        rc.DH(d=0.0, a=-0.0825, alpha=-p2),
        rc.DH(d=0.384, a=0.0, alpha=p2),
        rc.DH(d=0.0, a=0.088, alpha=p2),
        rc.DH(d=0.0, a=0.0, alpha=0.0),
    ]
    return rc.Chain.from_dh(rows, tool=rc.spatial.translation(0, 0, 0.107), name="panda sdh")


def test_panda_mdh_equals_independent_standard_dh(rng):
    mdh = rc.robots.panda()
    sdh = _panda_standard_dh()
    q = mdh.random_q(200, rng=rng)
    assert np.max(np.abs(mdh.fk(q) - sdh.fk(q))) < 1e-12
    assert np.max(np.abs(mdh.jacobian(q) - sdh.jacobian(q))) < 1e-12


def test_known_poses_at_zero():
    # UR5e at q = 0: x = a2 + a3, y = -(d4 + d6), z = d1 - d5
    T = rc.robots.ur5e().fk(np.zeros(6))
    assert np.allclose(T[:3, 3], [-0.8172, -0.2329, 0.0628], atol=1e-12)
    # Panda flange at q = 0: x = 0.088, z = 0.333 + 0.316 + 0.384 - 0.107, pointing down
    T = rc.robots.panda().fk(np.zeros(7))
    assert np.allclose(T[:3, 3], [0.088, 0.0, 0.926], atol=1e-12)
    assert np.allclose(T[:3, 2], [0, 0, -1], atol=1e-12)


def test_frames_are_consistent_with_fk_and_axes(arm, rng):
    q = arm.random_q(rng=rng)
    F = arm.frames(q)
    assert F.shape == (arm.dof + 1, 4, 4)
    assert np.allclose(F[0], arm.base)
    assert np.allclose(F[-1] @ arm.tool, arm.fk(q), atol=1e-13)
    z, o = arm.joint_axes(q)
    J = arm.jacobian(q)
    p = arm.fk(q)[:3, 3]
    for i in range(arm.dof):
        if arm.prismatic[i]:
            assert np.allclose(J[:3, i], z[i]) and np.allclose(J[3:, i], 0)
        else:
            assert np.allclose(J[:3, i], np.cross(z[i], p - o[i]), atol=1e-13)
            assert np.allclose(J[3:, i], z[i], atol=1e-13)


def test_standard_dh_joint_moves_about_previous_frame_z(rng):
    arm = rc.robots.ur5e()
    q = arm.random_q(rng=rng)
    F = arm.frames(q)
    z, o = arm.joint_axes(q)
    for i in range(arm.dof):
        assert np.allclose(z[i], F[i, :3, 2]) and np.allclose(o[i], F[i, :3, 3])


@pytest.mark.parametrize("shape", [(7,), (3, 4), (2, 3, 5)])
def test_batched_equals_looped(arm, rng, shape):
    q = arm.random_q(shape, rng=rng)
    T, J = arm.fk(q), arm.jacobian(q)
    TJ = arm.fk_jacobian(q)
    Jt = arm.jacobian(q, frame="tool")
    assert T.shape == shape + (4, 4) and J.shape == shape + (6, arm.dof)
    for idx in np.ndindex(*shape):
        assert np.max(np.abs(T[idx] - arm.fk(q[idx]))) < 1e-14
        assert np.max(np.abs(J[idx] - arm.jacobian(q[idx]))) < 1e-14
        assert np.max(np.abs(Jt[idx] - arm.jacobian(q[idx], frame="tool"))) < 1e-14
        assert np.array_equal(TJ[0][idx], T[idx]) and np.array_equal(TJ[1][idx], J[idx])


def test_large_batch_spans_several_chunks(rng):
    arm = rc.robots.ur5e()
    q = arm.random_q(20000, rng=rng)  # > one 8192-column chunk, with a ragged tail
    J = arm.jacobian(q)
    for i in (0, 8191, 8192, 16383, 16384, 19999):
        assert np.max(np.abs(J[i] - arm.jacobian(q[i]))) < 1e-14


def test_list_and_int_inputs_are_accepted():
    arm = rc.robots.planar2r()
    assert np.allclose(arm.jacobian([0, 1]), arm.jacobian(np.array([0.0, 1.0])))
    assert np.allclose(arm.fk((0, 1)), arm.fk(np.array([0.0, 1.0])))


def test_jacobian_dot_matches_finite_differences(arm, rng):
    h = 1e-6
    for frame in ("base", "tool"):
        for point in (None, np.array([0.01, 0.02, 0.05])):
            q = arm.random_q(rng=rng)
            qd = rng.normal(size=arm.dof)
            Jd = arm.jacobian_dot(q, qd, frame=frame, point=point)
            fd = (arm.jacobian(q + h * qd, frame=frame, point=point)
                  - arm.jacobian(q - h * qd, frame=frame, point=point)) / (2 * h)
            assert np.max(np.abs(Jd - fd)) < 1e-6


def test_jacobian_dot_batched(rng):
    arm = rc.robots.iiwa7()
    q = arm.random_q(5, rng=rng)
    qd = rng.normal(size=(5, 7))
    Jd = arm.jacobian_dot(q, qd)
    for i in range(5):
        assert np.allclose(Jd[i], arm.jacobian_dot(q[i], qd[i]), atol=1e-14)


def test_joint_torques_is_jacobian_transpose(rng):
    arm = rc.robots.ur5e()
    q = arm.random_q(rng=rng)
    F = np.array([10.0, -5.0, 20.0, 1.0, 0.5, -2.0])
    tau = arm.joint_torques(q, F)
    assert np.allclose(tau, arm.jacobian(q).T @ F)
    # virtual work: tau . qd == F . xi
    qd = rng.normal(size=6)
    assert math.isclose(tau @ qd, F @ (arm.jacobian(q) @ qd), rel_tol=1e-12)


def test_shift_jacobian_composes():
    arm = rc.robots.puma560()
    q = np.array([0.1, 0.2, -0.3, 0.4, 0.5, 0.6])
    J = arm.jacobian(q)
    r = np.array([0.1, 0.2, 0.3])
    assert np.allclose(shift_jacobian(shift_jacobian(J, r), -r), J)


def test_base_transform_moves_everything(rng):
    arm = rc.robots.ur5e()
    base = rc.spatial.transform(rc.spatial.rotz(0.7), [1.0, 2.0, 0.5])
    moved = arm.with_base(base)
    q = arm.random_q(rng=rng)
    assert np.allclose(moved.fk(q), base @ arm.fk(q))
    Jm = moved.jacobian(q)
    R = base[:3, :3]
    assert np.allclose(Jm[:3], R @ arm.jacobian(q)[:3]) and np.allclose(Jm[3:], R @ arm.jacobian(q)[3:])
    assert np.max(np.abs(Jm - numerical_jacobian(moved, q))) < 1e-7


# ---------------------------------------------------------------- random chains
@st.composite
def random_chain(draw):
    n = draw(st.integers(1, 8))
    cls = draw(st.sampled_from([rc.DH, rc.MDH]))
    lengths = st.floats(-1.0, 1.0, allow_nan=False)
    special = st.sampled_from([0.0, math.pi / 2, -math.pi / 2, math.pi])
    angles = st.one_of(st.floats(-math.pi, math.pi, allow_nan=False), special)
    rows = [cls(a=draw(lengths), d=draw(lengths), alpha=draw(angles), theta=draw(angles),
                joint=draw(st.sampled_from(["revolute", "revolute", "prismatic"])))
            for _ in range(n)]
    tool = rc.spatial.transform(rc.spatial.so3_exp(draw(st.lists(lengths, min_size=3, max_size=3))),
                                draw(st.lists(lengths, min_size=3, max_size=3)))
    vec = st.lists(lengths, min_size=3, max_size=3)
    base = rc.spatial.transform(rc.spatial.rotx(draw(angles)), draw(vec))
    build = rc.Chain.from_dh if cls is rc.DH else rc.Chain.from_mdh
    chain = build(rows, tool=tool, base=base)
    q = np.array(draw(st.lists(st.floats(-math.pi, math.pi, allow_nan=False), min_size=n, max_size=n)))
    return chain, q


@settings(max_examples=150, deadline=None)
@given(random_chain())
def test_random_chains_match_finite_differences(case):
    chain, q = case
    J = chain.jacobian(q)
    assert np.max(np.abs(J - numerical_jacobian(chain, q))) < 1e-7
    # batched kernel agrees with the single-configuration kernel
    Jb = chain.jacobian(np.stack([q, q]))
    assert np.max(np.abs(Jb[1] - J)) < 1e-13
    # the generic frame product agrees with the generated kernel
    assert np.max(np.abs(chain.frames(q)[-1] @ chain.tool - chain.fk(q))) < 1e-12


@pytest.mark.parametrize("rows", [
    [rc.DH(joint="prismatic")],
    [rc.DH(joint="prismatic"), rc.DH(joint="prismatic")],
    [rc.DH(joint="prismatic", theta=math.pi), rc.DH(joint="revolute")],
    [rc.DH(joint="revolute"), rc.DH(joint="prismatic")],
], ids=["P", "PP", "P(theta=pi)R", "RP"])
def test_outputs_that_are_raw_joint_values_are_written_by_the_batched_kernel(rows):
    """A pose entry equal to a joint value itself (no line computes it) was left unwritten by the
    batched kernel: uninitialised memory came back for a bare prismatic joint."""
    chain = rc.Chain.from_dh(rows)
    Q = np.random.default_rng(3).uniform(-1.0, 1.0, (7, chain.dof))
    T, J = chain.fk_jacobian(Q)
    for i in range(len(Q)):
        np.testing.assert_array_equal(T[i], chain.fk(Q[i]))
        np.testing.assert_array_equal(J[i], chain.jacobian(Q[i]))
    np.testing.assert_allclose(chain.jacobian(Q[0]), numerical_jacobian(chain, Q[0]), atol=1e-7)
