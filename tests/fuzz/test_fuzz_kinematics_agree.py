"""Fuzz: every kinematics entry point, single and batched, refuses the same inputs.

For a chain with prismatic joints and joint values from ordinary to 1e300 (and NaN):
``fk``, ``jacobian`` (base, tool, a point), ``fk_jacobian``, ``frames``, ``joint_axes`` and
``jacobian_dot``, on one configuration and on a batch holding it, either all answer with
finite arrays or all raise a `RatectlError` — no entry point skips a check that another
makes (a batched call once returned inf where the single one refused).
"""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

import ratectl as rc
from ratectl.errors import RatectlError

_CHAINS = [rc.robots.stanford(),
           rc.Chain.from_dh([rc.DH(a=0.0, alpha=-1.5707963267948966, d=0.0, theta=0.0, joint="prismatic"),
                             rc.DH(a=0.3, alpha=0.0, d=0.0, theta=0.0),
                             rc.DH(a=0.0, alpha=1.5707963267948966, d=0.1, theta=0.0, joint="prismatic")],
                            name="PRP")]


def _calls(chain):
    n = chain.dof
    qd = np.full(n, 0.1)
    return {
        "fk": chain.fk,
        "jacobian": chain.jacobian,
        "jacobian tool": lambda q: chain.jacobian(q, frame="tool"),
        "jacobian point": lambda q: chain.jacobian(q, point=[0.0, 0.0, 0.1]),
        "fk_jacobian": chain.fk_jacobian,
        "fk_jacobian tool": lambda q: chain.fk_jacobian(q, frame="tool"),
        "frames": chain.frames,
        "joint_axes": chain.joint_axes,
        "jacobian_dot": lambda q: chain.jacobian_dot(q, np.broadcast_to(qd, np.shape(q))),
    }


def _outcome(fn, q):
    try:
        out = fn(q)
    except RatectlError:
        return "refused"
    arrays = out if isinstance(out, tuple) else (out,)
    assert all(np.all(np.isfinite(a)) for a in arrays), "a non-finite answer instead of an error"
    return "answered"


def test_single_and_batched_kinematics_refuse_the_same_inputs(fuzz):
    @fuzz.settings(40)
    @given(seed=st.integers(0, 2**32 - 1), big=st.sampled_from([0.5, 1e3, 1e10, 1e100, 1e200, 1e300, np.nan]))
    def prop(seed, big):
        r = np.random.default_rng(seed)
        chain = _CHAINS[seed % len(_CHAINS)]
        q = r.uniform(-1.0, 1.0, chain.dof)
        j = int(r.choice(np.flatnonzero(chain.prismatic)))
        q[j] = big * (1 if r.random() < 0.5 else -1)
        batch = np.stack([np.zeros(chain.dof), q, np.zeros(chain.dof)])
        outcomes = {}
        for name, fn in _calls(chain).items():
            outcomes[name] = _outcome(fn, q)
            outcomes[name + " batched"] = _outcome(fn, batch)
            fuzz.count("kinematics", 2)
        assert len(set(outcomes.values())) == 1, outcomes

    prop()
