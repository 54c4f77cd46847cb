"""Fuzz: hostile arguments to the public calls raise a ratectl error, and `rc.run` refuses
them before anything moves.

Every public call that takes a number, a vector, a pose, a chain or a solver option is
given text, None, complex numbers, NaN, negative values, ragged sequences and objects of
the wrong kind: the answer is a `RatectlError` (whose message names the argument), never
a foreign exception and never a value silently converted (``"1"`` parsed, a complex
number's imaginary part dropped). `rc.run` raises before the driver's first command and
`ScriptedDriver` before it is built.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import ratectl as rc
from ratectl.drivers.scripted import ScriptedDriver
from ratectl.errors import RatectlError

ARM = rc.robots.ur5e()
Q = np.array([0.1, -1.2, 1.3, -1.6, -1.5, 0.2])
T = ARM.fk(Q)

HOSTILE = ["abc", "1", "1ms", None, 1j, complex(1, 1), math.nan, -1.0, -math.inf, [1.0, 2.0, 3.0],
           [[1.0], [2.0, 3.0]], object(), (1e-4,), {"a": 1}]


def _scaled(k):
    A = T.copy()
    A[:3, :3] *= k
    return A


def _mirrored():
    A = T.copy()
    A[:3, 0] *= -1.0
    return A


def _drv(**kw):
    return ScriptedDriver(ARM, Q, **kw)


def _run_refuses(**kw):
    """rc.run with ``kw`` raises a RatectlError and the driver never moved."""
    d = _drv()
    kw.setdefault("duration", 0.05)
    if not any(k in kw for k in ("path", "target", "twist")):
        kw["target"] = T
    with pytest.raises(RatectlError):
        rc.run(d, **kw)
    assert d.commands == [], "the robot was commanded before the argument was refused"


@pytest.mark.parametrize("kw", [
    dict(tolerance="abc"), dict(tolerance=None), dict(tolerance=(1e-4,)), dict(tolerance=(-1.0, 1e-3)),
    dict(tolerance=(math.nan, 1e-3)), dict(tolerance=(1e-4, "1")),
    dict(target="T"), dict(target=_scaled(2.0)),
    dict(target=_mirrored()), dict(target=T + 0j), dict(twist="abcdef"), dict(twist=[1, 2, 3]),
    dict(controller="default"), dict(settle="1"), dict(settle=-1.0), dict(settle=math.nan),
    dict(rate_hz="500"), dict(rate_hz=0.0), dict(timeout=math.nan), dict(duration="1"),
    dict(status_line="yes"), dict(on_interrupt="ignore"),
])
def test_run_refuses_bad_arguments_before_anything_moves(kw):
    _run_refuses(**kw)


def test_run_refuses_any_hostile_option_before_anything_moves(fuzz):
    @fuzz.settings(60)
    @given(name=st.sampled_from(["tolerance", "settle", "rate_hz", "timeout", "duration", "target",
                                 "twist", "controller", "status_line"]),
           bad=st.sampled_from(HOSTILE))
    def prop(name, bad):
        if bad is None and name in ("duration", "status_line", "controller", "target", "twist"):
            return  # None is a documented value there
        fuzz.count("run")
        _run_refuses(**{name: bad})

    prop()


@pytest.mark.parametrize("kw", [
    dict(drop="x"), dict(drop=2.0), dict(drop=math.nan), dict(seed="x"), dict(seed=-1), dict(seed=1.5),
    dict(read_delay="1ms"), dict(read_delay=-1.0), dict(read_delay=math.nan), dict(stale_after=math.nan),
    dict(stale_after="1"), dict(nan_after=-1.0), dict(fail_after=1j),
])
def test_scripted_driver_refuses_bad_arguments(kw):
    with pytest.raises(RatectlError):
        _drv(**kw)


def test_scripted_driver_refuses_a_bad_command():
    d = _drv()
    for bad in ("abc", [1.0, 2.0], [[1.0], [2.0]], np.ones(6) * 1j):
        with pytest.raises(RatectlError):
            d.command(bad)
    assert d.commands == []


_LINE = rc.paths.Line(T, T @ np.diag([1.0, 1.0, 1.0, 1.0]) + np.r_[[[0, 0, 0, 0.01]] * 3, [[0, 0, 0, 0]]],
                      speed=0.1, acceleration=1.0)

CALLS = {
    "ik tol None": lambda: rc.ik(ARM, T, Q, tol=None),
    "ik tol text": lambda: rc.ik(ARM, T, Q, tol="1e-6"),
    "ik chain text": lambda: rc.ik("ur5e", T, Q),
    "ik complex target": lambda: rc.ik(ARM, T + 0.1j, Q),
    "ik restarts text": lambda: rc.ik(ARM, T, Q, restarts="3"),
    "ik restarts negative": lambda: rc.ik(ARM, T, Q, restarts=-1),
    "ik seed text": lambda: rc.ik(ARM, T, Q, restarts=2, seed="x"),
    "ik nearest ragged": lambda: rc.ik(ARM, T, Q, nearest=[1.0, 2.0]),
    "ik nearest NaN": lambda: rc.ik(ARM, T, Q, nearest=np.full(6, np.nan)),
    "ik max_iter bool": lambda: rc.ik(ARM, T, Q, max_iter=True),
    "analyze text": lambda: rc.analyze("ur5e", Q),
    "follow dt text": lambda: rc.follow(ARM, _LINE, Q, dt="1ms"),
    "jacobian point text": lambda: ARM.jacobian(Q, point="abc"),
    "joint_torques text": lambda: ARM.joint_torques(Q, "abcdef"),
    "joint_torques complex": lambda: ARM.joint_torques(Q, np.ones(6) * 1j),
    "from_dh None": lambda: rc.Chain.from_dh(None),
    "from_dh text": lambda: rc.Chain.from_dh("abc"),
    "from_dh length text": lambda: rc.Chain.from_dh([rc.DH(a=0.1, alpha=0, d=0, theta=0)],
                                                    characteristic_length="1"),
    "DLS task_weights text": lambda: rc.solvers.DLS(task_weights=["a"] * 6),
    "DLS joint_weights text": lambda: rc.solvers.DLS(joint_weights=["a"] * 6),
    "with_limits vmax text": lambda: ARM.with_limits(vmax="1"),
    "with_limits qlim text": lambda: ARM.with_limits(qlim="ab"),
    "with_limits amax complex": lambda: ARM.with_limits(amax=1j),
    "Waypoints blend None": lambda: rc.paths.Waypoints([T, T], blend=None, speed=1.0, acceleration=1.0),
    "Waypoints text": lambda: rc.paths.Waypoints("abc", speed=1.0, acceleration=1.0),
    "Waypoints ragged": lambda: rc.paths.Waypoints([np.eye(4), np.eye(3)], speed=1.0, acceleration=1.0),
    "singular_values text": lambda: rc.singular_values("abc"),
    "manipulability ragged": lambda: rc.manipulability([[1.0], [2.0, 3.0]]),
}


@pytest.mark.parametrize("name", sorted(CALLS))
def test_hostile_arguments_raise_a_ratectl_error(name):
    with pytest.raises(RatectlError):
        CALLS[name]()
