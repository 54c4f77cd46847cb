"""`rc.ik` with restarts finds what is there, and says so when nothing is.

Targets are fk(q) of random q within the limits (so a solution exists) and the start q0
is another random configuration: with ``restarts=20`` at least 99 % are found on every
built-in arm and on three arms from example-robot-data (UR10, Panda, xArm7). The
default run draws 40 targets per arm and allows one miss; ``RATECTL_SLOW=1`` draws 500
and asserts the 99 %. Poses out of reach give ``converged=False`` with the closest
attempt, inside the limits.
"""

from __future__ import annotations

import os
import site
import sys
from pathlib import Path

import numpy as np
import pytest

import ratectl as rc
from ratectl.solvers.ik import ik_iterate, ik_search

SLOW = bool(os.environ.get("RATECTL_SLOW"))
N = 500 if SLOW else 40


def _erd_robots() -> Path | None:
    """example-robot-data's robots directory (installed from PyPI under cmeel.prefix)."""
    for d in [*site.getsitepackages(), site.getusersitepackages(), *sys.path]:
        p = Path(d) / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if p.is_dir():
            return p
    return None


ERD = _erd_robots()
_URDFS = {"ur10": ("ur_description/urdf/ur10_robot.urdf", "tool0"),
          "panda (URDF)": ("panda_description/urdf/panda.urdf", "panda_link8"),
          "xarm7": ("xarm_description/urdf/xarm7.urdf", None)}


def _arm(name):
    if name in rc.robots.BUILTIN:
        return rc.robots.BUILTIN[name]()
    if ERD is None:
        pytest.skip("example-robot-data is not installed")
    path, tip = _URDFS[name]
    return rc.Chain.from_urdf(ERD / path, tip=tip)


@pytest.mark.parametrize("name", [*rc.robots.BUILTIN, *_URDFS])
def test_ik_with_restarts_finds_reachable_targets(name):
    arm = _arm(name)
    rng = np.random.default_rng(2024)
    q_target = arm.random_q(N, rng=rng)
    q0 = arm.random_q(N, rng=rng)
    found = 0
    for i in range(N):
        T = arm.fk(q_target[i])
        r = rc.ik(arm, T, q0[i], restarts=20, seed=i)
        assert r.within_limits and arm.within_limits(r.q)
        if r.converged:
            found += 1
            assert r.position_error <= 1e-9 and r.orientation_error <= 1e-9
            e = rc.spatial.pose_error(T, arm.fk(r.q))
            assert np.linalg.norm(e[:3]) <= 1e-9 and np.linalg.norm(e[3:]) <= 1e-9
    if SLOW:
        assert found >= 0.99 * N, f"{arm.name}: {found}/{N}"
    else:
        assert found >= N - 1, f"{arm.name}: {found}/{N}"


@pytest.mark.parametrize("name", ["ur5e", "panda", "puma560"])
def test_ik_reports_unreachable_targets_as_not_converged(name):
    arm = _arm(name)
    rng = np.random.default_rng(7)
    for q in arm.random_q(5, rng=rng):
        T = arm.fk(q)
        T[:3, 3] *= 3.0 + 2.0 * arm.reach() / max(np.linalg.norm(T[:3, 3]), 1e-3)  # beyond reach
        r = rc.ik(arm, T, q, restarts=3, seed=1, max_iter=100)
        assert not r.converged and r.position_error > 0.1
        assert arm.within_limits(r.q) and r.starts == 4


def test_nearest_returns_the_solution_on_the_branch_of_a_configuration():
    arm = rc.robots.puma560()
    q_a = np.array([0.3, -0.6, 0.4, 0.5, 0.8, -0.2])
    T = arm.fk(q_a)
    # start elsewhere: without nearest some solution, with nearest=q_a the one at q_a
    r = rc.ik(arm, T, np.zeros(6), restarts=30, seed=3, nearest=q_a)
    assert r.converged and np.allclose(r.q, q_a, atol=1e-6)
    others = []
    for s in range(8):
        x = rc.ik(arm, T, arm.random_q(rng=s), restarts=0)
        if x.converged:
            others.append(x.q)
    assert all(np.linalg.norm(r.q - q_a) <= np.linalg.norm(o - q_a) + 1e-9 for o in others)


def test_restarts_are_reproducible_with_a_seed():
    arm = rc.robots.ur5e()
    T = arm.fk(arm.random_q(rng=5))
    q0 = arm.random_q(rng=6)
    a = rc.ik(arm, T, q0, restarts=10, seed=11)
    b = rc.ik(arm, T, q0, restarts=10, seed=11)
    assert np.array_equal(a.q, b.q) and a.starts == b.starts and a.iterations == b.iterations


def test_the_core_is_callable_below_the_planner():
    arm = rc.robots.ur5e()
    q = np.array([0.1, -1.2, 1.3, -1.6, -1.5, 0.2])
    T = arm.fk(q)
    r = ik_iterate(arm, T, q + 0.05, tol_position=1e-9, tol_orientation=1e-9, max_iter=100, damping=1e-3,
                   max_step=0.2)
    assert r.converged and r.starts == 1 and np.allclose(r.q, q, atol=1e-6)
    s = ik_search(arm, T, q + 2.0, tol_position=1e-9, tol_orientation=1e-9, max_iter=200, damping=1e-3,
                  max_step=0.2, restarts=10, seed=0)
    assert s.converged and s.starts >= 1
    with pytest.raises(ValueError):
        s.q[0] = 1.0  # read-only
