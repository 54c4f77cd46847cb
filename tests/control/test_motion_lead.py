"""`Motion.commanded`: the lead q_lead that the commands have sent the arm to, by its rule
per joint, whether every joint was moved by the last command or only some."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ratectl.control.cycle import _AT_REST, Motion

N = 6
joint = st.floats(-3.0, 3.0, allow_nan=False)
vec = st.lists(joint, min_size=N, max_size=N).map(np.array)


def _rule(q, q_prev, q_next_prev, lead, q_next):
    """The docstring's rule, joint by joint: a joint the last command moved by at most
    _AT_REST, measured not moving toward its lead, owes nothing (its lead is its q)."""
    out = []
    for a, b, p, m, ld in zip(q, q_next, q_prev, q_next_prev, lead, strict=True):
        keep = abs(m - p) > _AT_REST or (a - p) * (ld - a) > 0.0
        out.append((ld if keep else a) + (b - a))
    return np.array(out)


@settings(max_examples=300, deadline=None)
@given(vec, vec, vec, vec, st.lists(st.booleans(), min_size=N, max_size=N), st.floats(1e-12, 1e-3))
def test_the_lead_follows_its_rule_per_joint(q_prev, q, q_next, lead, rested, step):
    m = Motion(N)
    m.commanded(q_prev, None, q_prev)  # the first command: the lead is where it sent the arm
    assert np.array_equal(m.q_lead, q_prev)
    # the last command moved the joints by `step`, except the `rested` ones (below _AT_REST)
    moved = np.where(rested, 0.5 * _AT_REST, step)
    m.q_next = q_prev + moved
    m.q_lead = lead.copy()
    expected = _rule(q, q_prev, m.q_next, lead, q_next)
    m.commanded(q, q_prev, q_next)
    assert np.array_equal(m.q_lead, expected)
