"""Cartesian paths and time laws: geometry, derivatives, limits, errors."""

import math

import numpy as np
import pytest

import ratectl as rc
from ratectl.errors import InputError
from ratectl.paths import JerkLimited, Quintic, Trapezoidal
from ratectl.spatial import rotation_angle, rotx, roty, rotz, so3_log, transform


def _pose(R, p):
    return transform(R, np.asarray(p, dtype=float))


def _fd_twist(path, s, h=1e-6):
    """Finite-difference tangent dP/ds as [dp; ω] (ω from log(R(s+h) R(s−h)ᵀ)/2h)."""
    a, b = path.pose_at(s - h), path.pose_at(s + h)
    v = (b[:3, 3] - a[:3, 3]) / (2 * h)
    w = so3_log(b[:3, :3] @ a[:3, :3].T) / (2 * h)
    return np.concatenate([v, w])


@pytest.mark.parametrize("law", [Trapezoidal, Quintic])
@pytest.mark.parametrize("length", [0.01, 0.3, 2.0])
def test_time_laws_respect_limits_and_end_at_rest(law, length):
    v, a = 0.25, 1.5
    tl = law(length, speed=v, acceleration=a)
    t = np.linspace(0, tl.duration, 4001)
    s, sd, sdd = np.array([tl(x) for x in t]).T
    assert s[0] == 0 and abs(s[-1] - length) < 1e-12
    assert np.all(np.diff(s) >= -1e-15)
    assert np.max(sd) <= v * (1 + 1e-9) and np.max(np.abs(sdd)) <= a * (1 + 1e-9)
    assert sd[0] == 0 and abs(sd[-1]) < 1e-9
    # ṡ is the derivative of s
    assert np.max(np.abs(np.gradient(s, t) - sd)) < 2e-3 * max(v, 1e-3) + a * (t[1] - t[0])
    # one of the limits is reached (time-optimal within the law's family)
    assert max(np.max(sd) / v, np.max(np.abs(sdd)) / a) > 0.99


def test_trapezoid_duration_closed_form():
    L, v, a = 1.0, 0.5, 2.0
    assert Trapezoidal(L, speed=v, acceleration=a).duration == pytest.approx(L / v + v / a)
    L = 0.01  # triangular
    assert Trapezoidal(L, speed=v, acceleration=a).duration == pytest.approx(2 * math.sqrt(L / a))
    assert Quintic(1.0, speed=0.5, acceleration=100.0).duration == pytest.approx(15 / 8 / 0.5)


def test_jerk_limited_law_respects_jerk():
    tl = JerkLimited(0.5, speed=0.3, acceleration=1.0, jerk=5.0)
    dt = 1e-3
    t = np.arange(0, tl.duration + dt, dt)
    s, sd, sdd = np.array([tl(x) for x in t]).T
    assert abs(s[-1] - 0.5) < 1e-9 and abs(sd[-1]) < 1e-9
    assert np.max(sd) <= 0.3 + 1e-9 and np.max(np.abs(sdd)) <= 1.0 + 1e-9
    assert np.max(np.abs(np.diff(sdd))) / dt <= 5.0 * (1 + 1e-6)
    # slower than the trapezoid with the same v, a
    assert tl.duration > Trapezoidal(0.5, speed=0.3, acceleration=1.0).duration
    path = rc.paths.Line(np.eye(4), _pose(np.eye(3), [0.5, 0, 0]), speed=0.3, acceleration=1.0, jerk=5.0)
    assert path.law.name == "jerk-limited"


def test_line_geometry_twist_and_time():
    R0, R1 = rotz(0.3) @ rotx(0.2), rotz(-0.5) @ roty(0.4)
    T0, T1 = _pose(R0, [0.4, -0.1, 0.3]), _pose(R1, [0.1, 0.3, 0.5])
    line = rc.paths.Line(T0, T1, speed=0.2, acceleration=1.0)
    assert np.allclose(line.start, T0) and np.allclose(line.end, T1)
    dp = np.linalg.norm(T1[:3, 3] - T0[:3, 3])
    ang = rotation_angle(R0.T @ R1)
    assert line.length == pytest.approx(math.hypot(dp, 0.1 * ang))
    for s in np.linspace(0.01, line.length - 0.01, 7):
        assert np.allclose(line.twist_at(s), _fd_twist(line, s), atol=1e-7)
        # positions on the segment, orientation on the geodesic
        P = line.pose_at(s)
        lam = s / line.length
        assert np.allclose(P[:3, 3], T0[:3, 3] + lam * (T1[:3, 3] - T0[:3, 3]))
        assert rotation_angle(R0.T @ P[:3, :3]) == pytest.approx(lam * ang, abs=1e-12)
    # time interface = law ∘ geometry
    t = 0.37 * line.duration
    s, sd, _ = line.progress(t)
    assert np.allclose(line.pose(t), line.pose_at(s)) and np.allclose(line.twist(t), line.twist_at(s) * sd)
    assert np.allclose(line.pose(-1.0), T0) and np.allclose(line.pose(1e3), T1)
    assert np.allclose(line.twist(1e3), 0.0)


def test_arc_centre_axis_and_three_points():
    T0 = _pose(rotx(math.pi), [0.5, 0.0, 0.3])
    c, k = np.array([0.4, 0.0, 0.3]), np.array([0.0, 0.0, 1.0])
    arc = rc.paths.Arc(T0, centre=c, axis=k, angle=math.pi / 2, speed=0.1, acceleration=0.5)
    assert arc.radius == pytest.approx(0.1) and arc.length == pytest.approx(0.1 * math.pi / 2)
    assert np.allclose(arc.end[:3, 3], [0.4, 0.1, 0.3])
    assert np.allclose(arc.end[:3, :3], T0[:3, :3])  # fixed orientation
    for s in np.linspace(0.0, arc.length, 9):
        assert np.linalg.norm(arc.position_at(s) - c) == pytest.approx(0.1)
        if 0 < s < arc.length:
            assert np.allclose(arc.twist_at(s), _fd_twist(arc, s), atol=1e-7)
    # "rotate": the tool turns with the arc
    arc_r = rc.paths.Arc(T0, centre=c, axis=k, angle=math.pi / 2, orientation="rotate", speed=0.1,
                         acceleration=0.5)
    assert np.allclose(arc_r.end[:3, :3], rotz(math.pi / 2) @ T0[:3, :3])
    s = 0.3 * arc_r.length
    assert np.allclose(arc_r.twist_at(s), _fd_twist(arc_r, s), atol=1e-7)
    # three points: start, via, end on one circle, passed in order
    T2 = _pose(rotx(math.pi) @ rotz(0.5), [0.3, 0.0, 0.3])
    arc3 = rc.paths.Arc.through(T0, [0.4, 0.1, 0.3], T2, speed=0.1, acceleration=0.5)
    assert np.allclose(arc3.centre, c) and arc3.angle == pytest.approx(math.pi)
    assert np.allclose(arc3.end, T2, atol=1e-12)
    s_via = arc3.closest([0.4, 0.1, 0.3])
    assert np.linalg.norm(arc3.position_at(s_via) - [0.4, 0.1, 0.3]) < 1e-9
    assert s_via == pytest.approx(arc3.length / 2, rel=1e-6)
    with pytest.raises(InputError, match="collinear"):
        rc.paths.Arc.through(T0, [0.4, 0.0, 0.3], T2, speed=0.1, acceleration=0.5)


def test_waypoints_pass_through_and_are_smooth():
    Ps = [[0.4, 0.0, 0.3], [0.5, 0.0, 0.3], [0.5, 0.1, 0.35], [0.4, 0.1, 0.35]]
    Rs = [rotx(math.pi), rotx(math.pi) @ rotz(0.3), rotx(math.pi) @ rotz(0.6), rotx(math.pi)]
    poses = [_pose(R, p) for R, p in zip(Rs, Ps, strict=True)]
    wp = rc.paths.Waypoints(poses, blend=0.02, speed=0.1, acceleration=0.5)
    assert np.allclose(wp.start, poses[0]) and np.allclose(wp.end, poses[-1])
    for i, T in enumerate(poses):  # passes through every waypoint (at its knot)
        assert np.allclose(wp.pose_at(wp.knots[i]), T, atol=1e-12)
    # C1: the tangent is continuous everywhere, also at the blend ends
    s = np.linspace(1e-4, wp.length - 1e-4, 3001)
    tw = np.array([wp.twist_at(x) for x in s])
    assert np.max(np.abs(np.diff(tw, axis=0))) < 0.2  # a corner would jump by ~1–8
    for knot, d in zip(wp.knots[1:-1], wp.blends[1:-1], strict=True):
        for x in (knot - d, knot + d, knot - 0.3 * d):
            assert np.allclose(wp.twist_at(x), _fd_twist(wp, x, h=1e-7), atol=1e-5)
    # sharp corners without blends
    sharp = rc.paths.Waypoints(poses, blend=0.0, speed=0.1, acceleration=0.5)
    assert sharp.length == pytest.approx(wp.length)


def test_closest_and_distance():
    T0, T1 = _pose(np.eye(3), [0, 0, 0]), _pose(np.eye(3), [1, 0, 0])
    line = rc.paths.Line(T0, T1, speed=1, acceleration=1)
    T = _pose(rotz(0.1), [0.3, 0.004, -0.003])
    dpos, dang, s = line.distance(T)
    assert s == pytest.approx(0.3) and dpos == pytest.approx(0.005) and dang == pytest.approx(0.1)
    arc = rc.paths.Arc(_pose(np.eye(3), [1, 0, 0]), centre=[0, 0, 0], axis=[0, 0, 1], angle=math.pi,
                       speed=1, acceleration=1)
    p = np.array([0.0, 1.2, 0.0])
    assert arc.closest(p) == pytest.approx(math.pi / 2)
    assert arc.closest(p, s_hint=1.4, window=0.5) == pytest.approx(math.pi / 2)
    assert arc.distance(_pose(np.eye(3), p))[0] == pytest.approx(0.2)


def test_path_input_errors():
    T = np.eye(4)
    with pytest.raises(InputError, match="speed"):
        rc.paths.Line(T, T, speed=0.0, acceleration=1.0)
    with pytest.raises(InputError, match="acceleration"):
        rc.paths.Line(T, T, speed=1.0, acceleration=float("nan"))
    with pytest.raises(InputError, match="4x4"):
        rc.paths.Line(np.eye(3), T, speed=1.0, acceleration=1.0)
    bad = np.eye(4)
    bad[0, 0] = 2.0
    with pytest.raises(InputError, match="rigid"):
        rc.paths.Line(bad, T, speed=1.0, acceleration=1.0)
    with pytest.raises(InputError, match="law"):
        rc.paths.Line(T, T, speed=1.0, acceleration=1.0, law="cubic")
    with pytest.raises(InputError, match="jerk"):
        rc.paths.Line(T, T, speed=1.0, acceleration=1.0, law="jerk-limited")
    with pytest.raises(InputError, match="axis"):
        rc.paths.Arc(T, centre=[1, 0, 0], axis=[0, 0, 0], angle=1.0, speed=1, acceleration=1)
    with pytest.raises(InputError, match="radius 0"):
        rc.paths.Arc(T, centre=[0, 0, 0], axis=[0, 0, 1], angle=1.0, speed=1, acceleration=1)
    with pytest.raises(InputError, match="orientation"):
        rc.paths.Arc(T, centre=[1, 0, 0], axis=[0, 0, 1], angle=1.0, orientation="spin", speed=1,
                     acceleration=1)
    with pytest.raises(InputError, match="N ≥ 2"):
        rc.paths.Waypoints([T], speed=1, acceleration=1)
    with pytest.raises(InputError, match="coincide"):
        rc.paths.Waypoints([T, T], speed=1, acceleration=1)
    line = rc.paths.Line(T, _pose(np.eye(3), [1, 0, 0]), speed=1, acceleration=1)
    with pytest.raises(InputError, match="finite"):
        line.pose_at(float("nan"))
