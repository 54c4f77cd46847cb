"""The URDF reader keeps the links' geometry (for drawing), placed on the chain's frames."""

import numpy as np
import pytest

import ratectl as rc
from ratectl.io.urdf import find_mesh

URDF = """<robot name="two">
  <material name="blue"><color rgba="0 0 1 1"/></material>
  <link name="base">
    <visual><geometry><mesh filename="meshes/base.stl" scale="0.001 0.001 0.001"/></geometry></visual>
  </link>
  <link name="l1">
    <visual><origin xyz="0 0 0.1"/><geometry><cylinder radius="0.05" length="0.2"/></geometry>
      <material name="blue"/></visual>
    <collision><geometry><box size="0.1 0.1 0.2"/></geometry></collision>
  </link>
  <link name="bracket">
    <visual><geometry><sphere radius="0.03"/></geometry>
      <material name="red"><color rgba="1 0 0 0.5"/></material></visual>
  </link>
  <link name="l2">
    <visual><geometry><mesh filename="package://pkg/meshes/l2.dae"/></geometry></visual>
    <visual><geometry><capsule radius="1" length="2"/></geometry></visual>
    <visual><geometry><box size="nan 1 1"/></geometry></visual>
  </link>
  <link name="tip"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.2"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="1"/></joint>
  <joint name="fix" type="fixed"><parent link="l1"/><child link="bracket"/>
    <origin xyz="0.3 0 0"/></joint>
  <joint name="j2" type="revolute"><parent link="bracket"/><child link="l2"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" velocity="1"/></joint>
  <joint name="j3" type="fixed"><parent link="l2"/><child link="tip"/><origin xyz="0.2 0 0"/></joint>
</robot>"""


@pytest.fixture
def package(tmp_path):
    """A package tree: pkg/urdf/two.urdf, pkg/meshes/l2.dae, pkg/urdf/meshes/base.stl."""
    (tmp_path / "pkg" / "urdf" / "meshes").mkdir(parents=True)
    (tmp_path / "pkg" / "meshes").mkdir()
    (tmp_path / "pkg" / "meshes" / "l2.dae").write_text("<COLLADA/>")
    (tmp_path / "pkg" / "urdf" / "meshes" / "base.stl").write_text("solid x\nendsolid x\n")
    path = tmp_path / "pkg" / "urdf" / "two.urdf"
    path.write_text(URDF)
    return path


def test_geometry_is_placed_on_the_frame_it_moves_with(package):
    chain = rc.Chain.from_urdf(package)
    got = {(v.link, v.role, v.shape): v for v in chain.visuals}
    assert set(got) == {("base", "visual", "mesh"), ("l1", "visual", "cylinder"),
                        ("l1", "collision", "box"), ("bracket", "visual", "sphere"),
                        ("l2", "visual", "mesh")}   # the capsule and the NaN box are left out
    assert [got[k].frame for k in sorted(got)] == [0, 1, 1, 1, 2]
    # the bracket hangs on frame 1 through the fixed joint: its origin carries that offset
    np.testing.assert_allclose(got["bracket", "visual", "sphere"].origin[:3, 3], [0.3, 0, 0])
    np.testing.assert_allclose(got["l1", "visual", "cylinder"].origin[:3, 3], [0, 0, 0.1])
    # placed geometry moves with the chain: frame 1 · origin = the bracket's pose at any q
    q = np.array([0.7, -0.4])
    bracket = chain.frames(q)[1] @ got["bracket", "visual", "sphere"].origin
    np.testing.assert_allclose(bracket[:3, 3], [0.3 * np.cos(0.7), 0.3 * np.sin(0.7), 0.2], atol=1e-12)
    assert got["l1", "visual", "cylinder"].size == (0.05, 0.2)
    assert got["l1", "visual", "cylinder"].rgba == (0.0, 0.0, 1.0, 1.0)    # a named material
    assert got["bracket", "visual", "sphere"].rgba == (1.0, 0.0, 0.0, 0.5)
    assert got["base", "visual", "mesh"].size == (0.001, 0.001, 0.001)


def test_mesh_files_are_found_relative_and_in_packages(package):
    chain = rc.Chain.from_urdf(package)
    paths = {v.link: v.path for v in chain.visuals if v.shape == "mesh"}
    assert paths["base"] == str(package.parent / "meshes" / "base.stl")
    assert paths["l2"] == str((package.parent.parent / "meshes" / "l2.dae").resolve())
    assert find_mesh("package://nothere/x.stl", package.parent) is None
    assert find_mesh("package://pkg", package.parent) is None
    assert find_mesh("", package.parent) is None
    assert find_mesh(f"file://{paths['base']}") == package.parent / "meshes" / "base.stl"


def test_geometry_survives_new_limits_tool_and_base(package):
    chain = rc.Chain.from_urdf(package)
    for other in (chain.with_limits(vmax=2.0), chain.with_tool(np.eye(4)), chain.with_base(np.eye(4))):
        assert other.visuals == chain.visuals


def test_text_sources_keep_geometry_but_find_no_relative_mesh():
    chain = rc.Chain.from_urdf(URDF)
    meshes = [v for v in chain.visuals if v.shape == "mesh"]
    assert len(meshes) == 2 and all(v.path is None for v in meshes)
    assert rc.robots.ur5e().visuals == ()


# ------------------------------------------- one reader for the viewer and the collision model
COLLIDING = """<robot name="c">
  <link name="a">
    <collision><origin xyz="0.1 0 0" rpy="0 0 0.5"/><geometry><box size="0.1 0.2 0.3"/></geometry></collision>
    <collision><geometry><sphere radius="0.04"/></geometry></collision>
    <collision><origin xyz="0 0 0.2"/><geometry><cylinder radius="0.05" length="0.4"/></geometry></collision>
    <collision><geometry><mesh filename="package://pkg/meshes/l2.dae" scale="2 2 2"/></geometry></collision>
    <collision><geometry><mesh filename="meshes/base.stl"/></geometry></collision>
  </link>
  <link name="b"/>
  <joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" velocity="1"/></joint>
</robot>"""


def test_the_viewer_and_the_collision_model_read_the_same_geometry(package):
    from ratectl.io.urdf_geometry import urdf_collision_geometry

    f = package.parent / "c.urdf"
    f.write_text(COLLIDING)
    elements = urdf_collision_geometry(f).elements
    visuals = [v for v in rc.Chain.from_urdf(f).visuals if v.role == "collision"]
    assert [e.kind for e in elements] == [v.shape for v in visuals] == ["box", "sphere", "cylinder",
                                                                         "mesh", "mesh"]
    for e, v in zip(elements, visuals, strict=True):
        np.testing.assert_array_equal(e.origin, v.origin)      # link a is the base: frame 0, no offset
        if e.kind == "mesh":
            assert e.filename == v.path and tuple(e.scale) == v.size
        else:
            assert e.size == v.size
    assert elements[0].size == (0.1, 0.2, 0.3) and elements[2].size == (0.05, 0.4)
    assert tuple(elements[3].scale) == (2.0, 2.0, 2.0)


@pytest.mark.parametrize("geometry, words", [
    ("<box/>", "<box> has no size"),
    ("<box size='1 2'/>", "expected 3"),
    ("<sphere/>", "<sphere> has no radius"),
    ("<cylinder radius='0.1'/>", "<cylinder> has no length"),
    ("<cylinder radius='x' length='1'/>", "expected 1 numbers"),
    ("<cone radius='1'/>", "allowed: mesh, box, cylinder, sphere, capsule"),
    ("<mesh/>", "has no filename"),
    ("<mesh filename='package://nowhere/m.stl'/>", "not found; looked in"),
    ("", "has no <geometry>"),
])
def test_bad_collision_geometry_is_refused_with_a_message_and_left_out_of_the_drawing(geometry, words):
    from ratectl.errors import ImportModelError
    from ratectl.io.urdf_geometry import urdf_collision_geometry

    doc = (f'<robot name="c"><link name="a"><collision><geometry>{geometry}</geometry></collision>'
           '</link><link name="b"/><joint name="j" type="revolute"><parent link="a"/><child link="b"/>'
           '<axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="1"/></joint></robot>')
    if not geometry:
        doc = doc.replace("<geometry></geometry>", "")
    with pytest.raises(ImportModelError, match="link 'a' <collision> 0") as exc:
        urdf_collision_geometry(doc)
    assert words in str(exc.value)
    drawn = rc.Chain.from_urdf(doc).visuals      # drawing never refuses a model
    assert all(v.shape == "mesh" for v in drawn) and len(drawn) == (geometry.startswith("<mesh") and 1)
