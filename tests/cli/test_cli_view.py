"""``ratectl view`` and ``ratectl demo --view``: bounded runs (``--seconds``) without a browser."""

import numpy as np
import pytest
from cli_helpers import run  # noqa: E402 - the helper module beside these tests

import ratectl as rc
from ratectl.cli import main as cli

pytest.importorskip("viser", reason="the viewer needs the view extra: pip install -e '.[view]'")


@pytest.fixture
def opened(monkeypatch):
    """The viewers the command opens, with a hook to act on each one first."""
    made, hooks = [], []
    original = cli._open_viewer

    def spy(chain, q, **options):
        v = original(chain, q, **options)
        made.append(v)
        for hook in hooks:
            hook(v)
        return v

    monkeypatch.setattr(cli, "_open_viewer", spy)
    return made, hooks


def test_view_serves_the_arm_and_servos_to_the_dragged_target(opened):
    made, hooks = opened
    moved = {}

    def drag(v):   # as if the user dragged the target 6 cm along x in the browser
        T = v.target.copy()
        T[0, 3] += 0.06
        v.target = T
        moved["T"] = T

    hooks.append(drag)
    code, out, err = run(["view", "ur5e", "--q", "0", "-1.6", "1.7", "-1.7", "-1.57", "0", "--servo",
                          "--seconds", "2.5"])
    assert code == 0, err
    assert "http://127.0.0.1:" in out
    (v,) = made
    T = rc.robots.ur5e().fk(v.q)
    assert np.linalg.norm(T[:3, 3] - moved["T"][:3, 3]) < 1e-3   # the arm followed the target
    assert "σ_min(J_L)" in v.text


def test_view_without_servo_keeps_the_arm_still(opened):
    made, _ = opened
    code, out, err = run(["view", "puma560", "--seconds", "0.3"])
    assert code == 0, err
    np.testing.assert_array_equal(made[0].q, np.zeros(6))


def test_view_refuses_a_negative_duration():
    code, out, err = run(["view", "ur5e", "--seconds", "-1"])
    assert code == 2 and "--seconds" in err


@pytest.mark.xdist_group("demo")
def test_demo_view_replays_the_five_methods_side_by_side(opened):
    made, _ = opened
    code, out, err = run(["demo", "--fast", "--no-plot", "--view", "--seconds", "0.3"])
    assert code == 0, err
    (v,) = made
    assert len(v._extra_arms) == 4
    for method in ("exact inverse", "DLS", "adaptive DLS", "QP"):
        assert f"**{method}**" in v.text
    assert "**governor**" in v.text
