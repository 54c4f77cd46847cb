"""Braking toward a position limit (``ratectl.model.limits``): the bound that holds when
dt changes between periods, the beyond-the-limit rule, and the exact jerk-limited stop
while already braking."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ratectl.model.limits import (
    braking_speed,
    braking_speed_any_dt,
    braking_speed_any_dt_scalar,
    braking_speed_discrete,
    braking_speed_scalar,
    speed_toward_limit,
    stopping_distance,
    stopping_distance_scalar,
)

dts = st.lists(st.floats(1e-5, 0.05), min_size=1, max_size=60)


@given(D=st.floats(0.0, 2.0), a=st.floats(0.1, 100.0), dt=st.floats(1e-5, 0.05), later=dts,
       frac=st.floats(0.0, 1.0))
def test_any_dt_bound_stops_before_the_limit_for_every_later_dt(D, a, dt, later, frac):
    """From any v ≤ the bound, braking by a·dt' per period with arbitrary later periods dt'
    stays before the limit, and each later period's bound is ≥ v − a·dt' (the bound and the
    acceleration limit always meet)."""
    v = frac * float(braking_speed_any_dt(D, dt, 2.0 / a))
    assert v * dt + v * v / (2.0 * a) <= D * (1 + 1e-12) + 1e-15
    room = D - v * dt
    for dtk in later:
        bound = float(braking_speed_any_dt(room, dtk, 2.0 / a))
        assert bound >= v - a * dtk - 1e-12 * (1 + v)
        v = max(v - a * dtk, 0.0)
        room -= v * dtk
        assert room >= -1e-12 * (1 + D)


@given(D=st.floats(0.0, 2.0), a=st.floats(0.1, 100.0), dt=st.floats(1e-5, 0.05))
def test_any_dt_bound_is_the_root_and_tends_to_the_discrete_bound(D, a, dt):
    v = float(braking_speed_any_dt(D, dt, 2.0 / a))
    assert math.isclose(v * dt + v * v / (2 * a), D, rel_tol=1e-9, abs_tol=1e-15)
    vd = float(braking_speed_discrete(D, a * dt, 1.0 / (a * dt * dt), 1.0 / dt))
    assert v <= vd * (1 + 1e-12) + 1e-15  # more conservative than the constant-dt bound
    assert vd - v <= a * dt * (1 + 1e-9)  # by less than a·dt


def test_any_dt_bound_without_acceleration_limit_is_room_per_period():
    assert float(braking_speed_any_dt(0.3, 0.01, 2.0 / 1e200)) == 30.0
    assert float(braking_speed_any_dt(0.3, 0.01, 0.0)) == 30.0
    assert float(braking_speed_any_dt(-0.3, 0.01, 0.2)) == -30.0


def test_beyond_the_limit_the_command_goes_back_and_never_further_out():
    D = np.array([-0.1, -0.1, -0.1, -1e-4, 0.2])
    v_prev = np.array([1.0, 0.0, -0.5, -0.5, 3.0])
    adt, vmax, dt = 0.01, 2.0, 1e-3
    out = speed_toward_limit(D, v_prev, dt=dt, two_over_a=2.0 / 10.0, adt=adt, vmax=vmax)
    assert out[0] == 0.0  # still moving out: stop (harder than amax; the caller reports it)
    assert out[1] == -adt  # from rest: back within amax
    assert out[2] == -0.5 - adt  # already coming back: within amax and vmax
    assert out[3] == -0.1  # no farther than to the limit in one period
    assert out[4] == braking_speed_any_dt(0.2, dt, 0.2)  # inside: the braking bound (below v_prev − a·dt)
    no_prev = speed_toward_limit(D, None, dt=dt, two_over_a=0.2, adt=adt, vmax=vmax)
    assert no_prev[0] == -vmax


def test_exact_stopping_distance_while_braking_equals_ruckigs_stop():
    from ratectl.control.smoothing import stop

    rng = np.random.default_rng(3)
    for _ in range(60):
        A, J = rng.uniform(1, 20), rng.uniform(10, 500)
        a0 = -rng.uniform(0, A)
        v = rng.uniform(0, 2) if rng.random() < 0.7 else 0.5 * a0 * a0 / J * rng.uniform(0.8, 1.2)
        tr = stop(np.zeros(1), np.array([v]), qdd=np.array([a0]), amax=A, jmax=J)
        ts = np.linspace(0.0, tr.duration, 2001)
        fine = max(tr.at(t)[0][0] for t in ts)  # the farthest point of Ruckig's stop
        d = float(stopping_distance(v, a0, A, J, exact_when_braking=True))
        assert d >= fine - 1e-12
        assert d <= fine + 1e-6 * (1 + fine) + v * tr.duration / 2000  # sampling resolution
        assert d <= float(stopping_distance(v, a0, A, J)) + 1e-15  # the default over-estimates


@settings(max_examples=300, deadline=None)
@given(st.floats(-1.0, 5.0), st.sampled_from([1e-4, 1e-3, 4e-3, 0.05]), st.floats(1e-3, 1e4),
       st.floats(1e-2, 1e7) | st.just(1e300))
def test_scalar_braking_speeds_are_the_array_formulas(D, dt, a, j):
    """The plain-float forms the per-cycle progress bounds use give the array forms' values."""
    with np.errstate(over="ignore"):  # J² of an absent jerk limit (1e300) is inf: the same branch
        any_dt = float(braking_speed_any_dt(np.array([D]), dt, 2.0 / a)[0])
        braking = float(braking_speed(D, a, j))
    assert braking_speed_any_dt_scalar(D, dt, 2.0 / a) == pytest.approx(any_dt, rel=1e-12, abs=1e-300)
    assert braking_speed_scalar(D, a, j) == pytest.approx(braking, rel=1e-12, abs=1e-300)


@settings(max_examples=400, deadline=None)
@given(v=st.floats(-1.0, 5.0) | st.just(0.0), a_share=st.floats(-1.0, 1.0) | st.just(0.0),
       A=st.floats(1e-2, 1e3), J=st.floats(1e-1, 1e6), exact=st.booleans())
def test_the_scalar_stopping_distance_is_the_array_formula_to_the_last_bit(v, a_share, A, J, exact):
    """`stopping_distance_scalar` (a progress plans its stop with it every period) gives the
    array form's number exactly, braking or not, from rest, and with an acceleration at the
    bound; non-positive or absent bounds go through the array form."""
    a = a_share * A
    with np.errstate(over="ignore", invalid="ignore"):
        expected = float(stopping_distance(v, a, A, J, exact_when_braking=exact))
    assert stopping_distance_scalar(v, a, A, J, exact_when_braking=exact) == expected
    for bad_A, bad_J in ((0.0, J), (A, math.inf)):
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            ref = float(stopping_distance(v, a, bad_A, bad_J, exact_when_braking=exact))
            got = stopping_distance_scalar(v, a, bad_A, bad_J, exact_when_braking=exact)
        assert got == ref or (math.isnan(got) and math.isnan(ref))
