"""Fuzz: Cartesian paths with hostile speeds, steps and poses: finite samples or a ratectl
error, and the work of sampling bounded up front (every call returns within a second)."""

from __future__ import annotations

import time

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

import ratectl as rc
from ratectl.errors import RatectlError

_num = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([1e-300, 1e-12, 1e-6, 1e6,
                                                                                   1e300, "1", None, 1j]))


def _pose(r, scale):
    T = np.eye(4)
    a = r.uniform(-np.pi, np.pi)
    T[:2, :2] = [[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]
    T[:3, 3] = r.uniform(-1, 1, 3) * scale
    return T


def test_paths_sample_finite_or_ratectl_error(fuzz):
    @fuzz.settings(60)
    @given(seed=st.integers(0, 2**32 - 1), speed=_num, acc=_num, dt=_num,
           kind=st.sampled_from(["line", "arc", "waypoints"]), law=st.sampled_from([None, "quintic"]))
    def prop(seed, speed, acc, dt, kind, law):
        r = np.random.default_rng(seed)
        scale = 10.0 ** r.uniform(-9, 9)
        t0 = time.perf_counter()
        fuzz.count("path")
        try:
            if kind == "line":
                p = rc.paths.Line(_pose(r, scale), _pose(r, scale), speed=speed, acceleration=acc, law=law)
            elif kind == "arc":
                T = _pose(r, scale)
                p = rc.paths.Arc(T, centre=T[:3, 3] + r.uniform(-1, 1, 3) * scale, axis=r.uniform(-1, 1, 3),
                                 angle=float(r.uniform(-6, 6)), speed=speed, acceleration=acc, law=law)
            else:
                p = rc.paths.Waypoints([_pose(r, scale) for _ in range(int(r.integers(2, 5)))],
                                       speed=speed, acceleration=acc, law=law)
            t, T, xi = p.sample(dt, max_steps=2_000)
        except RatectlError:
            assert time.perf_counter() - t0 < 1.0
            return
        assert time.perf_counter() - t0 < 2.0
        assert np.all(np.isfinite(t)) and np.all(np.isfinite(T)) and np.all(np.isfinite(xi))
        assert len(t) <= 2_000

    prop()


def test_a_denormal_acceleration_is_an_input_error():
    """acceleration = 5e-324 (found by the soak): √(a·L) underflows to 0 and the trapezoidal
    law divided by it (ZeroDivisionError); it is a ratectl InputError naming the cause."""
    import pytest

    T0, T1 = np.eye(4), np.eye(4)
    T1[0, 3] = 1e-3
    with pytest.raises(rc.errors.InputError, match="underflows"):
        rc.paths.Line(T0, T1, speed=1.0, acceleration=5e-324)
