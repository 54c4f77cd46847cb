"""Reachability-based time-optimal speed profile: limits hold on the grid, it matches toppra."""

import numpy as np
import pytest

from ratectl.planning import joint_path
from ratectl.planning.topp import reachability_profile


@pytest.fixture(scope="module")
def jp_and_limits(ur5e_exact_wrist):
    arm, line, q0 = ur5e_exact_wrist
    return joint_path(arm, line, q0), arm.vmax, arm.amax, line.speed, line.acceleration


def test_profile_respects_every_limit_on_the_grid(jp_and_limits):
    jp, vmax, amax, speed, acc = jp_and_limits
    prof = reachability_profile(jp, vmax, amax, speed, acc)
    x, u = prof.x, prof.u
    assert x[0] == 0.0 and x[-1] == 0.0 and np.all(x >= 0) and np.all(x <= prof.mvc + 1e-12)
    sd = np.sqrt(x)
    assert np.all(np.abs(jp.dq) * sd[:, None] <= vmax * (1 + 1e-9))
    qdd = jp.dq[:-1] * u[:-1, None] + jp.ddq[:-1] * x[:-1, None]
    assert np.all(np.abs(qdd) <= amax * (1 + 1e-6))
    assert np.all(sd <= speed * (1 + 1e-12)) and np.all(np.abs(u[:-1]) <= acc * (1 + 1e-9))
    # x_{k+1} = x_k + 2 Δ u_k and the times follow from it
    assert np.allclose(np.diff(x), 2 * np.diff(jp.s) * u[:-1], atol=1e-12)
    dt = 2 * np.diff(jp.s) / (sd[:-1] + sd[1:])
    assert prof.duration == pytest.approx(np.sum(dt), rel=1e-9)


def test_profile_matches_toppra(jp_and_limits):
    ta = pytest.importorskip("toppra")
    jp, vmax, amax, speed, acc = jp_and_limits
    prof = reachability_profile(jp, vmax, amax, speed, acc)
    way = np.hstack([jp.q, jp.s[:, None]])  # the extra coordinate s carries the path's limits
    geo = ta.SplineInterpolator(jp.s, way)
    vlim, alim = np.append(vmax, speed), np.append(amax, acc)
    cons = [ta.constraint.JointVelocityConstraint(np.stack([-vlim, vlim], axis=1)),
            ta.constraint.JointAccelerationConstraint(np.stack([-alim, alim], axis=1))]
    algo = ta.algorithm.TOPPRA(cons, geo, gridpoints=np.linspace(0, jp.s[-1], 1001),
                               parametrizer="ParametrizeConstAccel")
    ref = algo.compute_trajectory(0.0, 0.0).duration
    assert prof.duration == pytest.approx(ref, rel=0.02)


def test_sampled_progress_is_continuous_and_ends_at_rest(jp_and_limits):
    jp, vmax, amax, speed, acc = jp_and_limits
    prof = reachability_profile(jp, vmax, amax, speed, acc)
    dt = 2e-3
    s, sd, _ = prof.sample(dt)
    assert s[0] == 0.0 and s[-1] == jp.s[-1] and sd[-1] == 0.0
    assert np.all(np.diff(s) >= 0)
    assert np.allclose(np.diff(s) / dt, 0.5 * (sd[1:] + sd[:-1]), atol=acc * dt)
    assert len(s) == int(np.ceil(prof.duration / dt - 1e-9)) + 1
