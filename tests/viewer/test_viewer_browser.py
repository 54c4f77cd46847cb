"""The viewer as a user sees it: headless Chromium (SwiftShader WebGL) opens the page and the
screenshots are checked — the arm is drawn, the picture follows q, a target set from Python
reads back unchanged, an imported URDF shows its meshes.

Skipped when no Chromium is installed (CI installs it). With ``RATECTL_VIEWER_SHOTS=DIR``
the screenshots are also written to ``DIR/viewer_*.png`` (the pictures of docs/viewer.md:
``RATECTL_VIEWER_SHOTS=docs/img python -m pytest tests/viewer -n 0``).
"""

import os
import sysconfig
import time
from pathlib import Path

import numpy as np
import pytest

import ratectl as rc

pytest.importorskip("viser", reason="the viewer needs the view extra: pip install -e '.[view]'")

from viewer_browser import CHROMIUM, Browser, save_png, wait_for_client  # noqa: E402

pytestmark = [pytest.mark.skipif(CHROMIUM is None, reason="no chromium installed (CI installs it; "
                                 "apt-get install chromium)"),
              pytest.mark.xdist_group("chromium")]

SHOTS = os.environ.get("RATECTL_VIEWER_SHOTS")
Q_WRIST = np.array([0.3, -1.3, 1.6, -1.9, 0.01, 0.2])   # 0.01 rad from the UR5e wrist singularity
Q_OTHER = np.array([1.4, -0.7, 0.9, -1.0, 1.2, 0.2])


def _shot(name, browser):
    """The whole page (3-D view and control panel) for the docs, when asked for."""
    if SHOTS:
        save_png(browser.screenshot(), Path(SHOTS) / f"viewer_{name}.png")


def _scene(image, k=4):
    """A render averaged over k×k blocks (software rendering antialiases the thin grid lines
    a little differently each time)."""
    h, w, _ = image.shape
    a = image[: h - h % k, : w - w % k].astype(float)
    return a.reshape(a.shape[0] // k, k, a.shape[1] // k, k, 3).mean(axis=(1, 3))


def _changed(a, b, tol=30.0):
    """Fraction of (block-averaged) scene pixels that differ by more than ``tol`` (sum over RGB)."""
    return float(np.mean(np.abs(_scene(a) - _scene(b)).sum(axis=-1) > tol))


def _leave(browser, viewer):
    """Disconnect the browser before the viewer closes (the server then stops at once)."""
    browser.open("about:blank")
    deadline = time.monotonic() + 1.0
    while viewer.server.get_clients() and time.monotonic() < deadline:
        time.sleep(0.05)


@pytest.fixture(scope="module")
def browser():
    b = Browser(width=1100, height=720)
    yield b
    b.close()


@pytest.fixture
def ur5e_view(browser):
    chain = rc.robots.ur5e()
    with rc.viewer.Viewer(chain, Q_WRIST) as v:
        browser.open(v.url)
        assert wait_for_client(v), "the browser did not connect to the viewer"
        yield v
        _leave(browser, v)


def test_the_arm_is_drawn_and_follows_q(browser, ur5e_view):
    v = ur5e_view
    with_arm = browser.settled(v)
    _shot("ur5e", browser)
    v.arm_visible = False
    empty = browser.render(v)
    v.arm_visible = True
    # the capsule arm covers a visible part of the picture, in its own colours
    assert _changed(with_arm, empty) > 0.005
    v.update(Q_OTHER)
    moved = browser.render(v)
    assert _changed(moved, with_arm) > 0.005
    assert _changed(moved, empty) > 0.005
    v.update(Q_WRIST)
    back = browser.render(v)
    assert _changed(back, with_arm) < 0.1 * _changed(moved, with_arm)


def test_the_singularity_report_is_shown(ur5e_view):
    v = ur5e_view
    assert "kind: **wrist**" in v.text and "σ_min(J_L)" in v.text
    v.update(Q_OTHER)
    assert v.sync()
    assert "kind: **regular**" in v.text


def test_a_target_set_from_python_reads_back_unchanged(browser, ur5e_view):
    v = ur5e_view
    T = rc.robots.ur5e().fk(Q_OTHER)
    T[:3, 3] += [0.0123456789, -0.02, 0.031]
    v.target = T
    browser.render(v)   # the browser got the pose (and may echo it back)
    assert np.array_equal(v.target, T)
    assert not v.target.flags.writeable


def test_an_imported_urdf_shows_its_meshes(browser):
    urdf = (Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix/share/example-robot-data/robots"
            / "ur_description/urdf/ur10_robot.urdf")
    if not urdf.is_file():
        pytest.skip("example-robot-data is not installed")
    chain = rc.Chain.from_urdf(urdf, tip="tool0")
    q = np.array([0.4, -1.1, 1.5, -1.9, -1.4, 0.3])
    with rc.viewer.Viewer(chain, q) as v:
        # the visual mesh of each of the 7 links, and the 1 cm collision box of ee_link
        # (a link without a visual is drawn from its collision geometry)
        assert v.meshes_drawn == 8
        browser.open(v.url)
        assert wait_for_client(v)
        meshes = browser.settled(v)
        _shot("ur10_meshes", browser)
        v.arm_visible = False
        empty = browser.render(v)
        _leave(browser, v)
    assert _changed(meshes, empty) > 0.005
    with rc.viewer.Viewer(chain, q, meshes=False) as v:
        assert v.meshes_drawn == 0
        browser.open(v.url)
        assert wait_for_client(v)
        capsules = browser.settled(v)
        _leave(browser, v)
    # the same arm drawn from its meshes and as capsules: different pictures
    assert _changed(meshes, capsules) > 0.005


def test_a_replay_shows_the_run_with_a_time_slider(browser):
    chain = rc.robots.ur5e()
    T0 = chain.fk(Q_WRIST)
    T1 = T0.copy()
    T1[:3, 3] += [0.0, 0.15, -0.05]
    path = rc.paths.Line(T0, T1, speed=0.25, acceleration=1.0)
    run = rc.follow(chain, path, Q_WRIST, dt=0.01)
    with rc.viewer.Viewer(chain, Q_WRIST, path=path) as v:
        v.replay(run)
        browser.open(v.url)
        assert wait_for_client(v)
        start = browser.settled(v)
        assert "status" in v.text and "path error" in v.text and "|q̇|/vmax" in v.text
        v.seek(run.t[-1])
        end = browser.render(v)
        _shot("replay", browser)
        assert f"t = {run.t[-1]:.3f} s" in v.text
        np.testing.assert_allclose(v.q, run.q[-1])
        _leave(browser, v)
    assert _changed(start, end) > 0.001
