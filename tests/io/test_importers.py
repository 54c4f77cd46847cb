"""URDF and MJCF import: kinematics equal to MuJoCo's own, limits, safe parsing, clear errors."""

from pathlib import Path

import numpy as np
import pytest

import ratectl as rc
from ratectl.io import axis_rotation

mujoco = pytest.importorskip("mujoco")

DATA = Path(__file__).resolve().parents[1] / "data"

# (file, tip, frame type in MuJoCo's compiled model, expected dof)
MODELS = [
    ("ur5e_like.urdf", "tool0", "body", 6),
    ("panda_like.urdf", "hand_tcp", "body", 7),
    ("ur5e_like.xml", "attachment_site", "site", 6),
    ("panda_like.xml", "tcp", "site", 7),
    ("panda_like.xml", "hand", "body", 7),
]


def _load(fname, tip):
    path = DATA / fname
    if fname.endswith(".urdf"):
        return rc.Chain.from_urdf(path, tip=tip)
    return rc.Chain.from_mjcf(path, tip=tip)


def _mujoco_reference(model, data, chain, q, tip, frame_type):
    """MuJoCo's own pose and [jacp; jacr] of the tip, columns in chain order."""
    jids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in chain.joint_names]
    assert min(jids) >= 0
    data.qpos[:] = model.qpos0
    data.qpos[[model.jnt_qposadr[j] for j in jids]] = q
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    jp, jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    if frame_type == "site":
        i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, tip)
        pos, mat = data.site_xpos[i], data.site_xmat[i]
        mujoco.mj_jacSite(model, data, jp, jr, i)
    else:
        i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, tip)
        pos, mat = data.xpos[i], data.xmat[i]
        mujoco.mj_jacBody(model, data, jp, jr, i)
    T = np.eye(4)
    T[:3, :3] = mat.reshape(3, 3)
    T[:3, 3] = pos
    dofs = [model.jnt_dofadr[j] for j in jids]
    return T, np.vstack([jp, jr])[:, dofs]


@pytest.mark.parametrize("fname,tip,frame_type,dof", MODELS)
def test_import_matches_mujoco_at_random_q(fname, tip, frame_type, dof, rng):
    chain = _load(fname, tip)
    assert chain.dof == dof
    model = mujoco.MjModel.from_xml_path(str(DATA / fname))  # MuJoCo's own reading of the file
    data = mujoco.MjData(model)
    qs = chain.random_q(100, rng=rng)
    Tb, Jb = chain.fk_jacobian(qs)  # batched
    worst_T = worst_J = 0.0
    for k, q in enumerate(qs):
        T_ref, J_ref = _mujoco_reference(model, data, chain, q, tip, frame_type)
        worst_T = max(worst_T, np.max(np.abs(chain.fk(q) - T_ref)), np.max(np.abs(Tb[k] - T_ref)))
        worst_J = max(worst_J, np.max(np.abs(chain.jacobian(q) - J_ref)), np.max(np.abs(Jb[k] - J_ref)))
    assert worst_T < 1e-9
    assert worst_J < 1e-9
    # and the imported Jacobian is the derivative of the imported fk
    from ratectl.kinematics import numerical_jacobian

    assert np.max(np.abs(chain.jacobian(qs[0]) - numerical_jacobian(chain, qs[0]))) < 1e-7


def test_from_compiled_model_equals_from_file(rng):
    model = mujoco.MjModel.from_xml_path(str(DATA / "panda_like.xml"))
    a = rc.Chain.from_mjcf(model, tip="tcp")
    b = rc.Chain.from_mjcf(DATA / "panda_like.xml", tip="tcp")
    qs = a.random_q(20, rng=rng)
    assert np.max(np.abs(a.fk(qs) - b.fk(qs))) < 1e-14


def test_urdf_limits_names_and_folded_fixed_joints():
    chain = rc.Chain.from_urdf(DATA / "ur5e_like.urdf", tip="tool0")
    assert chain.joint_names == ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint",
                                 "wrist_1_joint", "wrist_2_joint", "wrist_3_joint")
    assert chain.name == "ur5e_like"
    np.testing.assert_allclose(chain.lower[:5], [-2 * np.pi, -2 * np.pi, -np.pi, -2 * np.pi, -2 * np.pi],
                               atol=1e-12)
    assert chain.lower[5] == -np.inf and chain.upper[5] == np.inf  # continuous joint
    np.testing.assert_allclose(chain.vmax, [3.14159] * 3 + [6.28319] * 3)  # <limit velocity>
    assert not chain.prismatic.any()
    # the fixed flange and tool0 joints are folded into the tool transform
    assert not np.allclose(chain.tool, np.eye(4))
    # a tip that is a fixed child gives the same joints and a different tool
    flange = rc.Chain.from_urdf(DATA / "ur5e_like.urdf", tip="flange")
    q = np.array([0.1, -0.5, 0.8, -0.3, 1.2, 0.4])
    np.testing.assert_allclose(flange.fk(q) @ (np.linalg.inv(flange.tool) @ chain.tool), chain.fk(q),
                               atol=1e-14)
    # a base link below the root drops the fixed world joint
    based = rc.Chain.from_urdf(DATA / "ur5e_like.urdf", tip="tool0", base_link="base_link")
    world_base = rc.spatial.transform(rc.spatial.rotz(0.3), [0.1, -0.2, 0.05])
    np.testing.assert_allclose(world_base @ based.fk(q), chain.fk(q), atol=1e-14)


def test_urdf_prismatic_tip_and_single_leaf_default():
    fingers = rc.Chain.from_urdf(DATA / "panda_like.urdf", tip="leftfinger")
    assert fingers.dof == 8 and fingers.prismatic.tolist() == [False] * 7 + [True]
    assert fingers.upper[-1] == pytest.approx(0.04) and fingers.vmax[-1] == pytest.approx(0.2)
    # UR5e-like has a single leaf: tip may be omitted
    assert rc.Chain.from_urdf(DATA / "ur5e_like.urdf").dof == 6
    assert rc.Chain.from_mjcf(DATA / "ur5e_like.xml").dof == 6


def test_mjcf_ref_degrees_and_anchor_are_honoured():
    chain = rc.Chain.from_mjcf(DATA / "panda_like.xml", tip="tcp")
    # degrees are converted: joint1 range ±166°
    assert chain.upper[0] == pytest.approx(np.deg2rad(166))
    assert chain.lower[3] == pytest.approx(np.deg2rad(-176))
    # joint3 has ref=10°: q = ref is the modelled pose, so fk(qpos0) is MuJoCo's rest pose
    model = mujoco.MjModel.from_xml_path(str(DATA / "panda_like.xml"))
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "tcp")
    q0 = model.qpos0[:7]
    assert q0[2] == pytest.approx(np.deg2rad(10))
    np.testing.assert_allclose(chain.fk(q0)[:3, 3], data.site_xpos[site], atol=1e-12)


def test_body_with_two_joints_and_mesh_files_ignored(rng, tmp_path):
    xml = """
    <mujoco model="two_joint_body">
      <asset><mesh name="shell" file="does/not/exist.stl"/></asset>
      <worldbody>
        <body name="a" pos="0.1 0 0.2" euler="0.3 0.2 0.1">
          <joint name="ja" axis="1 0 0" pos="0 0.05 0"/>
          <joint name="jb" type="slide" axis="0 1 1" range="-0.1 0.2"/>
          <geom type="mesh" mesh="shell"/>
          <body name="b" pos="0 0 0.3">
            <joint name="jc" axis="0 1 0" pos="0.02 0 0.01" ref="0.3"/>
            <geom size="0.05"/>
            <site name="tip" pos="0.1 0 0.1" euler="0 0.5 0"/>
          </body>
        </body>
      </worldbody>
    </mujoco>"""
    chain = rc.Chain.from_mjcf(xml, tip="tip")
    assert chain.joint_names == ("ja", "jb", "jc")
    assert chain.prismatic.tolist() == [False, True, False]
    # MuJoCo's reference: the same model with the mesh geom made a sphere
    ref_xml = xml.replace('<asset><mesh name="shell" file="does/not/exist.stl"/></asset>', "").replace(
        '<geom type="mesh" mesh="shell"/>', '<geom size="0.05"/>')
    model = mujoco.MjModel.from_xml_string(ref_xml)
    data = mujoco.MjData(model)
    for q in chain.random_q(100, rng=rng):
        T, J = _mujoco_reference(model, data, chain, q, "tip", "site")
        assert np.max(np.abs(chain.fk(q) - T)) < 1e-12
        assert np.max(np.abs(chain.jacobian(q) - J)) < 1e-12
    # the same from a file on disk
    f = tmp_path / "two.xml"
    f.write_text(xml)
    assert rc.Chain.from_mjcf(f, tip="tip").dof == 3


def test_axis_rotation_takes_z_onto_the_axis(rng):
    for a in [np.array([0, 0, 1.0]), np.array([0, 0, -1.0]), np.array([1.0, 0, 0]),
              *rng.normal(size=(20, 3))]:
        a = a / np.linalg.norm(a)
        R = axis_rotation(a)
        np.testing.assert_allclose(R @ [0, 0, 1], a, atol=1e-15)
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-15)
        assert np.linalg.det(R) == pytest.approx(1.0)


# ---------------------------------------------------------------- errors
def _raises(fn, *args, element, match=None, **kw):
    with pytest.raises(rc.ImportModelError, match=match) as info:
        fn(*args, **kw)
    assert info.value.element == element, (info.value.element, str(info.value))
    assert isinstance(info.value, rc.ModelError)
    return info.value


def test_malformed_xml_names_the_position():
    e = _raises(rc.Chain.from_urdf, DATA / "bad_malformed.urdf", element="XML line 8 column 2")
    assert "malformed" in str(e)


@pytest.mark.parametrize("loader", [rc.Chain.from_urdf, rc.Chain.from_mjcf])
def test_entity_declarations_are_refused_without_expansion(loader):
    _raises(loader, DATA / "bad_entities.urdf", element="<!DOCTYPE>", match="not allowed")
    _raises(loader, '<?xml version="1.0"?><!ENTITY x SYSTEM "http://example.com/x"><robot/>',
            element="<!ENTITY>")


def test_unsupported_urdf_structures_name_the_element():
    _raises(rc.Chain.from_urdf, DATA / "bad_floating.urdf", element="joint 'free_base'", match="floating")
    _raises(rc.Chain.from_urdf, DATA / "bad_missing_link.urdf", element="joint 'elbow'",
            match="'forearm'")
    _raises(rc.Chain.from_urdf, DATA / "panda_like.urdf", element="link 'hand'", match="branches")
    _raises(rc.Chain.from_urdf, DATA / "panda_like.urdf", tip="rightfinger",
            element="joint 'finger_joint2'", match="mimic")
    _raises(rc.Chain.from_urdf, DATA / "panda_like.urdf", tip="nope", element="link 'nope'")
    _raises(rc.Chain.from_urdf, DATA / "nope.urdf", element=f"file {str(DATA / 'nope.urdf')!r}",
            match="not found")
    planar = """<robot name="p"><link name="a"/><link name="b"/>
      <joint name="slider" type="planar"><parent link="a"/><child link="b"/></joint></robot>"""
    _raises(rc.Chain.from_urdf, planar, element="joint 'slider'", match="planar")
    no_limit = """<robot name="p"><link name="a"/><link name="b"/>
      <joint name="j1" type="revolute"><parent link="a"/><child link="b"/></joint></robot>"""
    _raises(rc.Chain.from_urdf, no_limit, element="joint 'j1'", match="limit")
    bad_axis = """<robot name="p"><link name="a"/><link name="b"/>
      <joint name="j1" type="continuous"><parent link="a"/><child link="b"/>
      <axis xyz="0 0 x"/></joint></robot>"""
    _raises(rc.Chain.from_urdf, bad_axis, element="joint 'j1' <axis xyz>")
    zero_axis = bad_axis.replace("0 0 x", "0 0 0")
    _raises(rc.Chain.from_urdf, zero_axis, element="joint 'j1'", match="zero length")
    two_parents = """<robot name="p"><link name="a"/><link name="b"/><link name="c"/>
      <joint name="j1" type="continuous"><parent link="a"/><child link="c"/></joint>
      <joint name="j2" type="continuous"><parent link="b"/><child link="c"/></joint></robot>"""
    _raises(rc.Chain.from_urdf, two_parents, element="joint 'j2'", match="two joints")
    _raises(rc.Chain.from_urdf, "<sdf/>", element="<sdf>")
    no_range = no_limit.replace('</joint>', '<limit effort="1" velocity="1"/></joint>')
    _raises(rc.Chain.from_urdf, no_range, element="joint 'j1'", match="neither lower nor upper")


@pytest.mark.parametrize("loader", [rc.Chain.from_urdf, rc.Chain.from_mjcf])
def test_an_empty_name_or_a_directory_is_named_as_such(loader):
    _raises(loader, "", element="file", match="file name is empty")
    _raises(loader, "  ", element="file", match="file name is empty")
    _raises(loader, DATA, element=f"file {str(DATA)!r}", match="is a directory")


def test_unsupported_mjcf_structures_name_the_element():
    _raises(rc.Chain.from_mjcf, DATA / "bad_ball.xml", tip="tip", element="joint 'shoulder_ball'",
            match="ball")
    _raises(rc.Chain.from_mjcf, DATA / "panda_like.xml", element="body 'hand'", match="branch")
    _raises(rc.Chain.from_mjcf, DATA / "panda_like.xml", tip="left_finger",
            element="equality 'finger_coupling'", match="mimic")
    _raises(rc.Chain.from_mjcf, DATA / "panda_like.xml", tip="nope", element="tip 'nope'")
    free = """<mujoco><worldbody><body name="floater"><freejoint name="float"/><geom size="0.1"/>
      <body name="arm"><joint name="j"/><geom size="0.1"/></body></body></worldbody></mujoco>"""
    _raises(rc.Chain.from_mjcf, free, tip="arm", element="joint 'float'", match="free")
    e = _raises(rc.Chain.from_mjcf, "<mujoco><worldbody><body><joint/><geom size='1' typo='x'/>"
                "</body></worldbody></mujoco>", element="<geom>")
    assert "typo" in str(e)
    _raises(rc.Chain.from_mjcf, "<robot/>", element="<robot>")


# --------------------------------------------------------------------------- gripper joint, no tip
def _arm_with_jaw(jaw_name="finger_joint", jaw_type="prismatic", child="left_finger"):
    links = ["base"] + [f"l{i}" for i in range(1, 7)] + ["hand", child]
    joints = []
    for i in range(1, 7):
        axis = "0 0 1" if i % 2 else "0 1 0"
        joints.append(f'<joint name="j{i}" type="revolute"><parent link="{links[i - 1]}"/>'
                      f'<child link="l{i}"/><origin xyz="0 0 0.1"/><axis xyz="{axis}"/>'
                      '<limit lower="-3" upper="3" velocity="2" effort="1"/></joint>')
    joints.append('<joint name="hand_fixed" type="fixed"><parent link="l6"/><child link="hand"/>'
                  '<origin xyz="0 0 0.05"/></joint>')
    joints.append(f'<joint name="{jaw_name}" type="{jaw_type}"><parent link="hand"/><child link="{child}"/>'
                  '<axis xyz="0 1 0"/><limit lower="0" upper="0.04" velocity="0.1" effort="1"/></joint>')
    body = "".join(f'<link name="{lk}"/>' for lk in links) + "".join(joints)
    return f'<robot name="jaw">{body}</robot>'


@pytest.mark.parametrize("jaw_name, jaw_type, child", [
    ("finger_joint", "prismatic", "left_finger"),
    ("slide", "prismatic", "pad"),                  # a 7th prismatic joint after six revolute ones
    ("gripper_knuckle", "revolute", "knuckle_link"),
])
def test_urdf_without_tip_refuses_a_gripper_joint(tmp_path, jaw_name, jaw_type, child):
    f = tmp_path / "jaw.urdf"
    f.write_text(_arm_with_jaw(jaw_name, jaw_type, child))
    with pytest.raises(rc.ImportModelError) as info:
        rc.Chain.from_urdf(f)
    msg = str(info.value)
    assert jaw_name in msg and "tip='hand'" in msg and f"tip={child!r}" in msg
    assert rc.Chain.from_urdf(f, tip="hand").dof == 6
    assert rc.Chain.from_urdf(f, tip=child).dof == 7
