"""The viewer without a browser: what it draws, how it throttles, its target, its errors."""

import subprocess
import sys
import time

import numpy as np
import pytest

import ratectl as rc

pytest.importorskip("viser", reason="the viewer needs the view extra: pip install -e '.[view]'")

from ratectl.viewer import body_polylines, lost_directions, path_points  # noqa: E402

Q_WRIST = np.array([0.3, -1.3, 1.6, -1.9, 0.01, 0.2])


def test_import_ratectl_does_not_load_viser():
    code = "import sys, ratectl; ratectl.robots.ur5e(); assert 'viser' not in sys.modules, 'viser loaded'"
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)


def test_without_viser_the_viewer_says_how_to_install_it():
    code = ("import sys; sys.modules['viser'] = None\n"
            "import ratectl as rc\n"
            "try:\n    rc.viewer\nexcept rc.RatectlError as e:\n    print(e)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60).stdout
    assert 'pip install -e ".[view]"' in out


@pytest.mark.parametrize("name", ["ur5e", "puma560", "stanford", "rpr"])
def test_capsules_join_the_joints(name):
    """Each body's polyline starts at its joint and ends on the next joint's axis (or the
    tool), so the capsules drawn at any q form one connected arm."""
    chain = rc.robots.BUILTIN[name]()
    q = chain.random_q(rng=3)
    Ts = chain.frames(q)
    axes, points = chain.joint_axes(q)
    lines = body_polylines(chain)
    assert len(lines) == chain.dof + 1
    for k, pts in enumerate(lines):
        world = (Ts[k][:3, :3] @ pts.T).T + Ts[k][:3, 3]
        end = world[-1]
        if k < chain.dof:   # on the axis of joint k+1
            d = end - points[k]
            assert np.linalg.norm(d - (d @ axes[k]) * axes[k]) < 1e-9
        else:
            np.testing.assert_allclose(end, (Ts[-1] @ chain.tool)[:3, 3], atol=1e-9)
        if k > 0 and not chain.prismatic[k - 1]:   # starts at the origin of joint k's frame
            np.testing.assert_allclose(world[0], points[k - 1], atol=1e-9)


def test_lost_directions_only_near_a_singularity():
    chain = rc.robots.ur5e()
    assert lost_directions(rc.analyze(chain, np.array([1.4, -0.7, 0.9, -1.0, 1.2, 0.2]))) == []
    dirs = lost_directions(rc.analyze(chain, Q_WRIST))
    assert dirs and all(abs(np.linalg.norm(d) - 1) < 1e-12 for _, d in dirs)
    assert {name for name, _ in dirs} <= {"translation", "rotation"}
    singular = lost_directions(rc.analyze(chain, np.array([0.3, -1.3, 1.6, -1.9, 0.0, 0.2])))
    assert singular


def test_path_points_from_paths_points_and_poses():
    chain = rc.robots.ur5e()
    T0 = chain.fk(Q_WRIST)
    T1 = T0.copy()
    T1[:3, 3] += [0.1, 0.0, 0.0]
    pts = path_points(rc.paths.Line(T0, T1, speed=0.1, acceleration=1.0), samples=11)
    np.testing.assert_allclose(pts[[0, -1]], [T0[:3, 3], T1[:3, 3]], atol=1e-12)
    np.testing.assert_allclose(path_points(np.stack([T0, T1])), pts[[0, -1]], atol=1e-12)
    with pytest.raises(rc.InputError, match="path must be"):
        path_points(np.zeros((1, 3)))


@pytest.fixture
def viewer():
    with rc.viewer.Viewer(rc.robots.ur5e(), Q_WRIST, rate_hz=20.0) as v:
        yield v


def test_update_never_waits_for_drawing(viewer):
    """A control loop calling update every cycle: each call returns in microseconds while
    the viewer draws at most rate_hz states a second, the newest one."""
    assert viewer.sync(10.0)
    frames0 = viewer._frames
    start = time.monotonic()
    for k in range(2000):
        viewer.update(Q_WRIST + 1e-4 * k)
    assert viewer.sync(10.0)
    elapsed = time.monotonic() - start
    np.testing.assert_allclose(viewer.q, Q_WRIST + 1e-4 * 1999)   # the newest state is shown
    # at most one frame per 1/rate_hz (and the first at once): the other states were dropped
    assert 1 <= viewer._frames - frames0 <= 20.0 * elapsed + 2
    assert "σ_min(J_L)" in viewer.text


def test_target_reads_back_exactly_and_refuses_non_poses(viewer):
    np.testing.assert_allclose(viewer.target, rc.robots.ur5e().fk(Q_WRIST), atol=1e-15)
    T = np.eye(4)
    T[:3, :3] = rc.spatial.rotz(0.1234567890123)
    T[:3, 3] = [0.1, 0.2, 0.3000000000001]
    viewer.target = T
    assert np.array_equal(viewer.target, T)
    with pytest.raises(rc.InputError, match="target"):
        viewer.target = 2 * T
    with pytest.raises(rc.InputError):
        viewer.update(np.zeros(5))
    assert np.array_equal(viewer.target, T)


def test_a_drag_in_the_browser_becomes_the_target(viewer):
    """What viser reports for a drag (a quaternion and a position) is the new target."""
    from types import SimpleNamespace

    wxyz = np.array([np.cos(0.2), 0.0, 0.0, np.sin(0.2)])
    event = SimpleNamespace(client=object(), target=SimpleNamespace(wxyz=wxyz, position=(0.4, 0.1, 0.5)))
    viewer._on_drag(event)
    np.testing.assert_allclose(viewer.target[:3, 3], [0.4, 0.1, 0.5])
    np.testing.assert_allclose(viewer.target[:3, :3], rc.spatial.rotz(0.4), atol=1e-12)


def test_replay_and_errors(viewer):
    chain = rc.robots.ur5e()
    t = np.linspace(0.0, 1.0, 11)
    q = Q_WRIST + np.outer(t, [0.2, 0, 0, 0, 0, 0])
    from types import SimpleNamespace

    viewer.replay(SimpleNamespace(t=t, q=q, statuses=("ok",) * 11),
                  others={"copy": SimpleNamespace(t=t, q=q)})
    viewer.seek(0.5)
    np.testing.assert_allclose(viewer.q, q[5])
    assert "status **ok**" in viewer.text and "**copy**" in viewer.text
    with pytest.raises(rc.InputError, match="replay"):
        viewer.replay(SimpleNamespace(t=t, q=q[:, :5]))
    with pytest.raises(rc.InputError, match="chain"):
        rc.viewer.Viewer("ur5e")
    assert chain.dof == 6


def test_close_stops_the_server():
    v = rc.viewer.Viewer(rc.robots.planar2r())
    import urllib.request

    assert urllib.request.urlopen(v.url, timeout=10).status == 200
    v.close()
    v.close()                       # twice is fine
    v.update(np.zeros(2))           # after close: ignored
    with pytest.raises(OSError):
        urllib.request.urlopen(v.url, timeout=5)
