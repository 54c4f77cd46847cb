"""A frame task's rows: the link's Jacobian rows and b = √w·(ξ_ff + K e) with e the pose
error of `ratectl.spatial.pose_error`, for the tool and for a link, every kind of frame task."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ratectl as rc

ROWS = {"Pose": slice(0, 6), "Position": slice(0, 3), "Orientation": slice(3, 6)}


@settings(max_examples=60, deadline=None)
@given(kind=st.sampled_from(sorted(ROWS)), link=st.sampled_from([None, "link4", "link7"]),
       seed=st.integers(0, 10_000), weight=st.sampled_from([1.0, 0.3]), gain=st.floats(0.0, 50.0),
       twist=st.booleans(), strided=st.booleans())
def test_frame_task_rows_are_the_jacobian_and_the_pose_error(kind, link, seed, weight, gain, twist, strided):
    ch = rc.robots.panda()
    rng = np.random.default_rng(seed)
    q = ch.random_q(rng=rng)
    T_target = ch.fk(ch.random_q(rng=rng), link=link)
    task = getattr(rc.tasks, kind)(link=link, weight=weight, gain=gain)
    r = ROWS[kind]
    ff = rng.normal(size=r.stop - r.start) if twist else None
    if kind == "Position":
        task.set_target(T_target[:3, 3], **({"velocity": ff} if twist else {}))
    elif kind == "Orientation":
        task.set_target(T_target[:3, :3], **({"angular_velocity": ff} if twist else {}))
    else:
        task.set_target(T_target, **({"twist": ff} if twist else {}))
    # independently: the pose error of the package and the link's Jacobian
    T = ch.fk(q, link=link)
    e = rc.spatial.pose_error(T_target, T)[r]
    J = ch.jacobian(q, link=link)[r]
    b = gain * e + (ff if twist else 0.0)
    # the rows written into an array of their own or into a column block of a wider one
    A = np.zeros((r.stop - r.start, 9))[:, 1:8] if strided else np.zeros((r.stop - r.start, 7))
    bb = np.zeros(r.stop - r.start)
    ee = np.zeros(r.stop - r.start)
    sw = math.sqrt(weight)
    norm = task._fill(ch, q, A, bb, ee, sw)
    np.testing.assert_allclose(ee, e, rtol=0, atol=1e-12)
    np.testing.assert_allclose(bb, sw * b, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(A, sw * J)
    assert norm == pytest.approx(np.linalg.norm(e), abs=1e-12)
    rows = task.rows(ch, q)  # the public form, unscaled
    np.testing.assert_allclose(rows.b, b, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(rows.A, J)


@pytest.mark.parametrize("make", [lambda ch: rc.tasks.Pose(target=ch.fk(np.zeros(7))),
                                  lambda ch: rc.tasks.Position(link="link4", target=np.zeros(3)),
                                  lambda ch: rc.tasks.Posture(np.zeros(7))])
@pytest.mark.parametrize("q", [np.full(7, np.nan), np.r_[np.zeros(6), np.inf], np.zeros((2, 7)), np.zeros(6)])
def test_rows_at_a_configuration_that_is_not_one_finite_q_are_refused(make, q):
    ch = rc.robots.panda()
    with pytest.raises(rc.errors.InputError, match="q must|one configuration"):
        make(ch).rows(ch, q)
