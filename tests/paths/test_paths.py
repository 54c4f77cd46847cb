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
    for law in ("trapezoidal", "quintic"):  # a jerk they cannot honour is refused, not ignored
        with pytest.raises(rc.InputError, match="jerk-limited' only") as info:
            rc.paths.Line(np.eye(4), _pose(np.eye(3), [0.5, 0, 0]), speed=0.3, acceleration=1.0,
                          jerk=5.0, law=law)
        assert info.value.argument == "jerk"


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


def _corner_path(blend=0.02):
    Ps = [[0.4, 0.0, 0.3], [0.5, 0.0, 0.3], [0.5, 0.1, 0.35], [0.4, 0.1, 0.35]]
    Rs = [rotx(math.pi), rotx(math.pi) @ rotz(0.3), rotx(math.pi) @ rotz(0.6), rotx(math.pi)]
    poses = [_pose(R, p) for R, p in zip(Rs, Ps, strict=True)]
    return poses, rc.paths.Waypoints(poses, blend=blend, speed=0.1, acceleration=0.5)


def _fd_rate(path, s, h):
    """d/ds of the exact tangent `twist_at` (6,) by central differences."""
    return (path.twist_at(s + h) - path.twist_at(s - h)) / (2 * h)


def test_waypoints_blend_cuts_each_corner_by_the_documented_distance():
    poses, wp = _corner_path()
    assert np.allclose(wp.start, poses[0], atol=1e-15) and np.allclose(wp.end, poses[-1], atol=1e-15)
    for i in (1, 2):
        S, d = wp.knots[i], wp.blends[i]
        seg_in, seg_out = wp.segments[i - 1], wp.segments[i]
        dv = seg_out.dp / seg_out.length - seg_in.dp / seg_in.length
        dist = np.linalg.norm(wp.position_at(S) - poses[i][:3, 3])
        assert dist == pytest.approx(5 / 32 * d * np.linalg.norm(dv), rel=1e-12)
        assert wp.corner_distances[i] == pytest.approx(dist, rel=1e-12)
        # the rotation vector from R_i at the knot: (5/32) d (w_out/L_out − w_in/L_in)
        dw = seg_out.rot.w / seg_out.length - seg_in.rot.w / seg_in.length
        assert np.allclose(so3_log(poses[i][:3, :3].T @ wp.pose_at(S)[:3, :3]), 5 / 32 * d * dw, atol=1e-14)
        # outside the blend the path is the straight segment itself
        for x in (S - d - 1e-3, S + d + 1e-3):
            seg = seg_in if x < S else seg_out
            assert np.allclose(wp.pose_at(x), seg.pose_at(x - wp.knots[i - 1 if x < S else i]), atol=1e-14)
    sharp_poses, sharp = _corner_path(blend=0.0)
    assert sharp.length == pytest.approx(wp.length)  # s is the polyline's length either way
    for i, T in enumerate(sharp_poses):  # without blends: through every waypoint
        assert np.allclose(sharp.pose_at(sharp.knots[i]), T, atol=1e-12)
    assert not np.any(sharp.corner_distances)


def test_waypoints_tangent_is_exact():
    _, wp = _corner_path()
    for s in np.linspace(1e-4, wp.length - 1e-4, 397):
        assert np.allclose(wp.twist_at(s), _fd_twist(wp, s), atol=2e-8), s
    for knot, d in zip(wp.knots[1:-1], wp.blends[1:-1], strict=True):
        for x in (knot - d, knot + d, knot - 0.3 * d, knot + 0.7 * d):
            assert np.allclose(wp.twist_at(x), _fd_twist(wp, x, h=1e-7), atol=1e-6)


def test_waypoints_curvature_and_its_rate_are_continuous():
    """d²P/ds² and d³P/ds³ vanish at both ends of every blend (as on the segments) and are
    continuous inside it: no jump of curvature (which would need infinite joint jerk) and no
    jump of its rate. Inside the blend d²p/ds² = β′(x)/(2d)·Δc_p, the documented form."""
    _, wp = _corner_path()
    for k in (1, 2):
        S, d = wp.knots[k], wp.blends[k]
        c_in, c_out = (np.concatenate([g.dp, g.rot.w]) / g.length for g in wp.segments[k - 1:k + 1])
        h = 1e-6
        xs = np.linspace(S - d + 2 * h, S + d - 2 * h, 801)
        p2 = np.array([_fd_rate(wp, x, h)[:3] for x in xs])
        x = (xs - S + d) / (2 * d)
        expected = (30 * x**2 * (1 - x) ** 2 / (2 * d))[:, None] * (c_out - c_in)[:3]
        assert np.max(np.abs(p2 - expected)) < 1e-5 * np.max(np.abs(expected))
        # curvature κ = |p′ × p″| / |p′|³: zero at the blend ends, continuous inside
        p1 = np.array([wp.twist_at(x)[:3] for x in xs])
        kappa = np.linalg.norm(np.cross(p1, p2), axis=1) / np.linalg.norm(p1, axis=1) ** 3
        assert kappa[0] < 1e-4 * kappa.max() and kappa[-1] < 1e-4 * kappa.max()
        assert np.max(np.abs(np.diff(kappa))) < 0.02 * kappa.max()
        # the rate of the whole twist (rotation too) → 0 at the blend ends, to O(ε²)
        for e, side in ((S - d, 1.0), (S + d, -1.0)):
            eps = 1e-3 * d
            inside = _fd_rate(wp, e + side * eps, 1e-7)
            assert np.max(np.abs(inside)) < 1e-4 * np.max(np.abs(c_out - c_in)) / d
            # third derivative O(ε) at the ends as well: no jump of the curvature's rate
            third = (_fd_rate(wp, e + side * 2 * eps, 1e-7) - inside) / (side * eps)
            assert np.max(np.abs(third)) < 2e-2 * np.max(np.abs(c_out - c_in)) / d**2


def test_waypoints_never_faster_than_the_path_speed():
    """‖[dp/ds; ρ ω/ṡ]‖ = 1 on the segments and < 1 inside the blends: the tool's speed in the
    metric of rotation_length never exceeds ṡ."""
    _, wp = _corner_path()
    s = np.linspace(0.0, wp.length, 2001)
    rate = np.array([np.linalg.norm(np.concatenate([t[:3], wp.rotation_length * t[3:]]))
                     for t in (wp.twist_at(x) for x in s)])
    assert np.all(rate <= 1.0 + 1e-12)
    in_blend = np.zeros(len(s), dtype=bool)
    for knot, d in zip(wp.knots[1:-1], wp.blends[1:-1], strict=True):
        in_blend |= np.abs(s - knot) < d
    assert np.allclose(rate[~in_blend], 1.0, atol=1e-12)
    assert rate[in_blend].min() < 0.9  # a real corner is being cut


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


# ---------------------------------------------------------------------- nearest point (pose metric)
def _pose_metric(path, s, T):
    """d² = ‖p(s) − p‖² + ρ²θ² of the pose T from the path point at s."""
    P = path.pose_at(s)
    return float(np.sum((P[:3, 3] - T[:3, 3]) ** 2)
                 + path.rotation_length**2 * rotation_angle(P[:3, :3].T @ T[:3, :3]) ** 2)


def _metric_paths():
    """Paths on which a position-only search is ambiguous or wrong: a pure rotation, a tour that
    rotates on the spot and comes back to its start, an out-and-back with a blended reversal —
    and ordinary ones (a line that turns, an arc that rotates, blended and sharp waypoints)."""
    T0 = _pose(rotx(math.pi), [0.4, 0.0, 0.3])
    Tr = _pose(rotx(0.6) @ T0[:3, :3], T0[:3, 3])
    Tm = _pose(T0[:3, :3], T0[:3, 3] + [0.0, 0.1, 0.0])
    T1 = _pose(rotz(0.4) @ T0[:3, :3], T0[:3, 3] + [0.15, -0.1, 0.05])
    kw = dict(speed=0.1, acceleration=1.0)
    return {
        "pure rotation": rc.paths.Line(T0, Tr, **kw),
        "rotate, move, return": rc.paths.Waypoints([T0, Tr, Tm, T0], blend=0.02, **kw),
        "out and back": rc.paths.Waypoints([T0, Tm, T0 @ transform(None, np.array([0, 0, 1e-4]))],
                                           blend=0.03, **kw),
        "line that turns": rc.paths.Line(T0, T1, **kw),
        "arc that rotates": rc.paths.Arc(T0, centre=T0[:3, 3] + [0.0, 0.1, 0.0], axis=[0, 0, 1],
                                         angle=1.5 * math.pi, orientation="rotate", **kw),
        "sharp waypoints": rc.paths.Waypoints([T0, T1, Tm], blend=0.0, **kw),
        "blended corners": _corner_path()[1],
    }


@pytest.mark.parametrize("name", list(_metric_paths()))
def test_a_pose_on_the_path_is_found_where_it_is(name):
    """distance(pose_at(s)) is (0, 0, s) from a hint near s (the search `follow` makes) — even where
    the same position (or the same pose) comes back elsewhere — and the global search finds a
    point at zero distance (the first one where the path revisits a pose)."""
    path = _metric_paths()[name]
    for s in np.linspace(0.0, path.length, 23):
        T = path.pose_at(s)
        hint = min(max(s + 0.003 * path.length * (-1) ** int(s * 1e3), 0.0), path.length)
        dpos, dang, s_found = path.distance(T, s_hint=hint, window=0.05 * path.length)
        assert dpos < 1e-9 and dang < 1e-8 and s_found == pytest.approx(s, abs=1e-7), (s, s_found)
        dpos, dang, s_glob = path.distance(T)
        assert dpos < 1e-9 and dang < 1e-8, (s, s_glob)
        assert np.allclose(path.pose_at(s_glob), T, atol=1e-8)


@pytest.mark.parametrize("name", list(_metric_paths()))
def test_the_nearest_point_is_a_minimum_of_the_pose_metric(name):
    """For poses off the path (moved by up to 2 mm and turned by up to 2°), the returned s is a
    local minimum of d² = ‖Δp‖² + ρ²θ² and no farther than the point it was perturbed from."""
    path = _metric_paths()[name]
    rng = np.random.default_rng(7)
    h = 1e-5 * path.length
    for s in np.linspace(0.02, 0.98, 13) * path.length:
        P = path.pose_at(s)
        T = _pose(so3_exp_(rng.normal(size=3) * 0.02) @ P[:3, :3], P[:3, 3] + rng.normal(size=3) * 1e-3)
        s_near = path.closest(T, s_hint=s, window=0.25 * path.length)
        f = _pose_metric(path, s_near, T)
        assert f <= _pose_metric(path, s, T) + 1e-15
        for x in (s_near - h, s_near + h):
            if 0.0 <= x <= path.length:
                assert f <= _pose_metric(path, x, T) + 1e-15, (s, s_near)


def so3_exp_(w):
    from ratectl.spatial import so3_exp

    return so3_exp(w)


def test_pure_rotation_distance_regression():
    """The new-user report: a 0.6 rad rotation on the spot; pose_at(L/2) was reported 0.3 rad away
    at s = 0 by a position-only search."""
    T0 = _pose(np.eye(3), [0.4, 0.0, 0.3])
    line = rc.paths.Line(T0, _pose(rotx(0.6), [0.4, 0.0, 0.3]), speed=0.1, acceleration=0.5)
    dpos, dang, s = line.distance(line.pose_at(line.length / 2))
    assert dpos == 0.0 and dang < 1e-12 and s == pytest.approx(line.length / 2, abs=1e-12)
    # a position alone still has no preferred point on a rotation on the spot
    assert line.closest(T0[:3, 3]) == 0.0
    with pytest.raises(InputError, match="point"):
        line.closest(np.zeros(4))


# ---------------------------------------------------------------------- corners
def test_sharp_corners_are_listed_with_both_tangents():
    """Waypoints with blend=0 list their inner waypoints as corners (where the tangent jumps),
    twist_at gives the incoming tangent with side='before' and the outgoing one by default;
    blends, straight continuations and other paths have none."""
    poses, sharp = _corner_path(blend=0.0)
    assert np.allclose(sharp.corners, sharp.knots[1:-1])
    for i, s in enumerate(sharp.corners, start=1):
        seg_in, seg_out = sharp.segments[i - 1], sharp.segments[i]
        assert np.allclose(sharp.twist_at(s, side="before"), seg_in.twist_at(seg_in.length), atol=1e-14)
        assert np.allclose(sharp.twist_at(s), seg_out.twist_at(0.0), atol=1e-14)
        assert not np.allclose(sharp.twist_at(s, side="before"), sharp.twist_at(s))
        x = s + 0.3 * seg_out.length  # away from corners both sides agree
        assert np.array_equal(sharp.twist_at(x, side="before"), sharp.twist_at(x))
    assert _corner_path(blend=0.02)[1].corners.size == 0
    mid = rc.paths.Line(poses[0], poses[1], speed=0.1, acceleration=0.5)
    straight = rc.paths.Waypoints([poses[0], mid.pose_at(0.4 * mid.length), poses[1]], blend=0.0,
                                  speed=0.1, acceleration=0.5)
    assert straight.corners.size == 0  # the same direction on both sides: no corner
    assert rc.paths.Line(poses[0], poses[1], speed=0.1, acceleration=0.5).corners.size == 0
    with pytest.raises(InputError, match="side"):
        sharp.twist_at(0.01, side="left")


@pytest.mark.parametrize("law", ["trapezoidal", "quintic", "jerk-limited"])
def test_time_law_max_jerk_is_the_largest_jerk_of_the_law(law):
    line = rc.paths.Line(_pose(np.eye(3), [0, 0, 0]), _pose(np.eye(3), [0.1, 0, 0]), speed=0.2,
                         acceleration=1.0, jerk=5.0 if law == "jerk-limited" else None, law=law)
    dt = 1e-4
    t = np.arange(0.0, line.duration, dt)
    sdd = np.array([line.progress(x)[2] for x in t])
    jerk = np.abs(np.diff(sdd)) / dt
    if law == "trapezoidal":
        assert line.law.max_jerk == math.inf and jerk.max() > 1e3  # s̈ jumps
    else:
        assert jerk.max() == pytest.approx(line.law.max_jerk, rel=1e-2)
