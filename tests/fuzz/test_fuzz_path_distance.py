"""Fuzz: nearest points and distances of paths on hostile and ordinary inputs.

* Every path (`Line`, `Arc`, `Waypoints`) asked for `closest` / `distance` with NaN or
  infinite entries, a non-rigid pose, text, a window ≤ 0 or NaN, an s_hint NaN or text:
  a `RatectlError` (never a NaN answer, a foreign exception or a call that does not
  return) within a few seconds.
* Constructors on hostile arguments (ragged or text poses, blend None or text, poses
  1e300 m apart): a `RatectlError`, never a path of infinite length.
* Without ``s_hint`` the nearest point of a `Waypoints` path (sharp corners, blends,
  closed tours) is the global one: no sample of a dense grid is nearer.
"""

from __future__ import annotations

import math
import threading

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import ratectl as rc
from ratectl.errors import RatectlError
from ratectl.spatial import so3_exp, so3_log


def _pose(p, rv=(0.0, 0.0, 0.0)):
    T = np.eye(4)
    T[:3, :3] = so3_exp(np.asarray(rv, dtype=float))
    T[:3, 3] = p
    return T


def _returns_within(fn, seconds=5.0):
    """(done, value or exception) of fn() run in a daemon thread for at most ``seconds``."""
    box: dict = {}

    def run():
        try:
            box["value"] = fn()
        except BaseException as exc:  # noqa: BLE001 - handed back to the test
            box["exc"] = exc

    th = threading.Thread(target=run, daemon=True)
    th.start()
    th.join(seconds)
    return not th.is_alive(), box


def _paths():
    T0, T1 = _pose([0.4, 0.0, 0.3]), _pose([0.5, 0.2, 0.3], [0.0, 0.0, 0.5])
    line = rc.paths.Line(T0, T1, speed=0.1, acceleration=1.0)
    arc = rc.paths.Arc(T0, centre=[0.3, 0.0, 0.3], axis=[0, 0, 1], angle=1.0, speed=0.1, acceleration=1.0)
    way = rc.paths.Waypoints([T0, T1, _pose([0.3, 0.3, 0.4])], blend=0.02, speed=0.1, acceleration=1.0)
    sharp = rc.paths.Waypoints([T0, T1, _pose([0.3, 0.3, 0.4])], blend=0.0, speed=0.1, acceleration=1.0)
    return [line, arc, way, sharp]


_BAD_NUMBERS = [math.nan, math.inf, -math.inf, "1", None, 1j]


def _hostile_target(r):
    kind = int(r.integers(0, 6))
    T = _pose(r.uniform(-1, 1, 3), r.normal(0, 1, 3))
    if kind == 0:  # NaN / inf in a pose
        T[int(r.integers(0, 3)), int(r.integers(0, 4))] = r.choice([math.nan, math.inf])
        return T
    if kind == 1:  # a scaled pose
        T[:3, :3] *= 2.0
        return T
    if kind == 2:  # NaN point
        p = r.uniform(-1, 1, 3)
        p[int(r.integers(0, 3))] = math.nan
        return p
    if kind == 3:
        return "abc"
    if kind == 4:
        return np.zeros(5)
    return [[1, 2, 3], [4, 5]]


def test_hostile_distance_queries_raise_a_ratectl_error_quickly(fuzz):
    paths = _paths()

    @fuzz.settings(60)
    @given(seed=st.integers(0, 2**32 - 1))
    def prop(seed):
        r = np.random.default_rng(seed)
        path = paths[seed % len(paths)]
        good = path.pose_at(r.uniform(0, path.length))
        choice = int(r.integers(0, 4))
        if choice == 0:
            call = lambda: path.distance(_hostile_target(r))  # noqa: E731
        elif choice == 1:
            call = lambda: path.closest(_hostile_target(r))  # noqa: E731
        elif choice == 2:
            bad = _BAD_NUMBERS[int(r.integers(0, len(_BAD_NUMBERS)))]
            bad = -1.0 if bad is None and r.random() < 0.5 else bad
            call = lambda: path.closest(good, s_hint=0.01, window=bad if bad is not None else -1.0)  # noqa: E731
        else:
            bad = _BAD_NUMBERS[int(r.integers(0, len(_BAD_NUMBERS)))]
            call = lambda: path.distance(good, s_hint=bad)  # noqa: E731
        done, box = _returns_within(call)
        fuzz.count("path_distance")
        assert done, "the call did not return"
        if "exc" in box:
            assert isinstance(box["exc"], RatectlError), repr(box["exc"])
        else:  # only an infinite s_hint/window may be a valid request: the answer is finite
            v = box["value"]
            assert np.all(np.isfinite(np.asarray(v, dtype=float)))

    prop()


@pytest.mark.parametrize("make", [
    lambda: rc.paths.Waypoints([np.eye(4), np.eye(3)], speed=1.0, acceleration=1.0),
    lambda: rc.paths.Waypoints("abc", speed=1.0, acceleration=1.0),
    lambda: rc.paths.Waypoints([np.eye(4), _pose([1, 0, 0])], blend=None, speed=1.0, acceleration=1.0),
    lambda: rc.paths.Waypoints([np.eye(4), _pose([1, 0, 0])], blend="1", speed=1.0, acceleration=1.0),
    lambda: rc.paths.Waypoints([np.eye(4), _pose([math.nan, 0, 0])], speed=1.0, acceleration=1.0),
    lambda: rc.paths.Line(_pose([-1e300, 0, 0]), _pose([1e300, 0, 0]), speed=1.0, acceleration=1.0),
    lambda: rc.paths.Line(_pose([-1.7e308, 0, 0]), _pose([1.7e308, 0, 0]), speed=1.0, acceleration=1.0),
    lambda: rc.paths.Arc(_pose([1e300, 0, 0]), centre=[0, 0, 0], axis=[0, 0, 1], angle=1.0, speed=1.0,
                         acceleration=1.0),
])
def test_hostile_path_arguments_raise_a_ratectl_error(make):
    with _no_warning():  # refused, without overflow warnings on the way
        with pytest.raises(RatectlError):
            make()


class _no_warning:
    def __enter__(self):
        import warnings

        self._w = warnings.catch_warnings()
        self._w.__enter__()
        warnings.simplefilter("error")

    def __exit__(self, *exc):
        return self._w.__exit__(*exc)


def _brute_nearest(path, T, n=1501):
    rho2 = path.rotation_length ** 2
    best = math.inf
    for s in np.linspace(0.0, path.length, n):
        P = path.pose_at(s)
        e = P[:3, 3] - T[:3, 3]
        phi = so3_log(P[:3, :3] @ T[:3, :3].T)
        best = min(best, float(e @ e) + rho2 * float(phi @ phi))
    return best


def test_waypoints_nearest_point_without_a_hint_is_global(fuzz):
    @fuzz.settings(8)
    @given(seed=st.integers(0, 2**32 - 1))
    def prop(seed):
        r = np.random.default_rng(seed)
        k = int(r.integers(3, 6))
        pts = r.uniform(-0.3, 0.3, (k, 3))
        if r.random() < 0.4:  # a closed tour
            pts = np.vstack([pts, pts[:1]])
        same = r.random() < 0.5  # a tour of positions at one orientation
        rv0 = r.normal(0, 1, 3)
        poses = [_pose(p, rv0 if same else r.normal(0, 0.3, 3)) for p in pts]
        blend = float(r.choice([0.0, 0.0, 0.01, 0.05]))
        try:
            path = rc.paths.Waypoints(poses, blend=blend, speed=0.1, acceleration=1.0)
        except RatectlError:
            return
        for j in range(8):
            if j % 2:  # within a few mm of a waypoint, where the old search went wrong
                s = float(path.knots[int(r.integers(1, len(path.knots)))]) - r.uniform(0, 0.005)
            else:
                s = r.uniform(0, path.length)
            T = path.pose_at(s).copy()
            T[:3, 3] += r.normal(0, float(r.choice([0.0, 0.0, 0.001, 0.004, 0.03])), 3)
            d, a, s_found = path.distance(T)
            fuzz.count("path_distance")
            f = d * d + path.rotation_length ** 2 * a * a
            assert f <= _brute_nearest(path, T) + 1e-9, (s, s_found)

    prop()
