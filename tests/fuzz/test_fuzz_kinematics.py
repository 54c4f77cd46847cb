"""Fuzz: kinematics and singularity analysis on generated chains and hostile q.

Random DH/MDH chains (revolute and prismatic, lengths from 1e-9 m to the 1e9 m cap),
random configurations including huge values: fk, the Jacobian and the measures are
finite or raise a ratectl error; batched equals looped; the Jacobian matches finite
differences on moderate chains; ``random_q`` stays within the limits for every margin
it accepts.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import ratectl as rc
from ratectl.errors import RatectlError
from ratectl.kinematics.reference import numerical_jacobian


def _chain(r, *, extreme: bool):
    n = int(r.integers(1, 8))
    rows = []
    make = rc.DH if r.random() < 0.5 else rc.MDH
    for _ in range(n):
        scale = 10.0 ** r.uniform(-9, 9) if extreme else 1.0
        kind = "prismatic" if r.random() < 0.3 else "revolute"
        lo = -r.uniform(0.1, 3.0)
        hi = r.uniform(0.1, 3.0)
        rows.append(make(a=float(r.uniform(-1, 1) * scale), alpha=float(r.uniform(-np.pi, np.pi)),
                         d=float(r.uniform(-1, 1) * scale), theta=float(r.uniform(-np.pi, np.pi)),
                         joint=kind, qlim=(lo, hi) if r.random() < 0.8 else None,
                         vmax=float(r.uniform(0.1, 3)), amax=float(r.uniform(1, 20))))
    return rc.Chain.from_dh(rows) if make is rc.DH else rc.Chain.from_mdh(rows)


def _q(r, n, *, extreme: bool):
    q = r.uniform(-3, 3, n)
    if extreme:
        kind = int(r.integers(0, 5))
        if kind == 0:
            q = q * 10.0 ** r.uniform(0, 308)
        elif kind == 1:
            q[r.integers(0, n)] = r.choice([np.nan, np.inf, -np.inf])
        elif kind == 2:
            q = q * 10.0 ** r.uniform(-320, -100)
        elif kind == 3:
            q = np.full(n, 1e308) * r.choice([-1.0, 1.0])
    return q


def _call(fuzz, what, f):
    fuzz.count(what)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            return f()
        except RatectlError:
            return None


def test_kinematics_finite_or_ratectl_error(fuzz):
    @fuzz.settings(30)
    @given(seed=st.integers(0, 2**32 - 1), extreme=st.booleans())
    def prop(seed, extreme):
        r = np.random.default_rng(seed)
        chain = _chain(r, extreme=extreme)
        q = _q(r, chain.dof, extreme=extreme)
        T = _call(fuzz, "fk", lambda: chain.fk(q))
        if T is not None:
            assert np.all(np.isfinite(T))
        J = _call(fuzz, "jacobian", lambda: chain.jacobian(q))
        if J is not None:
            assert np.all(np.isfinite(J))
        Jm = J if J is not None else np.full((6, 1), np.nan)
        for f in (rc.manipulability, rc.singular_values):
            v = _call(fuzz, "measure", lambda f=f: f(Jm))
            if v is not None:
                assert np.all(np.isfinite(v))
        rep = _call(fuzz, "analyze", lambda: rc.analyze(chain, q))
        if rep is not None:
            assert rep.kind in rc.singularity.KINDS
            assert np.isfinite(rep.sigma_min)
        qs = np.stack([q, q * 0.5])
        Tb = _call(fuzz, "fk", lambda: chain.fk(qs))
        if Tb is not None and T is not None:
            assert np.allclose(Tb[0], T, rtol=1e-12, atol=1e-12 * (1 + np.abs(T).max()))

    prop()


def test_jacobian_matches_finite_differences_on_random_chains(fuzz):
    @fuzz.settings(15)
    @given(seed=st.integers(0, 2**32 - 1))
    def prop(seed):
        r = np.random.default_rng(seed)
        chain = _chain(r, extreme=False)
        q = r.uniform(-2, 2, chain.dof)
        fuzz.count("jacobian", 2)
        assert np.allclose(chain.jacobian(q), numerical_jacobian(chain, q), atol=1e-6)

    prop()


def test_random_q_within_limits_for_every_accepted_margin(fuzz):
    @fuzz.settings(30)
    @given(seed=st.integers(0, 2**32 - 1), margin=st.floats(0, 10, allow_nan=False))
    def prop(seed, margin):
        r = np.random.default_rng(seed)
        chain = _chain(r, extreme=False)
        fuzz.count("random_q")
        try:
            q = chain.random_q(5, rng=seed, margin=margin)
        except rc.errors.InputError:
            half = np.where(np.isfinite(chain.upper - chain.lower), (chain.upper - chain.lower) / 2,
                            np.inf)
            assert np.any(margin > half)
            return
        assert np.all(chain.within_limits(q))

    prop()


@pytest.mark.parametrize("bad", ["abc", [1j] * 6, np.zeros(6) + 1j, [None] * 6, np.zeros(5), {"a": 1},
                                 [[0.0] * 6, [0.0] * 5], b"\x00" * 6, [1e400] * 6])
def test_hostile_q_is_an_input_error(bad):
    arm = rc.robots.stanford()
    for f in (arm.fk, arm.jacobian, arm.fk_jacobian, lambda q: rc.analyze(arm, q), arm.frames):
        with pytest.raises(rc.errors.InputError):
            f(bad)
