"""Bad input raises a ratectl error whose message says what is wrong."""

import math

import numpy as np
import pytest

import ratectl as rc


@pytest.mark.parametrize("field,value", [("a", math.nan), ("d", math.inf), ("alpha", -math.inf),
                                         ("theta", math.nan), ("d", "x")])
def test_non_finite_table_entries(field, value):
    with pytest.raises(rc.ModelError, match=field):
        rc.DH(**{field: value})


def test_unknown_joint_kind():
    with pytest.raises(rc.ModelError, match="revolute.*prismatic"):
        rc.DH(joint="spherical")


def test_inverted_limits():
    with pytest.raises(rc.ModelError, match="lower bound 1.0 must be below upper bound -1.0") as e:
        rc.DH(qlim=(1.0, -1.0))
    assert e.value.field == "qlim"


@pytest.mark.parametrize("kw", [{"vmax": -1.0}, {"amax": 0.0}, {"jmax": math.nan}])
def test_non_positive_rate_limits(kw):
    with pytest.raises(rc.ModelError, match=next(iter(kw))):
        rc.DH(**kw)


def test_mixed_rows_rejected():
    with pytest.raises(rc.ModelError, match="from_mdh"):
        rc.Chain.from_dh([rc.DH(), rc.MDH()])


def test_empty_table_rejected():
    with pytest.raises(rc.ModelError, match="at least one"):
        rc.Chain.from_dh([])


def test_bad_tool_transform():
    with pytest.raises(rc.ModelError, match="tool must be a 4x4"):
        rc.Chain.from_dh([rc.DH()], tool=np.eye(3))
    with pytest.raises(rc.ModelError, match="rigid transform"):
        rc.Chain.from_dh([rc.DH()], tool=2 * np.eye(4))


@pytest.mark.parametrize("q,match", [
    (np.zeros(5), r"shape \(6,\) or \(\.\.\., 6\)"),
    (np.zeros((2, 7)), r"got shape \(2, 7\)"),
    (np.array([0, 0, np.nan, 0, 0, 0]), "finite"),
    (np.array([0, 0, 0, np.inf, 0, 0]), "finite"),
    (3.0, "shape"),
])
def test_bad_q(q, match):
    arm = rc.robots.ur5e()
    for f in (arm.fk, arm.jacobian, arm.fk_jacobian, arm.frames):
        with pytest.raises(rc.InputError, match=match):
            f(q)


def test_bad_frame_and_point():
    arm = rc.robots.ur5e()
    with pytest.raises(rc.InputError, match="'base' or 'tool'"):
        arm.jacobian(np.zeros(6), frame="world")
    with pytest.raises(rc.InputError, match="3-vector"):
        arm.jacobian(np.zeros(6), point=[1, 2])


def test_errors_are_value_errors_too():
    assert issubclass(rc.ModelError, ValueError) and issubclass(rc.InputError, ValueError)
    assert issubclass(rc.SingularityError, rc.RatectlError)
