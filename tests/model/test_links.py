"""Links by name: chain.link_names, fk(q, link=...) and jacobian(q, link=...)."""

import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import ratectl as rc
from ratectl.errors import InputError

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tasks"))
from panda_erd import panda_urdf  # noqa: E402

URDF = panda_urdf()
needs_urdf = pytest.mark.skipif(URDF is None, reason="example-robot-data is not installed")


def test_dh_chain_names_links_one_per_joint():
    ch = rc.robots.ur5e()
    assert ch.link_names == tuple(f"link{i}" for i in range(1, 7))
    q = ch.random_q(rng=3)
    # the last link is the flange: the tool pose is it times the tool transform
    np.testing.assert_allclose(ch.fk(q, link="link6") @ ch.tool, ch.fk(q), atol=1e-12)
    frames = ch.frames(q)
    for i in range(1, 7):
        np.testing.assert_allclose(ch.fk(q, link=f"link{i}"), frames[i], atol=1e-12)


@given(st.integers(0, 2**31 - 1), st.sampled_from(["panda", "ur5e", "iiwa7", "stanford", "rpr"]))
def test_link_jacobian_matches_finite_differences(seed, arm):
    ch = rc.robots.BUILTIN[arm]()
    q = ch.random_q(rng=seed)
    rng = np.random.default_rng(seed)
    link = ch.link_names[int(rng.integers(len(ch.link_names)))]
    point = rng.normal(size=3) * 0.1
    J = ch.jacobian(q, link=link, point=point)
    h = 1e-6
    T0 = ch.fk(q, link=link)
    for i in range(ch.dof):
        e = np.zeros(ch.dof)
        e[i] = h
        Tp, Tm = ch.fk(q + e, link=link), ch.fk(q - e, link=link)
        pp, pm = Tp[:3, :3] @ point + Tp[:3, 3], Tm[:3, :3] @ point + Tm[:3, 3]
        np.testing.assert_allclose(J[:3, i], (pp - pm) / (2 * h), atol=1e-7)
        W = (Tp[:3, :3] - Tm[:3, :3]) / (2 * h) @ T0[:3, :3].T
        np.testing.assert_allclose(J[3:, i], [W[2, 1], W[0, 2], W[1, 0]], atol=1e-7)


def test_link_batched_equals_looped():
    ch = rc.robots.panda()
    qs = ch.random_q((4, 3), rng=5)
    for link in ("link2", "link7"):
        T, J = ch.fk_jacobian(qs, link=link, frame="tool", point=[0.01, 0.02, 0.03])
        assert T.shape == (4, 3, 4, 4) and J.shape == (4, 3, 6, 7)
        for idx in np.ndindex(4, 3):
            np.testing.assert_allclose(T[idx], ch.fk(qs[idx], link=link), atol=1e-13)
            np.testing.assert_allclose(J[idx], ch.jacobian(qs[idx], link=link, frame="tool",
                                                           point=[0.01, 0.02, 0.03]), atol=1e-13)


def test_unknown_link_names_the_links():
    ch = rc.robots.panda()
    with pytest.raises(InputError, match="link7"):
        ch.fk(np.zeros(7), link="elbow")


def test_links_survive_with_limits_and_tool():
    ch = rc.robots.panda().with_limits(amax=5.0).with_tool(np.eye(4))
    assert ch.link_names[-1] == "link7"


@needs_urdf
def test_urdf_links_match_pinocchio():
    pin = pytest.importorskip("pinocchio")
    ch = rc.Chain.from_urdf(URDF, tip="panda_hand_tcp")
    assert ch.link_names[:2] == ("panda_link0", "panda_link1")
    assert {"panda_link4", "panda_link8", "panda_hand", "panda_hand_tcp"} <= set(ch.link_names)
    m = pin.buildModelFromUrdf(URDF)
    d = m.createData()
    for seed in range(5):
        q = ch.random_q(rng=seed)
        qp = np.zeros(m.nq)
        qp[:7] = q
        pin.forwardKinematics(m, d, qp)
        pin.updateFramePlacements(m, d)
        pin.computeJointJacobians(m, d, qp)
        for link in ch.link_names:
            fid = m.getFrameId(link)
            np.testing.assert_allclose(ch.fk(q, link=link), d.oMf[fid].homogeneous, atol=1e-12)
            Jp = pin.getFrameJacobian(m, d, fid, pin.LOCAL_WORLD_ALIGNED)[:, :7]
            np.testing.assert_allclose(ch.jacobian(q, link=link), Jp, atol=1e-12)
            Jl = pin.getFrameJacobian(m, d, fid, pin.LOCAL)[:, :7]
            np.testing.assert_allclose(ch.jacobian(q, link=link, frame="tool"), Jl, atol=1e-12)


def test_mjcf_links_are_bodies():
    mujoco = pytest.importorskip("mujoco")
    path = Path(__file__).resolve().parents[1] / "data" / "panda_like.xml"
    ch = rc.Chain.from_mjcf(str(path), tip="hand")
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    assert len(ch.link_names) >= ch.dof
    q = ch.random_q(rng=2)
    from ratectl.io.mjcf import mjcf_joint_addresses

    qadr, _ = mjcf_joint_addresses(model, ch)
    data.qpos[qadr] = q
    mujoco.mj_kinematics(model, data)
    for link in ch.link_names:
        b = model.body(link).id
        T = ch.fk(q, link=link)
        np.testing.assert_allclose(T[:3, 3], data.xpos[b], atol=1e-9)
        np.testing.assert_allclose(T[:3, :3], data.xmat[b].reshape(3, 3), atol=1e-9)
