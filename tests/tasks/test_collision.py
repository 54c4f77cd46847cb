"""Collision models from the Panda URDF (coal): pairs, exclusions, damper rows in the loop."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import ratectl as rc

sys.path.insert(0, str(Path(__file__).resolve().parent))
from panda_erd import (  # noqa: E402
    HOME,
    PinocchioDistance,
    default_overlaps,
    panda_chain,
    panda_urdf,
    srdf_default_pairs,
)

URDF = panda_urdf()
pytestmark = [pytest.mark.skipif(URDF is None, reason="example-robot-data is not installed")]
coal = pytest.importorskip("coal")


def test_import_ratectl_does_not_load_coal():
    code = "import sys, ratectl, ratectl.collision, ratectl.tasks; print('coal' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_self_collision_pairs_and_distances_match_pinocchio():
    pytest.importorskip("pinocchio")
    ch = panda_chain(URDF)
    sc = rc.collision.SelfCollision.from_urdf(URDF, ch, margin=0.02, exclude=[("panda_link1", "panda_link3")])
    excluded = {frozenset(p[:2]): p[2] for p in sc.excluded}
    assert "adjacent" in excluded[frozenset(("panda_link3", "panda_link4"))]
    assert "caller" in excluded[frozenset(("panda_link1", "panda_link3"))]
    assert "default configuration" in excluded[frozenset(("panda_link5", "panda_link7"))]
    assert "adjacent" in sc.describe()
    pd = PinocchioDistance(URDF, exclude=default_overlaps(sc) + (("panda_link1", "panda_link3"),))
    checked = 0
    for seed in range(12):
        q = ch.random_q(rng=seed)
        d = pd(q)
        if d > 0:  # separated (penetration depths come from different EPA runs)
            assert sc.distances(q).min() == pytest.approx(d, abs=1e-6)
            checked += 1
    assert checked >= 3


def test_pairs_overlapping_in_the_default_configuration_are_the_srdf_default_pairs():
    # the rule that leaves out the pairs whose hulls overlap in the default configuration finds,
    # among the pairs that are not adjacent, exactly the pairs the package's own SRDF (written
    # by MoveIt's setup assistant) disables as "Default"
    ch = panda_chain(URDF)
    sc = rc.collision.SelfCollision.from_urdf(URDF, ch, margin=0.02)
    adjacent = {frozenset(p[:2]) for p in sc.excluded if p[2].startswith("adjacent")}
    found = {frozenset(p) for p in default_overlaps(sc)}
    assert found == srdf_default_pairs(URDF) - adjacent
    assert found  # (link 5 with link 7 and with the hand)
    q0 = rc.collision.self_collision.default_configuration(ch)
    assert ch.within_limits(q0)
    # and they overlap there: checked after all with include=, their distance is negative
    inc = rc.collision.SelfCollision.from_urdf(URDF, ch, margin=0.02, include=sorted(tuple(p) for p in found))
    d = inc.distances(q0)
    for pair in found:
        mine = [k for k, (a, b) in enumerate(inc.pair_names)
                if frozenset((a.split("#")[0], b.split("#")[0])) == pair]
        assert mine and d[mine].min() < 0.0
    assert len(inc.pairs) > len(sc.pairs)
    assert not [p for p in inc.excluded if p[2].startswith("overlap")]


def test_sphere_obstacle_is_kept_at_the_margin_and_reported():
    ch = panda_chain(URDF)
    T0 = ch.fk(HOME)
    centre = T0[:3, 3] + np.array([0.15, 0.0, 0.0])
    ball = rc.collision.Sphere(centre, 0.04)
    obs = rc.collision.Obstacles.from_urdf(URDF, ch, [ball], margin=0.02, links=["panda_hand"])
    T = T0.copy()
    T[:3, 3] += [0.3, 0.0, 0.0]  # straight through the ball
    tool = rc.tasks.Pose(priority=0, target=T, gain=3.0)
    ctrl = rc.ResolvedRateController(ch, tasks=[tool, rc.tasks.Posture(HOME, priority=1, gain=0.5)],
                                     collision=[obs])
    q = HOME.copy()
    dmin, statuses = np.inf, set()
    for _ in range(1500):
        cmd = ctrl.step(q, dt=2e-3)
        q = cmd.q_next.copy()
        dmin = min(dmin, float(obs.distances(q).min()))
        statuses.update(cmd.flags)
    assert dmin >= 0.015
    assert "collision-avoidance" in statuses


def test_rows_skip_only_pairs_beyond_the_influence_distance():
    # the broad phase (bounding spheres, and the last distance less how far the shapes have
    # moved since) must never drop a pair that is within the influence distance: compare with
    # every pair's distance (no broad phase) along a smooth path, then after jumps
    ch = panda_chain(URDF)
    sc = rc.collision.SelfCollision.from_urdf(URDF, ch, margin=0.02)
    rng = np.random.default_rng(3)
    q_far = ch.random_q(rng=rng)
    path = [HOME + s * (q_far - HOME) for s in np.linspace(0.0, 1.0, 40)]
    path += [ch.random_q(rng=rng) for _ in range(8)] + [HOME, HOME]
    names = sc.pair_names
    computed = 0
    for q in path:
        r = sc.rows(q)
        d = sc.distances(q)
        within = {names[k]: d[k] for k in np.flatnonzero(d < sc.influence)}
        assert set(r.pairs) == set(within)
        for pair, dist in zip(r.pairs, r.distance, strict=True):
            assert dist == pytest.approx(within[pair], abs=1e-9)
        computed += len(r.pairs)
        if within:
            assert r.closest == pytest.approx(min(within.values()), abs=1e-9)
    assert computed > 0


def test_damper_rows_are_the_distance_rate():
    # G q̇ = −ḋ: the row against a finite difference of the distance of each near pair
    ch = panda_chain(URDF)
    sc = rc.collision.SelfCollision.from_urdf(URDF, ch, margin=0.02)
    rng = np.random.default_rng(4)
    checked = 0
    for _ in range(6):
        q = ch.random_q(rng=rng)
        r = sc.rows(q)
        qd = rng.normal(size=ch.dof)
        eps = 1e-6
        dp, dm = sc.distances(q + eps * qd), sc.distances(q - eps * qd)
        idx = {p: k for k, p in enumerate(sc.pair_names)}
        for row, pair, dist in zip(r.G, r.pairs, r.distance, strict=True):
            if dist <= 1e-3:
                continue  # penetrating: the witness points jump between faces
            ddot = (dp[idx[pair]] - dm[idx[pair]]) / (2 * eps)
            assert -row @ qd == pytest.approx(ddot, abs=1e-4 * (1 + abs(ddot)))
            checked += 1
    assert checked >= 5


def test_smoothed_tasks_hold_the_dampers_and_the_jerk_limit():
    """tasks= with smoothing=True: the cascade's q̇ goes through the Ruckig filter (|q̈| ≤ amax,
    |q⃛| ≤ jmax of what is commanded), and the collision dampers hold on what is commanded:
    the ball stays beyond 15 mm of the hand with the 2 cm margin. A period where the filter's
    lag would break a damper commands the cascade's q̇ within amax instead, says so, and the
    filter restarts from it at zero q̈ (the jerk bound holds from there)."""
    ch = panda_chain(URDF)
    ch = ch.with_limits(jmax=np.full(ch.dof, 500.0))  # the URDF has none; jmax·dt well below amax
    T0 = ch.fk(HOME)
    centre = T0[:3, 3] + np.array([0.15, 0.0, 0.0])
    obs = rc.collision.Obstacles.from_urdf(URDF, ch, [rc.collision.Sphere(centre, 0.04)], margin=0.02,
                                           links=["panda_hand"])
    T = T0.copy()
    T[:3, 3] += [0.3, 0.0, 0.0]  # straight through the ball
    tool = rc.tasks.Pose(priority=0, target=T, gain=3.0)
    ctrl = rc.ResolvedRateController(ch, tasks=[tool, rc.tasks.Posture(HOME, priority=1, gain=0.5)],
                                     collision=[obs], smoothing=True)
    dt = 2e-3
    q = HOME.copy()
    dmin, statuses = np.inf, set()
    qdd_prev = np.zeros(ch.dof)
    restarted = False  # the period after a restart of the filter starts from zero q̈
    for _ in range(1500):
        cmd = ctrl.step(q, dt=dt)
        assert np.all(np.abs(cmd.qd) <= ch.vmax * (1 + 1e-9))
        assert np.all(np.abs(cmd.qdd) <= ch.amax * (1 + 1e-6))
        fallback = "break a collision damper" in cmd.reason
        if not fallback:
            ref = np.zeros(ch.dof) if restarted else qdd_prev
            assert np.all(np.abs(cmd.qdd - ref) <= ch.jmax * dt * (1 + 1e-6) + 1e-9)
        restarted = fallback
        qdd_prev = cmd.qdd
        q = cmd.q_next.copy()
        dmin = min(dmin, float(obs.distances(q).min()))
        statuses.update(cmd.flags)
    assert dmin >= 0.015
    assert "collision-avoidance" in statuses
    assert np.all(q >= ch.lower) and np.all(q <= ch.upper)
